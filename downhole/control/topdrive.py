"""Top-drive speed control and hook modes: the rig descriptions live in the core
(:mod:`downhole.params.rig`, since every model's top boundary is built from them); this module
keeps the historical import path."""

from downhole.params.rig import Hook, TopDrive

__all__ = ["Hook", "TopDrive"]
