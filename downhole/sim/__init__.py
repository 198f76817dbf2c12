"""Simulation: compiled fixed-step kernels, the simulate() entry point and the Result object."""

from downhole.sim.inputs import SurfaceInputs
from downhole.sim.result import CHANNEL_UNITS, Result, load_result
from downhole.sim.simulate import LumpedPlant, simulate

__all__ = ["CHANNEL_UNITS", "LumpedPlant", "Result", "SurfaceInputs", "load_result", "simulate"]
