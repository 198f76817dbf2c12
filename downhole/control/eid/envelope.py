"""The EID over the drilling envelope: reachable steady states, a design scheduled over the
operating point by the margin of the regenerative bit/rock mode, a settle criterion and the map of
a grid of operating points.

The LMI of :mod:`downhole.control.eid.design` certifies the loop on the design model of Eq. 3.13,
which has no bit/rock law. With the *delayed* depth of cut the bit/rock interaction is
regenerative: the linearized loop has a bit/rock mode (30-60 rad/s) whose damping depends on the
operating point through the delay 2 pi/(n omega) between blades and the slopes of the bit law.
:func:`~downhole.control.eid.stability.regenerative_closed_loop` computes it for the EID loop
with the plant's input delay; the design here is therefore *checked*, operating point by operating
point, on that characteristic equation:

* :class:`EIDSchedule` solves the LMI for each of a few candidate tunings (filter bandwidth,
  observer gain, internal-model gain, gain bound; every one LMI-certified on the design model) and
  picks, at an operating point (rop, omega), the candidate whose closed loop with the linearized
  delayed depth of cut has the most negative spectral abscissa. The default tuning of
  :func:`~downhole.control.eid.controller.design_eid` is candidate 0.
* :func:`operating_point` says whether the plant can hold a steady state there at all (positive
  hook load, a depth of cut within an optional bit limit, commands within the actuator limits).
* :func:`settle_metrics` is the settle criterion; :func:`envelope_map` runs the grid from rest
  with the rotate-then-drill start-up of :func:`~downhole.control.eid.references.
  startup_reference` and classifies each point (settled or not, and why).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from downhole.errors import DownholeInputError

__all__ = [
    "APPROACH_OMEGA",
    "DESCENT_RATE",
    "ENVELOPE_CANDIDATES",
    "SETTLE_TOLERANCE",
    "EIDSchedule",
    "OperatingPoint",
    "envelope_map",
    "envelope_point",
    "open_loop_abscissa",
    "operating_point",
    "settle_metrics",
]

#: Candidate tunings of the axial channel (the torsional channel keeps the default): keyword
#: arguments of :func:`~downhole.control.eid.design.synthesize_channel`, plus, for the
#: predictive bit damper of :class:`~downhole.control.eid.predictor.PredictiveEID` on top of
#: that EID, ``damping_gain`` k_d > 0, ``angle_doc`` (the prediction's depth of cut looked up by
#: the measured bit angle), ``axial_filter`` (rad/s, a low-pass filter on the damping command)
#: and ``depth_of_cut_gain`` k_c (the axial reference scaled with the measured rotary speed).
#: Index 0 is the default of :func:`~downhole.control.eid.controller.design_eid`; 8 holds the
#: low rates of penetration below d* (k_d = 4, which chatters unfiltered), 9 the low speeds at
#: high rates of penetration (k_c = 1; docs/neutral-eid.md, "Envelope").
ENVELOPE_CANDIDATES = (
    {"br": 10.0, "bf": 20.0, "observer_gain": 20.0, "gain_bound": 5.0},
    {"br": 3.0, "bf": 5.0, "observer_gain": 20.0, "gain_bound": 2.0},
    {"br": 3.0, "bf": 60.0, "observer_gain": 5.0, "gain_bound": 2.0},
    {"br": 10.0, "bf": 20.0, "observer_gain": 20.0, "gain_bound": 20.0},
    {"br": 10.0, "bf": 20.0, "observer_gain": 20.0, "gain_bound": 5.0, "damping_gain": 2.0},
    {"br": 3.0, "bf": 5.0, "observer_gain": 20.0, "gain_bound": 2.0, "damping_gain": 2.0},
    {"br": 10.0, "bf": 20.0, "observer_gain": 20.0, "gain_bound": 5.0, "damping_gain": 3.0},
    {"br": 3.0, "bf": 5.0, "observer_gain": 20.0, "gain_bound": 2.0, "damping_gain": 3.0},
    {"br": 10.0, "bf": 20.0, "observer_gain": 20.0, "gain_bound": 5.0, "damping_gain": 4.0,
     "angle_doc": True, "axial_filter": 200.0},
    {"br": 3.0, "bf": 5.0, "observer_gain": 20.0, "gain_bound": 2.0, "damping_gain": 2.0,
     "angle_doc": True, "depth_of_cut_gain": 1.0},
)
_CANDIDATE_KEYS = {"br", "bf", "observer_gain", "gain_bound", "damping_gain",
                   "depth_of_cut_gain", "angle_doc", "axial_filter"}
_ADDON_KEYS = ("damping_gain", "depth_of_cut_gain", "angle_doc", "axial_filter")

#: Settle criterion: over the last ``window`` seconds, RMS error of each bit velocity below this
#: fraction of its reference, and the bit never leaves the rock (axial velocity > -tolerance x rop).
SETTLE_TOLERANCE = 0.02


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
    bit_rock_open_loop_roots`), leaving out the drift root s = 0 of the bit position."""
    from downhole.control.eid.stability import bit_rock_open_loop_roots

    r = [z for z in bit_rock_open_loop_roots(model, rop, omega) if abs(z) > 1e-6]
    if not r:
        return -math.inf, 0.0
    return float(r[0].real), float(r[0].imag)


def _margin(c, model, rop, omega):
    """Linearized closed loop with the delayed depth of cut of an EID or PredictiveEID."""
    from downhole.control.eid.predictor import PredictiveEID, predictive_closed_loop
    from downhole.control.eid.stability import regenerative_closed_loop

    if isinstance(c, PredictiveEID):
        return predictive_closed_loop(c.eid, model, rop, omega, c.damping_gain,
                                      torsional_gain=c.torsional_gain,
                                      torsional_filter=c.torsional_filter,
                                      depth_of_cut_gain=c.depth_of_cut_gain,
                                      axial_filter=c.axial_filter)
    return regenerative_closed_loop(c, model, rop, omega)


@dataclass
class EIDSchedule:
    """EID designs for a set of candidate axial tunings, scheduled over the operating point.

    Build with ``EIDSchedule(model)`` (solves one LMI per candidate); ``schedule.at(rop, omega)``
    returns the candidate whose closed loop with the linearized delayed depth of cut
    (:func:`~downhole.control.eid.stability.regenerative_closed_loop`, or
    :func:`~downhole.control.eid.predictor.predictive_closed_loop` for a candidate with the
    predictive bit damper) has the most negative spectral abscissa there, with that margin.

    Attributes
    ----------
    model : NeutralModel
    candidates : tuple of dict
        Axial-channel tunings (keyword arguments of ``synthesize_channel``).
    controllers : list of EIDController or PredictiveEID
        One per candidate (the EID LMI-certified on the design model; ``reports`` hold the
        margins).
    """

    model: object
    candidates: tuple = ENVELOPE_CANDIDATES
    controllers: list = field(default_factory=list)

    def __post_init__(self):
        from downhole.control.eid.controller import design_eid
        from downhole.control.eid.design import synthesize_channel

        if not self.candidates:
            raise DownholeInputError("EIDSchedule: at least one candidate tuning is needed")
        from downhole.control.eid.predictor import PredictiveEID

        for k, cand in enumerate(self.candidates):
            unknown = set(cand) - _CANDIDATE_KEYS
            if unknown:
                raise DownholeInputError(f"EIDSchedule candidate {k}: unknown keys "
                                         f"{sorted(unknown)}; expected "
                                         f"{', '.join(sorted(_CANDIDATE_KEYS))}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            base = design_eid(self.model)
            ch = base.model_coeffs[0]
            for cand in self.candidates:
                lmi = {k: v for k, v in cand.items() if k not in _ADDON_KEYS}
                g, rep = synthesize_channel(ch, "axial", **lmi)
                c = replace(base, gains=(g, base.gains[1]), reports=[rep, base.reports[1]])
                addons = {"damping_gain": 0.0,
                          **{k: cand[k] for k in _ADDON_KEYS if k in cand}}
                on = addons["damping_gain"] > 0 or addons.get("depth_of_cut_gain", 0.0) > 0
                self.controllers.append(PredictiveEID(c, self.model, **addons) if on else c)

    def margins(self, rop: float, omega: float) -> list:
        """:func:`regenerative_closed_loop` of every candidate at (rop, omega)."""
        rop, omega = _check_point(rop, omega)
        return [_margin(c, self.model, rop, omega) for c in self.controllers]

    def at(self, rop: float, omega: float):
        """(controller, candidate index, its regenerative_closed_loop dict) with the most
        negative spectral abscissa at (rop, omega); ties go to the lower index."""
        m = self.margins(rop, omega)
        k = int(np.argmin([x["spectral_abscissa"] for x in m]))
        return self.controllers[k], k, m[k]


def settle_metrics(res, rop: float, omega: float, window: float = 10.0,
                   tolerance: float = SETTLE_TOLERANCE) -> dict:
    """Settle criterion on a closed-loop Result: over the last ``window`` s, the RMS error of the
    bit axial velocity relative to ``rop`` and of the bit angular velocity relative to ``omega``
    are below ``tolerance``, and the bit axial velocity stays above ``-tolerance * rop`` (no
    bounce off the rock)."""
    t = res.time
    sel = t >= t[-1] - window
    v = res["bit_axial_velocity"][sel]
    w = res["bit_angular_velocity"][sel]
    ra = float(np.sqrt(np.mean((v - rop) ** 2)) / rop)
    rw = float(np.sqrt(np.mean((w - omega) ** 2)) / omega)
    vmin = float(v.min())
    return {"rms_axial": ra, "rms_angular": rw, "min_axial_velocity": vmin,
            "settled": bool(ra < tolerance and rw < tolerance and vmin > -tolerance * rop)}


#: Rotary speed (rad/s) from which a set point below it is approached (drill there, then slow
#: down; :func:`~downhole.control.eid.references.startup_reference`), and the descent rate
#: (rad/s per s).
APPROACH_OMEGA = 20.0
DESCENT_RATE = 1.0
#: Largest spacing (rad/s) of the rotary speeds at which the descent path is checked.
PATH_STEP = 2.5


def _path_speeds(omega, approach):
    n = max(1, int(math.ceil((approach - omega) / PATH_STEP)))
    return [omega + (approach - omega) * k / n for k in range(1, n + 1)]


def _path_abscissa(schedule, k, rop, speeds):
    """Largest spectral abscissa of candidate ``k`` at (rop, w) over ``speeds``."""
    c, m = schedule.controllers[k], schedule.model
    return max(_margin(c, m, rop, w)["spectral_abscissa"] for w in speeds)


def envelope_point(model, schedule: EIDSchedule, rop: float, omega: float, *, dt: float = 2e-4,
                   duration: float = 60.0, spin_up: float = 10.0, ramp_time: float = 2.0,
                   max_depth_of_cut: float | None = None,
                   approach_omega: float | None = APPROACH_OMEGA,
                   descent_rate: float = DESCENT_RATE) -> dict:
    """One grid point: reachability, open-loop and scheduled closed-loop margins, a run from rest
    with the scheduled design, the settle criterion and why.

    Start-up: rotate, then drill (:func:`~downhole.control.eid.references.startup_reference`).
    A set point below ``approach_omega`` is approached from above: the rate of penetration is
    ramped in at ``approach_omega``, then the rotary speed is lowered to ``omega`` at
    ``descent_rate`` rad/s per s. The candidate is then the one with the most negative abscissa
    at the set point among those whose loop is also stable (linearized) at ``rop`` at every
    speed of the descent (checked every :data:`PATH_STEP` rad/s); if none is, the set point is
    approached directly with the best candidate there. ``approach_omega=None``: always directly.
    """
    from downhole.control.eid.references import startup_reference
    from downhole.string.neutral import simulate_neutral

    op = operating_point(model, rop, omega, max_depth_of_cut=max_depth_of_cut)
    out = {"rop": float(rop), "omega": float(omega), "depth_of_cut": op.depth_of_cut,
           "wob": op.wob, "reachable": op.reachable}
    if not op.reachable:
        out.update(settled=False, reason=f"unreachable: {op.reason}")
        return out
    ol = open_loop_abscissa(model, rop, omega)
    margins = schedule.margins(rop, omega)
    order = [int(i) for i in np.argsort([x["spectral_abscissa"] for x in margins], kind="stable")]
    k, approach, path = order[0], None, None
    if approach_omega is not None and approach_omega > omega:
        speeds = _path_speeds(omega, float(approach_omega))
        for j in order:
            if margins[j]["spectral_abscissa"] >= 0:
                break
            pa = _path_abscissa(schedule, j, rop, speeds)
            if pa < 0:
                k, approach, path = j, float(approach_omega), pa
                break
    ctrl, cl = schedule.controllers[k], margins[k]
    ref = startup_reference(rop, omega, spin_up, ramp_time, approach_omega=approach,
                            descent_rate=descent_rate)
    res = simulate_neutral(model, duration=duration, dt=dt, controller=ctrl, reference=ref)
    s = settle_metrics(res, rop, omega)
    sa = cl["spectral_abscissa"]
    osc = cl["rightmost_oscillatory_root"]
    dom = cl["dominant_root"]
    if s["settled"] and sa < 0:
        reason = "settled"
    elif s["settled"]:
        reason = (f"settled although the linearized closed loop is not stable "
                  f"(abscissa {sa:+.2f} 1/s)")
    elif sa >= 0 and ol[0] > 0:
        reason = (f"open-loop bit/rock mode unstable ({ol[0]:+.2f} 1/s at {ol[1]:.0f} rad/s); "
                  f"no candidate design stabilizes it (best {sa:+.2f} 1/s, rightmost root at "
                  f"{abs(dom[1]):.1f} rad/s)")
    elif sa >= 0:
        reason = (f"closed loop unstable ({sa:+.2f} 1/s) although the open-loop bit/rock mode "
                  f"is stable ({ol[0]:+.2f} 1/s)")
    else:
        reason = (f"linearized closed loop stable ({sa:+.2f} 1/s) but the run did not settle "
                  f"(RMS {100 * s['rms_axial']:.1f} % / {100 * s['rms_angular']:.1f} %)")
    out.update(open_loop_abscissa=ol[0], open_loop_frequency=ol[1],
               default_abscissa=margins[0]["spectral_abscissa"], candidate=k,
               closed_loop_abscissa=sa, closed_loop_dominant_root=dom,
               closed_loop_regenerative_root=osc, approach_omega=approach,
               path_abscissa=path, **s, reason=reason)
    return out


def envelope_map(model, omegas, rops, *, schedule: EIDSchedule | None = None,
                 **kwargs) -> list:
    """:func:`envelope_point` over the grid ``omegas`` x ``rops`` (rad/s, m/s); keywords as
    there. Returns one dict per point, rotary speed outer."""
    omegas = [float(w) for w in omegas]
    rops = [float(r) for r in rops]
    if not omegas or not rops:
        raise DownholeInputError("envelope_map: empty grid")
    sched = schedule if schedule is not None else EIDSchedule(model)
    return [envelope_point(model, sched, r, w, **kwargs) for w in omegas for r in rops]
