"""Torque and drag of a system scenario: the described well and string, the bit's boundary loads.

``downhole torque-drag FILE`` reads a system scenario (``[model] fidelity`` with ``[well]`` and
``[string]``, :mod:`downhole.scenario.system`) and its optional ``[torque_drag]`` table
(:class:`~downhole.scenario.system.TorqueDragSettings`): friction factors, element length,
vertical-section azimuth, and WOB / TOB of the drilling case. Without them the drilling case
uses the ``[operation]`` set-points: the WOB given there (or the steady WOB at the given ROP)
and the bit law's torque at that WOB and surface speed
(:func:`~downhole.scenario.system.steady_bit_state`).
"""

from __future__ import annotations

from dataclasses import dataclass

from downhole.errors import DownholeInputError, ScenarioError
from downhole.scenario import check_values, model_type

__all__ = ["TorqueDragCase", "run_torque_drag", "torque_drag_case"]


@dataclass(frozen=True)
class TorqueDragCase:
    """A validated torque-and-drag input: the system, the friction factors, the element length,
    the vertical-section azimuth (rad, None = closure) and the drilling case's WOB (N) and TOB
    (N m)."""

    title: str
    system: object
    friction: tuple
    step: float
    azimuth: float | None
    wob: float
    tob: float


def torque_drag_case(data: dict, source: str, friction=None) -> TorqueDragCase:
    """Validate a system scenario for ``downhole torque-drag``; ``friction`` (a sequence of
    friction factors) overrides ``[torque_drag] friction_factors``.

    Raises
    ------
    ScenarioError
        Naming the file and the field: not a system scenario, a schema error, a string that does
        not reach from surface to the bit, a WOB that the bit law cannot reach.
    """
    from downhole.scenario.system import (
        DESCRIBED,
        _check_renames,
        build_system,
        parse_system,
        steady_bit_state,
    )

    check_values(data, source)
    mtype = model_type(data, source)
    if mtype != "system":
        raise ScenarioError(source, "model", f"torque-drag needs a scenario that describes the "
                            f"system ([model] fidelity with [well] and [string], no preset or "
                            f"[controller]; docs/scenarios.md); this one runs {mtype!r}")
    _check_renames(data, source)
    sc = parse_system(data, source)
    system = build_system(sc, source, sc.model.fidelity)
    span = system.well.total_depth - system.well.top_depth
    if abs(system.string.length - span) > 1e-6 * max(1.0, span):
        raise ScenarioError(source, "string.segments", f"torque and drag needs a string from "
                            f"surface to the bit: the segments are {system.string.length:g} m "
                            f"long, the well {span:g} m (leave the last segment's length out "
                            "to fill the well)")
    td, op = sc.torque_drag, sc.operation
    factors = tuple(td.friction_factors) if friction is None else tuple(friction)
    wob = td.wob if td.wob is not None else op.wob
    field = "torque_drag.wob" if td.wob is not None else "operation.wob"
    tob = td.tob
    speed = DESCRIBED["surface_speed"] if op.surface_speed is None else op.surface_speed
    try:
        if wob is None:
            _, wob, tob_law = steady_bit_state(system.bit, speed, rop=op.rop)
            tob = tob_law if tob is None else tob
        elif tob is None:
            _, _, tob = steady_bit_state(system.bit, speed, wob=wob)
    except (DownholeInputError, ValueError) as exc:
        raise ScenarioError(source, field, f"no steady cutting state of the bit law at this "
                            f"set-point: {exc}") from None
    return TorqueDragCase(title=sc.title, system=system, friction=factors, step=td.step,
                          azimuth=td.vertical_section_azimuth, wob=float(wob), tob=float(tob))


def run_torque_drag(case: TorqueDragCase, source: str = "<dict>"):
    """The :class:`~downhole.string.torque_drag.TorqueDrag` of a validated case."""
    from downhole.string.torque_drag import torque_drag

    try:
        return torque_drag(case.system.well, case.system.string, friction=case.friction,
                           wob=case.wob, tob=case.tob, step=case.step)
    except ScenarioError:
        raise
    except DownholeInputError as exc:
        raise ScenarioError(source, "torque_drag", str(exc)) from None
