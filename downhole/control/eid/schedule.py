"""The EID over the drilling envelope: reachable steady states and a design scheduled over the
operating point by the margin of the regenerative bit/rock mode.

The LMI of :mod:`downhole.control.eid.design` certifies the loop on the design model of Eq. 3.13,
which has no bit/rock law. With the *delayed* depth of cut the bit/rock interaction is
regenerative: the linearized loop has a bit/rock mode (30-60 rad/s) whose damping depends on the
operating point through the delay 2 pi/(n omega) between blades and the slopes of the bit law.
:func:`~downhole.control.eid.stability.regenerative_closed_loop` computes it for the EID loop
with the plant's input delay; a design is therefore *checked*, operating point by operating
point, on that characteristic equation:

* :class:`EIDSchedule` solves the LMI for each of the candidate tunings it is given (filter
  bandwidth, observer gain, internal-model gain, gain bound of the axial channel; each
  LMI-certified on the design model; optionally the predictive bit damper of
  :class:`~downhole.control.eid.predictor.PredictiveEID` on top) and picks, at an operating point
  (rop, omega), the candidate whose closed loop with the linearized delayed depth of cut has the
  most negative spectral abscissa. The candidates of the ``eid-envelope`` claim are data of that
  experiment (``downhole/experiments/eid_envelope.toml``).
* :func:`operating_point` says whether the plant can hold a steady state there at all (positive
  hook load, a depth of cut within an optional bit limit, commands within the actuator limits).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from downhole.errors import DownholeInputError

__all__ = [
    "CANDIDATE_KEYS",
    "EIDSchedule",
    "OperatingPoint",
    "closed_loop_margin",
    "open_loop_abscissa",
    "operating_point",
]

#: Keys of a candidate of :class:`EIDSchedule`: the axial channel's tuning (keyword arguments of
#: :func:`~downhole.control.eid.design.synthesize_channel`) and the options of the predictive bit
#: damper (:class:`~downhole.control.eid.predictor.PredictiveEID`).
LMI_KEYS = ("br", "bf", "observer_gain", "gain_bound")
DAMPER_KEYS = ("damping_gain", "depth_of_cut_gain", "angle_doc", "axial_filter")
CANDIDATE_KEYS = LMI_KEYS + DAMPER_KEYS


@dataclass(frozen=True)
class OperatingPoint:
    """Steady drilling at (rop, omega) with the delayed depth of cut d = 2 pi rop / omega.

    Attributes
    ----------
    rop, omega : float
        m/s, rad/s.
    depth_of_cut : float
        Per revolution, all blades, m.
    wob, tob : float
        Steady bit forces, N and N m.
    hook_load : float
        (M_S + M_B) g - WOB, N.
    commands : (float, float)
        Steady top-drive commands (U_A, U_T) in the seed's convention.
    reachable : bool
    reason : str
        Why not, or "reachable".
    """

    rop: float
    omega: float
    depth_of_cut: float
    wob: float
    tob: float
    hook_load: float
    commands: tuple
    reachable: bool
    reason: str

    def to_dict(self) -> dict:
        return {"rop": self.rop, "omega": self.omega, "depth_of_cut": self.depth_of_cut,
                "wob": self.wob, "tob": self.tob, "hook_load": self.hook_load,
                "commands": list(self.commands), "reachable": self.reachable,
                "reason": self.reason}


def _check_point(rop, omega):
    for name, v in (("rop", rop), ("omega", omega)):
        if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
            raise DownholeInputError(f"operating point: {name} must be a positive finite number, "
                                     f"got {v!r}")
    return float(rop), float(omega)


def operating_point(model, rop: float, omega: float, *, max_depth_of_cut: float | None = None,
                    u_limits=((-1e3, 1e3), (-1e3, 1e3))) -> OperatingPoint:
    """Can the neutral plant ``model`` drill steadily at ``rop`` (m/s) and ``omega`` (rad/s)?

    The steady state has the depth of cut d = 2 pi rop/omega, the bit forces of the model's law at
    (d, rop, omega) and the commands U_A = rop + (W + M_S g)/alpha_A, U_T = omega + T/alpha_T. It
    is unreachable if the WOB exceeds the weight of string and bit (hook load <= 0: the string
    would have to be pushed), if d exceeds ``max_depth_of_cut`` (the bit's limit, m per
    revolution, e.g. the cutter exposure times the number of blades; None: no limit), if the
    torque on bit is not positive, or if a command is outside ``u_limits`` (plant units, the axial
    one relative to the hanging equilibrium, as :class:`EIDController.u_limits`).

    Parameters
    ----------
    model : NeutralModel
        The neutral-type plant.
    rop : float
        Rate of penetration, m/s (> 0).
    omega : float
        Bit rotary speed, rad/s (> 0).
    max_depth_of_cut : float, optional
        The bit's limit, m per revolution; None: no limit.
    u_limits : tuple of (float, float) pairs
        Admissible axial and torsional commands, plant units.

    Returns
    -------
    OperatingPoint
        The steady state and whether (and why not) it is reachable.
    """
    from downhole.bit.law import bit_forces_py

    rop, omega = _check_point(rop, omega)
    p = model.params
    d = 2.0 * math.pi * rop / omega
    wob, tob = bit_forces_py(d, rop, omega, model.bit)
    hook = (p.string_mass + p.bit_mass) * p.g - wob
    ua, ut = model.steady_inputs(rop, omega, wob, tob)
    reasons = []
    if hook <= 0:
        reasons.append(f"WOB {wob / 1e3:.1f} kN exceeds the weight of string and bit "
                       f"{(hook + wob) / 1e3:.1f} kN (hook load would be negative)")
    if max_depth_of_cut is not None and d > max_depth_of_cut:
        reasons.append(f"depth of cut {1e3 * d:.2f} mm/rev beyond the bit's limit "
                       f"{1e3 * max_depth_of_cut:.2f} mm/rev")
    if not tob > 0:
        reasons.append(f"torque on bit {tob:.3g} N m is not positive")
    rel = (ua - model.hang_command, ut)
    for name, u, (lo, hi) in zip(("axial", "angular"), rel, u_limits):
        if not lo <= u <= hi:
            reasons.append(f"{name} command {u:.4g} outside the actuator limits [{lo}, {hi}]")
    return OperatingPoint(rop, omega, d, float(wob), float(tob), float(hook),
                          (float(ua), float(ut)), not reasons,
                          "; ".join(reasons) if reasons else "reachable")


def open_loop_abscissa(model, rop: float, omega: float) -> tuple[float, float]:
    """(growth rate 1/s, frequency rad/s) of the rightmost root of the open-loop plant linearized
    with the delayed depth of cut (:func:`~downhole.control.eid.stability.
    bit_rock_open_loop_roots`), leaving out the drift root s = 0 of the bit position.

    Parameters
    ----------
    model : NeutralModel
        The neutral-type plant.
    rop : float
        Rate of penetration, m/s.
    omega : float
        Bit rotary speed, rad/s.

    Returns
    -------
    tuple of (float, float)
        Growth rate (1/s; ``-inf`` without roots) and frequency (rad/s).
    """
    from downhole.control.eid.stability import bit_rock_open_loop_roots

    r = [z for z in bit_rock_open_loop_roots(model, rop, omega) if abs(z) > 1e-6]
    if not r:
        return -math.inf, 0.0
    return float(r[0].real), float(r[0].imag)


def closed_loop_margin(c, model, rop: float, omega: float) -> dict:
    """Linearized closed loop with the delayed depth of cut of an EIDController
    (:func:`~downhole.control.eid.stability.regenerative_closed_loop`) or a PredictiveEID
    (:func:`~downhole.control.eid.predictor.predictive_closed_loop`) at (rop, omega).

    Parameters
    ----------
    c : EIDController or PredictiveEID
        The controller.
    model, rop, omega
        As :func:`open_loop_abscissa`.

    Returns
    -------
    dict
        The characteristic roots and spectral abscissa of the linearized loop (the keys of
        the function called).
    """
    from downhole.control.eid.predictor import PredictiveEID, predictive_closed_loop
    from downhole.control.eid.stability import regenerative_closed_loop

    if isinstance(c, PredictiveEID):
        return predictive_closed_loop(c.eid, model, rop, omega, c.damping_gain,
                                      depth_of_cut_gain=c.depth_of_cut_gain,
                                      axial_filter=c.axial_filter)
    return regenerative_closed_loop(c, model, rop, omega)


@dataclass
class EIDSchedule:
    """EID designs for a list of candidate tunings, scheduled over the operating point.

    Build with ``EIDSchedule(model, candidates)`` (solves one LMI per candidate);
    ``schedule.at(rop, omega)`` returns the candidate whose closed loop with the linearized
    delayed depth of cut (:func:`closed_loop_margin`) has the most negative spectral abscissa
    there, with that margin.

    Attributes
    ----------
    model : NeutralModel
    candidates : sequence of dict
        One dict per candidate with keys from :data:`CANDIDATE_KEYS`: ``br``, ``bf``,
        ``observer_gain``, ``gain_bound`` tune the axial channel (keyword arguments of
        :func:`~downhole.control.eid.design.synthesize_channel`; missing ones take its
        defaults; the torsional channel keeps the default of
        :func:`~downhole.control.eid.controller.design_eid`); ``damping_gain`` (k_d > 0) or
        ``depth_of_cut_gain`` (k_c > 0) put the predictive bit damper on top, with its options
        ``angle_doc`` and ``axial_filter`` (:class:`~downhole.control.eid.predictor.
        PredictiveEID`).
    controllers : list of EIDController or PredictiveEID
        One per candidate (the EID LMI-certified on the design model; ``reports`` hold the
        margins).
    """

    model: object
    candidates: tuple
    controllers: list = field(default_factory=list)

    def __post_init__(self):
        from downhole.control.eid.controller import design_eid
        from downhole.control.eid.design import synthesize_channel
        from downhole.control.eid.predictor import PredictiveEID

        self.candidates = tuple(dict(c) for c in self.candidates)
        if not self.candidates:
            raise DownholeInputError("EIDSchedule: at least one candidate tuning is needed")
        for k, cand in enumerate(self.candidates):
            unknown = set(cand) - set(CANDIDATE_KEYS)
            if unknown:
                raise DownholeInputError(f"EIDSchedule candidate {k}: unknown keys "
                                         f"{sorted(unknown)}; expected "
                                         f"{', '.join(sorted(CANDIDATE_KEYS))}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            base = design_eid(self.model)
            ch = base.model_coeffs[0]
            for cand in self.candidates:
                lmi = {k: v for k, v in cand.items() if k in LMI_KEYS}
                g, rep = synthesize_channel(ch, "axial", **lmi)
                c = replace(base, gains=(g, base.gains[1]), reports=[rep, base.reports[1]])
                addons = {"damping_gain": 0.0,
                          **{k: cand[k] for k in DAMPER_KEYS if k in cand}}
                on = addons["damping_gain"] > 0 or addons.get("depth_of_cut_gain", 0.0) > 0
                self.controllers.append(PredictiveEID(c, self.model, **addons) if on else c)

    def margin(self, k: int, rop: float, omega: float) -> dict:
        """:func:`closed_loop_margin` of candidate ``k`` at (rop, omega)."""
        rop, omega = _check_point(rop, omega)
        return closed_loop_margin(self.controllers[k], self.model, rop, omega)

    def margins(self, rop: float, omega: float) -> list:
        """:func:`closed_loop_margin` of every candidate at (rop, omega)."""
        return [self.margin(k, rop, omega) for k in range(len(self.controllers))]

    def at(self, rop: float, omega: float):
        """(controller, candidate index, its closed_loop_margin dict) with the most negative
        spectral abscissa at (rop, omega); ties go to the lower index."""
        m = self.margins(rop, omega)
        k = int(np.argmin([x["spectral_abscissa"] for x in m]))
        return self.controllers[k], k, m[k]
