"""The wave segment (lossless delay line) of the neutral-type and hybrid models.

Defined in :mod:`downhole.sim.wave`, beside the compiled kernels that step it
(:mod:`downhole.sim.fem_kernels`), so that the simulation package does not import this one (no
``sim`` <-> ``string`` cycle); this module keeps the drill-string namespace for it.
"""

from downhole.sim.wave import (WaveSegment, segments_from_pipe, wave_state, wave_incoming,
                               wave_push, wave_step, wave_step_at, wave_read, wave_read_plan,
                               wave_read_at, wave_outgoing, wave_end_forces, wave_source_forces,
                               static_end_forces, line_preload, initial_waves, WaveParams)

__all__ = ["WaveSegment", "segments_from_pipe", "wave_state", "wave_incoming", "wave_push",
           "wave_step", "wave_step_at", "wave_read", "wave_read_plan", "wave_read_at",
           "wave_outgoing", "wave_end_forces", "wave_source_forces", "static_end_forces",
           "line_preload", "initial_waves", "WaveParams"]
