"""Simulation: the one compiled mechanics kernel, the simulate() entry point and the Result object."""

from downhole.sim.inputs import SurfaceInputs
from downhole.sim.result import CHANNEL_UNITS, Result, load_result
from downhole.sim.simulate import simulate

__all__ = ["CHANNEL_UNITS", "Result", "SurfaceInputs", "load_result", "simulate"]
