"""Named DHP penalty weights: the documented presets a scenario can name.

``[controller.dhp] weights = "<name>"`` in a DHP or SIL scenario (and
:func:`downhole.sil.testing.ch6_dhp`) picks one of :data:`WEIGHT_SETS`, keyword arguments of
:class:`~downhole.control.dhp.drilling.PenaltyWeights` (non-dimensional, Eq. 4.45 layout, two
numbers per field: axial, torsional). Other weights are written out as a table. The experiments
use these presets by name and keep their research-only sets and searches themselves
(:mod:`downhole.experiments.ch4_dhp`, ``examples/research/``).
"""

from __future__ import annotations

from downhole.errors import DownholeInputError

__all__ = ["WEIGHT_SETS", "weight_set", "weight_set_names"]

#: The presets:
#:
#: - ``design``: the Ch. 4 claims' weights, equal to the defaults of ``PenaltyWeights()``.
#: - ``robust``: softer weights (lower gains) that keep the 24-state design stable on the
#:   68-state hybrid (the SIL chapter's controller, :func:`downhole.sil.testing.ch6_dhp`).
#: - ``planned``: the gains about a planned step start-up on the Table 5.1 well (the SIL
#:   scenario's default, with :func:`~downhole.control.dhp.plan.design_dhp_planned`; the claim
#:   ``dhp.hybrid68``): soft (the plan does the start-up), integral action, damping injection on
#:   the string velocities. Found by a (1+1) evolution strategy scoring the worst settling time
#:   of the planned step on the 24-state FEM and the 68-state hybrid (approximate and delayed
#:   depth of cut) and the tracking at epsilon 50 % and 300 %
#:   (``examples/research/dhp_planned_weight_search.py``; docs/dhp.md).
WEIGHT_SETS = {
    "design": {"bit_velocity": (100.0, 100.0), "bit_position": (0.1, 0.1), "r": (1.0, 1.0)},
    "robust": {"bit_velocity": (10.0, 10.0), "bit_position": (1.0, 10.0), "r": (1.0, 1.0)},
    "planned": {"bit_velocity": (0.0114, 2.03), "bit_position": (0.157, 0.0917),
                "string_velocity": (0.446, 0.0194), "r": (1.0, 2.07),
                "integral": (87.1, 287.0)},
}


def weight_set_names() -> tuple[str, ...]:
    """Names of the presets."""
    return tuple(WEIGHT_SETS)


def weight_set(name: str) -> dict:
    """The preset ``name`` as keyword arguments of ``PenaltyWeights`` (a fresh dict).

    Parameters
    ----------
    name : str
        One of :data:`WEIGHT_SETS` (``design``, ``robust``, ``planned``).

    Returns
    -------
    dict
        The penalty weights, a fresh copy.

    Raises
    ------
    DownholeInputError
        Unknown name (the known ones are listed).
    """
    if not isinstance(name, str) or name not in WEIGHT_SETS:
        raise DownholeInputError(f"no weight set {name!r}; known: {sorted(WEIGHT_SETS)}")
    return dict(WEIGHT_SETS[name])
