"""Closed-loop runs of a DHP controller, returned as :class:`~downhole.sim.result.Result` objects.

- :func:`run_design_model`: the controller on its own design model (control-affine, approximated
  depth of cut with the floor of Eq. 4.16) - the plant on which the seed's Ch. 4 claims are made.
- :func:`run_on_plant`: the controller on any step-by-step plant with named signals
  (``reset() -> obs``, ``step(command) -> obs``), e.g. the lumped chain with the *delayed* depth of
  cut (:class:`downhole.string.fem.DirectionalPlant`) - the true plant.

Both add the reference channels ``reference_axial_velocity`` and ``reference_angular_velocity``
and the controller's physical inputs under their names (``slack_off_force``, ``surface_torque``,
``top_drive_axial_displacement``, ``top_drive_angle``).
"""

from __future__ import annotations

import math

import numpy as np

from downhole.control.affine import INPUT_UNITS, ControlAffineModel
from downhole.control.dhp.controller import DHPController
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.sim.loop import run_loop
from downhole.sim.plant import plant_bit_radius
from downhole.sim.result import Result

__all__ = ["channels_from_states", "run_design_model", "run_on_plant"]


def _check_duration(duration, dt):
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise DownholeInputError(f"duration must be a positive number of seconds, got "
                                 f"{duration!r}")
    n = int(round(duration / dt))
    if n < 1:
        raise DownholeInputError(f"duration {duration} s is shorter than one step ({dt} s)")
    return n


def channels_from_states(model: ControlAffineModel, z: np.ndarray, u: np.ndarray) -> dict:
    """Standard Result channels from physical states z (T, n) and inputs u (T, m)."""
    bn = model.bit_node
    ch = {"bit_axial_position": z[:, model.index("axial_position", bn)],
          "bit_axial_velocity": z[:, model.index("axial_velocity", bn)],
          "bit_angle": z[:, model.index("angular_position", bn)],
          "bit_angular_velocity": z[:, model.index("angular_velocity", bn)]}
    if model.outputs is not None:
        ch.update(model.outputs(z, u))
    if "wob" not in ch and model.bit is not None:
        from downhole.control.dhp.drilling import bit_forces_batch

        f = bit_forces_batch(ch["bit_axial_velocity"], ch["bit_angular_velocity"], model.bit)
        ch.update(wob=f[:, 0], tob=f[:, 1], depth_of_cut=f[:, 2])
    names = list(model.input_names)
    if "hook_load" not in ch and "slack_off_force" in names:
        ch["hook_load"] = model.hanging_hook_load - u[:, names.index("slack_off_force")]
    if "surface_torque" not in ch and "surface_torque" in names:
        ch["surface_torque"] = u[:, names.index("surface_torque")]
    for kind, name in (("axial_velocity", "top_drive_axial_velocity"),
                       ("angular_velocity", "top_drive_angular_velocity")):
        if name not in ch and 0 in model.nodes:
            idx = model.indices(kind, 0)
            if idx.size == 1:
                ch[name] = z[:, idx[0]]
    for name in ("depth_of_cut", "wob", "tob", "hook_load", "surface_torque",
                 "top_drive_axial_velocity", "top_drive_angular_velocity"):
        ch.setdefault(name, np.full(z.shape[0], np.nan))
    return ch


def run_design_model(controller: DHPController, model: ControlAffineModel, duration: float, *,
                     z0=None, record_every: int = 1, attrs: dict | None = None) -> Result:
    """Run ``controller`` on the control-affine design ``model`` for ``duration`` s.

    Parameters
    ----------
    controller : DHPController
    model : ControlAffineModel
        Must have the controller's states and dt.
    duration : float
        Simulated time, s (past the trained horizon the controller's policy applies).
    z0 : array_like (n,), optional
        Initial physical state (default: rest at the hanging equilibrium, bit on bottom).
    record_every : int
        Keep every ``record_every``-th sample.

    Returns
    -------
    Result

    Raises
    ------
    SimulationDiverged
        A state became non-finite; names the time and the state.
    """
    n_ctrl = controller.n_states
    if controller._integral is not None and model.n_states != n_ctrl:
        n_ctrl = int(controller._integral["n_base"])   # the controller keeps its integrators
    if abs(model.dt - controller.dt) > 1e-12 * model.dt or model.n_states != n_ctrl:
        raise DownholeInputError(f"model (n={model.n_states}, dt={model.dt}) does not match the "
                                 f"controller (n={controller.n_states}, dt={controller.dt})")
    n = _check_duration(duration, model.dt)
    z = np.zeros(model.n_states) if z0 is None else np.asarray(z0, float).copy()
    Z = np.empty((n + 1, model.n_states))
    U = np.empty((n + 1, model.n_inputs))
    P, Us = model.state_scale, model.input_scale
    names = list(controller.input_names)
    state = {"zb": z / P, "k": 0}

    def step(u):
        zb = state["zb"] = model.step(state["zb"], u / Us)
        state["k"] += 1
        if not np.all(np.isfinite(zb)):
            bad = int(np.argmax(~np.isfinite(zb)))
            raise SimulationDiverged(state["k"] * model.dt, model.state_names[bad])
        return {"state": zb * P}

    def write(out, seen, u):
        u[:] = [out[nm] for nm in names]

    def on_sample(k, obs, u):
        Z[k] = obs["state"]
        U[k] = u

    controller.reset()
    run_loop(step, controller, {"state": state["zb"] * P}, n, model.dt,
             held=np.empty(model.n_inputs), write=write, on_sample=on_sample)
    return _result(controller, model, Z[::record_every], U[::record_every],
                   np.arange(n + 1)[::record_every] * model.dt, "design model", attrs)


def _result(controller, model, Z, U, t, plant, attrs):
    ch = channels_from_states(model, Z, U)
    v, w = controller.reference.velocities(t)
    ch["reference_axial_velocity"] = v
    ch["reference_angular_velocity"] = w
    units = {}
    for i, name in enumerate(model.input_names):
        ch[name] = U[:, i]
        units[name] = INPUT_UNITS.get(name, "")
    meta = {"model": model.name, "plant": plant, "controller": "dhp", "dt": model.dt,
            "reference": controller.reference.kind, "trained_horizon": controller.horizon}
    if model.bit is not None:
        meta["bit_radius"] = model.bit.radius
        meta["n_blades"] = model.bit.n_blades
    meta.update(attrs or {})
    return Result(t, ch, units=units, attrs=meta)


def run_on_plant(controller: DHPController, plant, duration: float, *, adapter=None,
                 record_every: int = 1, attrs: dict | None = None) -> Result:
    """Run ``controller`` against a step-by-step ``plant`` (the true, e.g. delayed-cut, plant).

    Parameters
    ----------
    controller : DHPController
    plant : object
        ``reset() -> obs`` and ``step(command) -> obs`` with named signals; ``plant.dt`` must
        equal the controller's dt. Observations must contain the controller's state names (or
        ``"state"``).
    duration : float
        Simulated time, s.
    adapter : callable, optional
        ``adapter(command, observation, dt) -> plant command`` (e.g. top displacements to top
        velocities); default: the controller's command unchanged.
    record_every : int
        Keep every ``record_every``-th sample.

    Returns
    -------
    Result
        The plant's observations (standard channels), the reference channels and the
        controller's inputs.
    """
    dt = float(getattr(plant, "dt", controller.dt))
    if abs(dt - controller.dt) > 1e-12 * dt:
        raise DownholeInputError(f"plant dt = {dt} differs from the controller dt = "
                                 f"{controller.dt}")
    n = _check_duration(duration, dt)
    obs = plant.reset()
    controller.reset()
    rows, inputs, times = [], [], []
    keys = [kk for kk in obs if isinstance(obs[kk], (int, float)) and kk != "time"]
    given: dict = {}

    def write(out, seen, held):
        given.clear()
        given.update(out)
        held.clear()
        held.update(adapter(out, seen, dt) if adapter is not None else out)

    def on_sample(k, o, held):
        if k % record_every == 0:
            rows.append([o[kk] for kk in keys])
            inputs.append([given[nm] for nm in controller.input_names])
            times.append(k * dt)

    run_loop(plant.step, controller, obs, n, dt, held={}, write=write, on_sample=on_sample)
    data = np.asarray(rows, dtype=float)
    ch = {kk: data[:, i] for i, kk in enumerate(keys)}
    t = np.asarray(times)
    v, w = controller.reference.velocities(t)
    ch["reference_axial_velocity"] = v
    ch["reference_angular_velocity"] = w
    U = np.asarray(inputs)
    units = {}
    for i, name in enumerate(controller.input_names):
        ch[name] = U[:, i]
        units[name] = INPUT_UNITS.get(name, "")
    meta = {"plant": type(plant).__name__, "controller": "dhp", "dt": dt,
            "reference": controller.reference.kind, "trained_horizon": controller.horizon}
    radius = plant_bit_radius(plant)
    if radius is not None:  # for the MSE of Result.summary()
        meta["bit_radius"] = radius
    meta.update(attrs or {})
    return Result(t, ch, units=units, attrs=meta)


class DisplacementToVelocity:
    """Adapter: top-drive displacement commands (m, rad) -> velocity commands over one step.

    For plants driven by top-drive velocities (:class:`downhole.string.fem.DirectionalPlant` in
    ``"velocity"`` mode): the commanded velocity moves the top to the commanded displacement by
    the end of the step, within the drive's admissible velocities
    (the ranges of :data:`downhole.signals.SIGNALS`): a displacement further than one step can reach
    (the controller's first command winds the string up from the hanging position) is
    approached at the drive's limit, never jumped to."""

    def __init__(self):
        from downhole.signals import SIGNALS

        self.top = np.zeros(2)
        self.limits = np.array([(SIGNALS[n].low, SIGNALS[n].high) for n in
                                ("top_drive_axial_velocity", "top_drive_angular_velocity")])

    def __call__(self, cmd, obs, dt):
        u = np.array([cmd["top_drive_axial_displacement"], cmd["top_drive_angle"]])
        vel = np.clip((u - self.top) / dt, self.limits[:, 0], self.limits[:, 1])
        self.top = self.top + vel * dt
        return {"top_drive_axial_velocity": float(vel[0]),
                "top_drive_angular_velocity": float(vel[1])}


def lumped_true_plant(string="table_2_1", bit=None, *, dt: float = 1e-3,
                      depth_of_cut: str = "delayed"):
    """The 4th-order lumped plant (lead's compiled chain) and its command adapter.

    Returns ``(plant, adapter)`` for :func:`run_on_plant`; ``depth_of_cut="delayed"`` is the true
    plant (rock-surface memory), ``"approximate"`` the design-model bit law."""
    from downhole.sim.lumped_model import lumped_model
    from downhole.string.fem import DirectionalPlant

    model = lumped_model(string, bit, order=4) if bit is not None else lumped_model(string,
                                                                                    order=4)
    return (DirectionalPlant(model, dt=dt, mode="velocity", depth_of_cut=depth_of_cut),
            DisplacementToVelocity())


__all__ += ["DisplacementToVelocity", "lumped_true_plant"]
