"""The wave segment (lossless delay line) of the neutral-type and hybrid models.

Defined in :mod:`downhole.sim.wave`, beside the compiled kernels that step it
(:mod:`downhole.sim.kernel`), so that the simulation package does not import this one (no
``sim`` <-> ``string`` cycle); this module keeps the drill-string namespace for it.
"""

from downhole.sim.wave import (
                               WaveParams,
                               WaveSegment,
                               initial_waves,
                               line_preload,
                               segments_from_pipe,
                               static_end_forces,
                               wave_end_forces,
                               wave_incoming,
                               wave_outgoing,
                               wave_push,
                               wave_read,
                               wave_read_at,
                               wave_read_plan,
                               wave_source_forces,
                               wave_state,
                               wave_step,
                               wave_step_at,
)

__all__ = [
                               "WaveParams",
                               "WaveSegment",
                               "initial_waves",
                               "line_preload",
                               "segments_from_pipe",
                               "static_end_forces",
                               "wave_end_forces",
                               "wave_incoming",
                               "wave_outgoing",
                               "wave_push",
                               "wave_read",
                               "wave_read_at",
                               "wave_read_plan",
                               "wave_source_forces",
                               "wave_state",
                               "wave_step",
                               "wave_step_at",
]
