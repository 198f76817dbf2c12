"""The lumped chain models of seed Ch. 2 (:func:`lumped_model`, :class:`ChainModel`).

They are defined in :mod:`downhole.sim.lumped_model`, next to the one kernel they configure
(:mod:`downhole.sim.kernel`) and the runner (:func:`downhole.sim.simulate`), so that the
simulation package does not import this one (no ``sim`` <-> ``string`` cycle); this module keeps
the drill-string namespace for them.
"""

from downhole.sim.lumped_model import ChainField, ChainModel, lumped_model

__all__ = ["ChainField", "ChainModel", "lumped_model"]
