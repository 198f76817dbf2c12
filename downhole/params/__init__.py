"""Typed parameter sets with units, and the named presets (seed Tables 2.1, 3.1, 5.1)."""

from downhole.params.bit import BitParams
from downhole.params.lumped import LumpedParams, TwelfthOrderSplit
from downhole.params.presets import PRESETS, Preset, get_preset
from downhole.params.strings import DirectionalWellParams, NeutralStringParams, PipeSection

__all__ = [
    "PRESETS",
    "BitParams",
    "DirectionalWellParams",
    "LumpedParams",
    "NeutralStringParams",
    "PipeSection",
    "Preset",
    "TwelfthOrderSplit",
    "get_preset",
]
