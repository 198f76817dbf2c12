"""Two-degree-of-freedom DHP: a start-up trajectory planned on the design FEM (beyond the seed).

The seed's DHP tracks a reference at every node (Eqs. 4.21-4.23) from t = 0. For a step on a
string at rest that reference is far from anything the string can do in the first seconds (the
torsional wave needs ~1.6 s to reach the bit of a 5 km string), so the trained feedback sees
large errors at every node, saturates the top drive and sends a sharp torque front down the
string. The 24-state FEM smears that front; a finer plant (the 68-state hybrid) does not, and its
reflection off the top drive sets the settling time (docs/dhp.md, "The 68-state hybrid").

Here the start-up is planned instead:

1. :func:`plan_trajectory` finds smooth, piecewise-linear top inputs (slack-off force and
   surface torque at knots every ``knot_spacing`` s, held after the last knot) for which the
   design FEM itself - the :class:`~downhole.string.fem.DirectionalModel` the 24-state design
   model is exported from, run by its compiled implicit integrator - takes the bit to the
   reference velocities and the string to its steady deflection. It is a nonlinear least-squares
   problem (SciPy ``least_squares``, trust-region reflective, finite differences): bit-velocity
   errors from ``settle_from`` on, node velocities and node deflections relative to the bit from
   ``steady_from`` on, the second differences of the knots (smoothness) and the last knot's
   distance from the steady feed-forward. No model but the design FEM is used.
2. :func:`planned_controller` keeps the trained DHP gains ``kd_k`` and replaces the reference
   and the feed-forward by the planned states and inputs (the controller law
   u = u_plan,k - kd_k (z - r_plan,k) with kc = 0, since the plan is a trajectory of the model);
   after the planned segment it continues with the usual consistent reference, shifted rigidly
   so that it joins the plan (the bit positions keep the lag of the start-up: the controller
   does not try to catch up the angle lost while the first wave travels down).

On the design FEM the closed loop reproduces the plan exactly (the error stays zero; tested).
On another plant the gains only correct the plan's error there, which is small because the
plan's inputs are smooth (the 24-state FEM and the 68-state hybrid answer smooth inputs alike).
:func:`design_dhp_planned` does both steps.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from downhole.control.affine import ControlAffineModel
from downhole.control.dhp.controller import DHPController
from downhole.control.dhp.references import BitReference
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

__all__ = [
    "PlanSettings",
    "PlannedTrajectory",
    "design_dhp_planned",
    "plan_trajectory",
    "planned_controller",
]

@dataclass(frozen=True)
class PlanSettings:
    """Settings of :func:`plan_trajectory` (times in s, weights non-dimensional).

    Attributes
    ----------
    duration : float
        Length of the planned segment; the reference continues as usual after it.
    knot_spacing : float
        Time between input knots (the inputs are piecewise linear from 0 at t = 0).
    n_knots : int
        Number of knots; the last one is held to the end of the segment.
    settle_from : float
        Bit-velocity errors count from this time on (before it the first wave is on its way).
    late_from, late_weight : float
        From ``late_from`` on the bit-velocity errors weigh ``late_weight`` times more.
    steady_from : float
        From this time on the node velocities and the node deflections relative to the bit are
        pulled to the steady consistent reference (so that the plan joins it).
    steady_weight, smoothness, terminal_weight : float
        Weights of the steady-state residuals, of the knots' second differences and of the
        last knot's distance from the steady feed-forward.
    axial_tolerance, angular_tolerance : float
        Error scales: m/s and rad/s (the 5% band of 10 mm/s and 20 rad/s by default).
    max_evaluations : int
        Residual evaluations of the least-squares solver (each a compiled run of the FEM).
    top_drive_inertia : float
        kg m^2 (as the design model and the plant).
    """

    duration: float = 7.0
    knot_spacing: float = 0.4
    n_knots: int = 12
    settle_from: float = 3.0
    late_from: float = 4.0
    late_weight: float = 3.0
    steady_from: float = 4.5
    steady_weight: float = 1.0
    smoothness: float = 1.0
    terminal_weight: float = 30.0
    axial_tolerance: float = 5e-4
    angular_tolerance: float = 1.0
    max_evaluations: int = 80
    top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA

    def __post_init__(self):
        for name in ("duration", "knot_spacing", "axial_tolerance", "angular_tolerance",
                     "top_drive_inertia"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise DownholeInputError(f"PlanSettings.{name} must be a positive number, "
                                         f"got {v!r}")
        for name in ("settle_from", "late_from", "steady_from", "late_weight", "steady_weight",
                     "smoothness", "terminal_weight"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise DownholeInputError(f"PlanSettings.{name} must be a number >= 0, got "
                                         f"{v!r}")
        for name in ("n_knots", "max_evaluations"):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                raise DownholeInputError(f"PlanSettings.{name} must be an integer >= 1, got "
                                         f"{v!r}")
        if self.n_knots * self.knot_spacing > self.duration + 1e-12:
            raise DownholeInputError(
                f"PlanSettings: the knots end at {self.n_knots * self.knot_spacing:g} s, past "
                f"duration = {self.duration:g} s; use fewer knots or a longer duration")
        for name in ("settle_from", "steady_from"):
            if getattr(self, name) >= self.duration:
                raise DownholeInputError(f"PlanSettings.{name} = {getattr(self, name):g} s must "
                                         f"be before duration = {self.duration:g} s")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class PlannedTrajectory:
    """A planned start-up on the design FEM (physical units, design-model state order).

    Attributes
    ----------
    time : ndarray (n + 1,)
    states : ndarray (n + 1, n_states)
        The design model's states (node positions from the hanging equilibrium and velocities).
    inputs : ndarray (n, m)
        Slack-off force (N) and surface torque (N m) applied over each step.
    knots : ndarray (n_knots, m)
        The optimized knot values (physical).
    cost : float
        Final least-squares cost (half the sum of squared residuals).
    evaluations : int
        FEM runs used.
    seconds : float
        Wall time of the optimization.
    settings : PlanSettings
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    knots: np.ndarray
    cost: float
    evaluations: int
    seconds: float
    settings: PlanSettings

    def bit_velocities(self, design: ControlAffineModel) -> tuple[np.ndarray, np.ndarray]:
        """(axial m/s, angular rad/s) of the bit along the plan."""
        bn = design.bit_node
        return (self.states[:, design.index("axial_velocity", bn)],
                self.states[:, design.index("angular_velocity", bn)])


def _check_pair(dmodel, design):
    from downhole.string.fem import DirectionalModel

    if not isinstance(dmodel, DirectionalModel):
        raise DownholeInputError(f"the planning model must be a DirectionalModel (the design "
                                 f"FEM), got {type(dmodel).__name__}")
    if not isinstance(design, ControlAffineModel) or design.node_depths is None:
        raise DownholeInputError("the design model must be a ControlAffineModel with "
                                 "node_depths (from directional_affine_model)")
    nd = np.asarray(design.node_depths, float)
    md = np.asarray(dmodel.node_md, float)
    if nd.max() > md.max() + 1e-6 or nd.min() < md.min() - 1e-6:
        raise DownholeInputError("the design model's node depths lie outside the planning "
                                 "model's nodes")
    _check_layout(design.state_kinds, nd.size, "the design model's")


def _check_layout(kinds, n_nodes, whose):
    """The directional state layout: positions then velocities, axial/angular per node."""
    expected = ("axial_position", "angular_position") * n_nodes + \
        ("axial_velocity", "angular_velocity") * n_nodes
    if tuple(kinds[:4 * n_nodes]) != expected:
        raise DownholeInputError(f"{whose} state layout is not the directional one (positions "
                                 "then velocities, axial/angular per node)")


def _knot_inputs(p, t, spacing, scale):
    p = np.asarray(p, float).reshape(-1, 2)
    knots = np.concatenate([[0.0], spacing * np.arange(1, p.shape[0] + 1)])
    vals = np.vstack([np.zeros((1, 2)), p])
    return np.stack([np.interp(t, knots, vals[:, j]) for j in range(2)], axis=1) * scale


def _run_plan(dmodel, design, p, st: PlanSettings, depth_of_cut="approximate"):
    """Compiled FEM run of the knot inputs; (time, design states (n+1, 4N), inputs)."""
    from downhole.control.topdrive import Hook, TopDrive
    from downhole.sim import simulate

    dt = design.dt
    n = int(round(st.duration / dt))
    t = np.arange(n + 1) * dt
    u = _knot_inputs(p, t, st.knot_spacing, design.input_scale)
    # simulate holds over step k the commands of its end, t_{k+1}; shifted by dt the schedule
    # applies u(t_k) over step k, as a controller command does
    res = simulate(
        dmodel, {"hook_load": (t + dt, float(dmodel.buoyed_weight) - u[:, 0]),
                 "surface_torque": (t + dt, u[:, 1])},
        duration=n * dt, dt=dt,
        top_drive=TopDrive(mode="torque", inertia=st.top_drive_inertia),
        hook=Hook(mode="force", wob=0.0), depth_of_cut=depth_of_cut, record_dt=dt,
        record_nodes=True)
    md = np.asarray(dmodel.node_md, float)         # record_nodes: every node of dmodel
    nd = np.asarray(design.node_depths, float)
    va, vw = res["node_axial_velocity"], res["node_angular_velocity"]
    if md.size != nd.size or np.any(np.abs(md - nd) > 1e-6):
        va = np.stack([np.interp(nd, md, row) for row in va])
        vw = np.stack([np.interp(nd, md, row) for row in vw])
    # the implicit (average-acceleration) integrator advances positions by the trapezoidal rule
    xa = np.vstack([np.zeros((1, nd.size)), np.cumsum(0.5 * (va[1:] + va[:-1]) * dt, axis=0)])
    xw = np.vstack([np.zeros((1, nd.size)), np.cumsum(0.5 * (vw[1:] + vw[:-1]) * dt, axis=0)])
    N = nd.size
    Z = np.empty((va.shape[0], 4 * N))
    Z[:, 0:2 * N:2], Z[:, 1:2 * N:2] = xa, xw
    Z[:, 2 * N::2], Z[:, 2 * N + 1::2] = va, vw
    return res.time, Z, u[:n]


def _steady(design, reference, duration):
    """Steady feed-forward (non-dimensional) and the consistent reference (physical): the
    tracking problem's own (:func:`~downhole.control.dhp.design.build_problem`)."""
    from downhole.control.dhp.design import build_problem
    from downhole.control.dhp.drilling import PenaltyWeights

    prob = build_problem(design, reference, duration, PenaltyWeights())
    return prob.u_ff, prob.reference * design.state_scale


def plan_trajectory(dmodel, design: ControlAffineModel, reference: BitReference | None = None,
                    settings: PlanSettings | None = None, *,
                    progress: bool = False) -> PlannedTrajectory:
    """Plan a smooth start-up of ``dmodel`` (the design FEM) for the bit ``reference``.

    Parameters
    ----------
    dmodel : DirectionalModel
        The FEM the design model was exported from (e.g. the 24-state FEM of Table 5.1).
    design : ControlAffineModel
        ``directional_affine_model(dmodel)``: its node depths, scales, dt and state layout.
    reference : BitReference, optional
        Default: the step 10 mm/s, 20 rad/s.
    settings : PlanSettings, optional
    progress : bool
        Progress bar over the solver's FEM runs.

    Returns
    -------
    PlannedTrajectory
    """
    from scipy.optimize import least_squares

    from downhole.control.dhp.trainer import _progress

    reference = reference or BitReference.step()
    st = settings or PlanSettings()
    if not isinstance(st, PlanSettings):
        raise DownholeInputError(f"settings must be PlanSettings, got {type(st).__name__}")
    _check_pair(dmodel, design)
    dt = design.dt
    N = np.asarray(design.node_depths).size
    uss, R = _steady(design, reference, st.duration + dt)
    uss = uss[-1]
    n = int(round(st.duration / dt))
    t = np.arange(n + 1) * dt
    vd, wd = reference.velocities(t)
    bx, ba = 2 * (N - 1), 2 * (N - 1) + 1
    rel_ref = R[:n + 1, :2 * N].copy()
    rel_ref[:, 0::2] -= R[:n + 1, [bx]]
    rel_ref[:, 1::2] -= R[:n + 1, [ba]]
    scale = np.tile([st.axial_tolerance, st.angular_tolerance], N)
    pos_scale = design.state_scale[:2 * N] / 20.0
    sel = np.nonzero(t >= st.settle_from)[0][::10]
    wsel = np.where(t[sel] >= st.late_from, st.late_weight, 1.0)
    ss = np.nonzero(t >= st.steady_from)[0][::50]
    bar = _progress(st.max_evaluations * (2 * st.n_knots + 1), progress, "plan start-up")
    count = [0]

    def residuals(p):
        count[0] += 1
        if bar is not None:
            bar[0].update(bar[1], advance=1)
        try:
            _, Z, _ = _run_plan(dmodel, design, p, st)
        except SimulationDiverged:
            Z = None
        if Z is None or not np.all(np.isfinite(Z)):
            if not res_size[0]:
                raise DownholeInputError(
                    f"the planned start-up's initial guess (a {st.knot_spacing:g} s ramp to "
                    "the steady inputs) diverges on the planning model; check the model and "
                    "the reference") from None
            return np.full(res_size[0], 1e6)     # a diverging trial: a large residual
        out = [wsel * (Z[sel, 2 * N + bx] - vd[sel]) / st.axial_tolerance,
               wsel * (Z[sel, 2 * N + ba] - wd[sel]) / st.angular_tolerance]
        rel = Z[ss, :2 * N].copy()
        rel[:, 0::2] -= Z[ss][:, [bx]]
        rel[:, 1::2] -= Z[ss][:, [ba]]
        out.append(st.steady_weight * ((rel - rel_ref[ss]) / pos_scale).ravel())
        out.append(st.steady_weight * ((Z[ss, 2 * N:] - R[ss, 2 * N:4 * N]) / scale).ravel())
        pp = np.asarray(p).reshape(-1, 2)
        d2 = np.diff(np.vstack([np.zeros((1, 2)), pp]), n=2, axis=0)
        out.append(10.0 * st.smoothness * d2.ravel())
        out.append(st.terminal_weight * (pp[-1] - uss))
        r = np.concatenate(out)
        res_size[0] = r.size
        return r

    res_size = [0]
    p0 = np.tile(uss, st.n_knots)
    t0 = time.perf_counter()
    try:
        residuals(p0)
        sol = least_squares(residuals, p0, diff_step=1e-3, max_nfev=st.max_evaluations,
                            x_scale=0.2)
    finally:
        if bar is not None:       # the total is an upper bound (the solver may stop earlier)
            bar[0].update(bar[1], total=count[0], completed=count[0])
            bar[0].stop()
    seconds = time.perf_counter() - t0
    try:
        tt, Z, u = _run_plan(dmodel, design, sol.x, st)
    except SimulationDiverged:
        Z = None
    if Z is None or not np.all(np.isfinite(Z)):
        raise DownholeInputError("the planned start-up diverged on the planning model; try a "
                                 "larger smoothness or a later settle_from")
    return PlannedTrajectory(tt, Z, u, sol.x.reshape(-1, 2) * design.input_scale,
                             float(sol.cost), count[0], seconds, st)


def planned_controller(gains: DHPController, plan: PlannedTrajectory) -> DHPController:
    """The DHP law of ``gains`` about the planned start-up ``plan``.

    ``u_k = u_plan,k - kd_k (z_k - r_plan,k)`` over the plan (kc = 0: the plan is a trajectory
    of the design FEM), then the trained reference and feed-forward, shifted rigidly (positions
    only) so that they join the plan. Integrator states (integral action) get the Euler sums of
    the plan's bit velocities (what the controller's integrators add up) as reference. The
    controller's arrays keep the shift (``reference_shift``) so that the past-horizon
    continuation and :func:`~downhole.control.dhp.load_controller` agree.
    """
    if not isinstance(gains, DHPController):
        raise DownholeInputError(f"gains must be a DHPController, got {type(gains).__name__}")
    if not isinstance(plan, PlannedTrajectory):
        raise DownholeInputError(f"plan must be a PlannedTrajectory, got {type(plan).__name__}")
    dt = gains.dt
    if abs(plan.time[1] - plan.time[0] - dt) > 1e-9 * dt:
        raise DownholeInputError(f"plan step {plan.time[1] - plan.time[0]:g} s differs from the "
                                 f"controller dt = {dt:g} s")
    npl = plan.inputs.shape[0]
    if npl >= gains.n_steps:
        raise DownholeInputError(f"the plan ({npl * dt:g} s) must be shorter than the trained "
                                 f"horizon ({gains.horizon:g} s)")
    P = gains.state_scale
    nb = plan.states.shape[1]
    kinds = gains.state_kinds
    N = nb // 4
    bx, ba = 2 * (N - 1), 2 * (N - 1) + 1
    _check_layout(kinds, N, "the controller's")
    ref = gains.reference_nd * P                      # physical
    shift = np.zeros(gains.n_states)
    dx = plan.states[-1, bx] - ref[npl, bx]
    da = plan.states[-1, ba] - ref[npl, ba]
    for i, kd in enumerate(kinds):
        if kd == "axial_position":
            shift[i] = dx
        elif kd == "angular_position":
            shift[i] = da
    integ = np.zeros((npl + 1, gains.n_states - nb))
    for j, i in enumerate(range(nb, gains.n_states)):
        # integrators (integral action): the controller's Euler sums of the plan's bit
        # velocities, so that the integrated error is zero along the plan
        src = nb // 2 + (bx if kinds[i] == "axial_position" else ba)
        integ[1:, j] = np.cumsum(plan.states[:-1, src]) * dt
        shift[i] = integ[-1, j] - ref[npl, i]
    new = ref + shift
    new[:npl + 1, :nb] = plan.states
    new[:npl + 1, nb:] = integ
    uff = gains.u_ff.copy()
    uff[:npl] = plan.inputs / gains.input_scale
    kc = gains.kc.copy()
    kc[:npl] = 0.0
    meta = dict(gains.meta)
    meta["plan"] = {"settings": plan.settings.to_dict(), "cost": plan.cost,
                    "evaluations": plan.evaluations, "seconds": plan.seconds,
                    "knots": plan.knots.tolist()}
    arrays = dict(gains.arrays)
    arrays["reference_shift"] = shift / P
    ctrl = DHPController(kc, gains.kd, new / P, uff, P, gains.input_scale, dt,
                         gains.state_names, gains.state_kinds, gains.input_names,
                         gains.reference, input_limits=gains.input_limits,
                         past_horizon=gains.past_horizon, stationary_step=gains.stationary_step,
                         meta=meta, arrays=arrays)
    if gains._model is not None:
        ctrl.attach_model(gains._model)
    if hasattr(gains, "training"):
        ctrl.training = gains.training
    return ctrl


def design_dhp_planned(design: ControlAffineModel, dmodel, reference: BitReference | None = None,
                       *, horizon: float = 40.0, weights=None, settings=None,
                       plan_settings: PlanSettings | None = None, progress: bool = False,
                       **design_kwargs) -> DHPController:
    """:func:`~downhole.control.dhp.design_dhp` on ``design`` (``design_kwargs`` passed on),
    then :func:`plan_trajectory` on ``dmodel`` and :func:`planned_controller`. The plan is kept
    in ``ctrl.plan`` and the training in ``ctrl.training``."""
    from downhole.control.dhp.design import design_dhp

    reference = reference or BitReference.step()
    gains = design_dhp(design, reference, horizon=horizon, weights=weights, settings=settings,
                       progress=progress, **design_kwargs)
    plan = plan_trajectory(dmodel, design, reference, plan_settings, progress=progress)
    ctrl = planned_controller(gains, plan)
    ctrl.plan = plan
    return ctrl
