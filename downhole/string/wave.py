"""The wave segment (lossless delay line) of the neutral-type and hybrid models.

Defined in :mod:`downhole.sim.wave`, beside the compiled kernels that step it
(:mod:`downhole.sim.kernel`), so that the simulation package does not import this one (no
``sim`` <-> ``string`` cycle); this module keeps the drill-string namespace for it.
"""

from downhole.sim import wave as _wave
from downhole.sim.wave import *  # noqa: F403 -- re-exported: the public names of downhole.sim.wave

__all__ = list(_wave.__all__)
