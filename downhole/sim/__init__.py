"""Simulation: compiled fixed-step kernels, the simulate() entry point and the Result object."""

from downhole.sim.result import CHANNEL_UNITS, Result, load_result

__all__ = ["Result", "load_result", "CHANNEL_UNITS"]
