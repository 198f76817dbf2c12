"""``simulate()``: the one entry point that runs any model open loop or closed loop and returns a
Result, through the one mechanics kernel (:func:`downhole.sim.kernel.run_kernel`).

Every model (lumped :class:`~downhole.sim.lumped_model.ChainModel`, neutral-type
:class:`~downhole.string.neutral.NeutralModel`, FEM and hybrid
:class:`~downhole.string.fem.DirectionalModel`) is a configuration of the kernel: its
``run_pack(dt, depth_of_cut, inputs, bit_noise, options)`` returns a *pack* (the kernel's arrays
for that configuration) with the few methods this module calls:

- ``rows(inputs, t)``: the commands at the step boundaries ``t`` (shape ``(len(t), k)``; the
  kernel holds row k + 1 over step k, or, for a lumped top, moves the top between rows k and
  k + 1);
- ``begin(start, rows, clearance)``: the kernel state and the record of t = 0;
- ``run(st, rows, rec, every, row)``: advance ``len(rows) - 1`` steps, recording every
  ``every`` steps into ``rec`` from row ``row``;
- ``step(st, command, rec)``: one step holding a command (the closed loop);
- ``command(out, held)``: a controller's output as a command row;
- ``channels(rec, rows, idx)``: the Result's channels, units and attributes;
- ``kind``, ``dt``, ``command_names``, ``n_cmd``.

So there is one simulate, one open-loop run and one Python closed loop for every model; the step
by step form of the same runs is :class:`downhole.string.fem.DirectionalPlant`.
"""

from __future__ import annotations

import math

import numpy as np

from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.sim.kernel import CHANNELS
from downhole.sim.loop import run_loop
from downhole.sim.lumped_model import DEPTH_OF_CUT_MODES, INTEGRATORS
from downhole.sim.plant import check_start
from downhole.sim.references import as_reference
from downhole.sim.result import Result
from downhole.units import si_or_number

__all__ = ["DEPTH_OF_CUT_MODES", "INTEGRATORS", "simulate"]

#: Steps per kernel call of a long open-loop run (a KeyboardInterrupt is delivered between
#: calls, so Ctrl-C ends a long run within one piece).
_PIECE = 200_000


def _positive(name, value):
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise DownholeInputError(f"{name} must be a positive number of seconds, got {value!r}")
    return float(value)


def simulate(model, inputs=None, *, duration: float = 20.0, dt: float | None = None,
             controller=None, reference=None, noise: dict | None = None, seed: int = 0,
             control_dt: float | None = None, python_loop: bool = False, start: str = "rest",
             clearance: float = 0.05, record_dt: float | None = None,
             record_nodes: bool = False, depth_of_cut: str = "delayed",
             attrs: dict | None = None, **options) -> Result:
    """Simulate a drill-string model with fixed steps, open loop or under a controller.

    Parameters
    ----------
    model : ChainModel, NeutralModel or DirectionalModel
        From :func:`~downhole.sim.lumped_model.lumped_model`,
        :func:`~downhole.string.neutral.neutral_model`, :func:`~downhole.string.fem.fem_model`,
        :func:`~downhole.string.hybrid.hybrid_model` or ``DrillingSystem.build``.
    inputs : optional
        Open-loop commands (ignored with a controller). Lumped: a
        :class:`~downhole.sim.inputs.SurfaceInputs` (default ``SurfaceInputs.velocity(0.01,
        10.0)``; ``SurfaceInputs.force(...)`` drives the top by hook load and torque). Neutral:
        ``SurfaceInputs.velocity(U_A, U_T)`` or a pair of signals in the seed's convention (U_A
        includes M_S g / alpha_A; default the nominal commands, 10 mm/s and 20 rad/s).
        FEM/hybrid: a mapping from command name to signal, ``hook_load`` (N, force hook) or
        ``top_drive_axial_velocity`` (m/s, velocity hook) and ``top_drive_angular_velocity``
        (the top drive's speed set-point, rad/s) or ``surface_torque`` (N m, torque mode);
        default the hook's and top drive's own. A signal is a constant, ``(times, values)`` or
        ``f(t)``.
    duration : float
        Simulated time, s. This and ``dt``, ``record_dt``, ``control_dt`` and ``clearance``
        also accept a quantity string (``"20 s"``, ``"0.5 ms"``) or a pint Quantity.
    dt : float, optional
        Step, s; default the model's ``default_dt`` (lumped 0.5 ms, the seed's; neutral 0.1 ms;
        FEM/hybrid 1 ms).
    controller : object, optional
        Closed loop: any object with ``reset()`` and ``command(t, observation, reference) ->
        {command name: value}`` (:class:`downhole.control.base.Controller`) runs in a Python
        loop over the kernel: at t_k it sees the channels of t_k (bit velocities plus the
        measurement noise) and its command is held over the next ``control_dt``. Compiled fast
        path (duck-typed): if the controller has ``kernel_runner(pack)`` returning a callable
        ``runner(pack, st, ref, mnoise, cmd_noise, nsteps, every, rec) -> (status, step,
        extra)``, the loop runs there (``extra``: further channels per record row); ``None``
        falls back to the Python loop.
    reference : Reference or pair of signals, optional
        Closed-loop reference (bit axial velocity m/s, bit angular velocity rad/s); default the
        controller's ``reference`` attribute, else 10 mm/s and 20 rad/s.
    noise : dict, optional
        Closed loop: ``{"axial": sigma_v, "angular": sigma_w}`` white measurement noise on the
        bit velocities the controller sees (m/s, rad/s per sample). Neutral model: also
        ``"wob"``, ``"tob"`` (N, N m per step) added to the bit forces, open or closed loop.
    seed : int
        Noise seed.
    control_dt : float, optional
        Controller sample time, a multiple of dt (default dt); the command is held between
        samples.
    python_loop : bool
        Ignore a controller's compiled ``kernel_runner``.
    start : {"rest", "off_bottom", "steady"}
        Initial state (:data:`downhole.sim.plant.START_MODES`) under the commands of t = 0;
        a closed loop starts from ``rest``.
    clearance : float
        Bit height above the hole bottom for ``start="off_bottom"``, m.
    record_dt : float, optional
        Output interval, s (rounded to a multiple of dt); default every step up to 20 000
        samples, then thinned. The last step is always recorded.
    record_nodes : bool
        Also record ``node_axial_velocity`` and ``node_angular_velocity`` (time x node or DOF).
    depth_of_cut : {"delayed", "approximate"}
        ``delayed``: from the rock-surface memory (Eqs. 2.9-2.10 corrected); ``approximate``:
        d = 2 pi v / omega (Eq. 2.11).
    attrs : dict, optional
        Extra metadata merged into the Result's attributes.
    **options
        The model's own: lumped ``integrator`` (``"euler"``, the seed's, or ``"newmark"``),
        ``rock_points_per_pitch``, ``rock_memory``; neutral ``rock_points_per_pitch``;
        FEM/hybrid ``top_drive`` (:class:`~downhole.params.rig.TopDrive`) and ``hook``
        (:class:`~downhole.params.rig.Hook`).

    Returns
    -------
    Result
        Standard channels (:data:`downhole.sim.result.CHANNEL_UNITS`) and the model's own
        (FEM/hybrid: forces at B and C; neutral: ``command_axial``/``command_angular``, U_A and
        U_T); closed loop also the reference and measured velocities and a compiled runner's
        channels. Attribute ``bit_radius`` (for MSE), ``model``, ``dt``, ``start``,
        ``controller``.

    Raises
    ------
    DownholeInputError
        Invalid arguments, named.
    SimulationDiverged
        The bit state ran away or went non-finite; the message names the time and channel.

    Examples
    --------
    >>> from downhole.sim.inputs import SurfaceInputs
    >>> from downhole.sim.lumped_model import lumped_model
    >>> res = simulate(lumped_model("table_2_1"), SurfaceInputs.velocity(0.01, 10.0),
    ...                duration=2.0, dt=5e-4)
    >>> res.time[-1]
    2.0
    """
    if not hasattr(model, "run_pack"):
        raise DownholeInputError(f"simulate() takes a model (lumped_model, neutral_model, "
                                 f"fem_model, hybrid_model or DrillingSystem.build), got "
                                 f"{type(model).__name__}")
    duration = _positive("duration", si_or_number(duration, "time", "duration"))
    dt = _positive("dt", si_or_number(model.default_dt if dt is None else dt, "time", "dt"))
    record_dt = si_or_number(record_dt, "time", "record_dt")
    control_dt = si_or_number(control_dt, "time", "control_dt")
    clearance = si_or_number(clearance, "length", "clearance")
    if depth_of_cut not in DEPTH_OF_CUT_MODES:
        raise DownholeInputError(f"depth_of_cut must be one of {DEPTH_OF_CUT_MODES}, got "
                                 f"{depth_of_cut!r}")
    check_start(start)
    nsteps = int(round(duration / dt))
    if nsteps < 1:
        raise DownholeInputError(f"duration = {duration} s is shorter than one step dt = {dt} s")
    if abs(nsteps * dt - duration) > 1e-9 * max(1.0, duration):
        raise DownholeInputError(f"dt = {dt} s does not divide duration = {duration} s")
    if record_dt is None:
        every = max(1, int(math.ceil((nsteps + 1) / 20000)))
    else:
        if not (isinstance(record_dt, (int, float)) and record_dt >= dt):
            raise DownholeInputError(f"record_dt must be >= dt ({dt} s), got {record_dt!r}")
        every = max(1, int(round(record_dt / dt)))
    sig = _noise(noise)
    bit_noise = sig["wob"] > 0 or sig["tob"] > 0
    closed = controller is not None
    pk = model.run_pack(dt, depth_of_cut, None if closed else inputs, bit_noise, options)
    t = np.arange(nsteps + 1) * dt
    rng = np.random.default_rng(seed)
    mnoise = np.zeros((2, nsteps + 1)) if closed else None
    for i, key in enumerate(("axial", "angular")):
        if sig[key] > 0:
            if not closed:
                raise DownholeInputError(f"noise.{key} is measurement noise: it needs a "
                                         "controller")
            mnoise[i] = rng.normal(0.0, sig[key], nsteps + 1)
    nrec = nsteps // every + 1 + (1 if nsteps % every else 0)
    idx = np.minimum(np.arange(nrec) * every, nsteps)
    rec = np.empty((nrec, len(CHANNELS)))
    meta = {"model": model.name, "dt": dt, "depth_of_cut": depth_of_cut, "start": start,
            "bit_radius": model.bit.radius, "n_blades": model.bit.n_blades,
            "controller": "open-loop"}
    if closed:
        if start != "rest":
            raise DownholeInputError(f"start={start!r} needs an open-loop run: a closed loop "
                                     "starts from 'rest' (the controller's integrators and "
                                     "predictor have no equilibrium initialization)")
        if record_nodes:
            raise DownholeInputError("record_nodes needs an open-loop run")
        if not (hasattr(controller, "command") and hasattr(controller, "reset")):
            raise DownholeInputError("controller must have reset() and command(t, observation, "
                                     f"reference); got {type(controller).__name__}")
        if reference is None:
            reference = getattr(controller, "reference", None)
        reference = as_reference(reference)
        ref = reference.sample(t)
        meta["reference"] = reference.name
        meta["controller"] = getattr(controller, "label", type(controller).__name__)
        rows = pk.still_rows(t)
        _bit_noise(pk, rows, sig, rng)
        st, rec[0] = pk.begin("rest", rows, clearance)
        hook = getattr(controller, "kernel_runner", None)
        runner = hook(pk) if (hook is not None and not python_loop) else None
        if runner is not None:
            status, kfail, extra = runner(pk, st, ref, mnoise, rows[1:, 2:pk.n_cmd], nsteps,
                                          every, rec)
        else:
            status, kfail, extra = _python_loop(pk, st, controller, ref, mnoise, rows, nsteps,
                                                every, rec, control_dt, meta)
        if status != 0:
            raise SimulationDiverged(kfail * dt, _diverged_channel(st["state"]))
        channels, units, more = pk.channels(rec, None, idx)
        channels["reference_axial_velocity"] = ref[0, idx]
        channels["reference_angular_velocity"] = ref[1, idx]
        channels.update(extra)
    else:
        rows = pk.rows(inputs, t)
        _bit_noise(pk, rows, sig, rng)
        st, rec[0] = pk.begin(start, rows, clearance)
        nodes = None
        if record_nodes:
            nodes = np.zeros((2, nrec, st["state"].shape[1]))
            nodes[0, 0], nodes[1, 0] = st["state"][1], st["state"][4]
        k, row = 0, 1
        while k < nsteps:
            # pieces of whole record intervals (one interval when nodes are recorded), then the
            # remainder recorded at its end
            n_main = ((nsteps - k) // every) * every
            m = every if nodes is not None else min(n_main, max(every, _PIECE // every * every))
            rec_every = every
            if n_main == 0:
                m = rec_every = nsteps - k
            status, r = pk.run(st, rows[k:k + m + 1], rec, rec_every, row)
            if status != 0:
                raise SimulationDiverged(float(st["run"]["time"][0]),
                                         _diverged_channel(st["state"]))
            if nodes is not None:
                nodes[0, row], nodes[1, row] = st["state"][1], st["state"][4]
            k += m
            row += r  # between pieces Python runs: Ctrl-C (KeyboardInterrupt) acts here
        channels, units, more = pk.channels(rec, rows, idx)
        if nodes is not None:
            channels["node_axial_velocity"] = nodes[0]
            channels["node_angular_velocity"] = nodes[1]
            units.update(node_axial_velocity="m/s", node_angular_velocity="rad/s")
    meta.update(more)
    meta.update(attrs or {})
    return Result(t[idx], channels, units=units, attrs=meta)


def _noise(noise) -> dict:
    noise = dict(noise or {})
    unknown = set(noise) - {"axial", "angular", "wob", "tob"}
    if unknown:
        raise DownholeInputError(f"noise: unknown keys {sorted(unknown)}; expected axial, "
                                 "angular, wob, tob")
    out = {}
    for key in ("axial", "angular", "wob", "tob"):
        s = float(noise.get(key, 0.0))
        if not s >= 0 or not math.isfinite(s):
            raise DownholeInputError(f"noise.{key} must be >= 0, got {s}")
        out[key] = s
    return out


def _bit_noise(pk, rows, sig, rng) -> None:
    """WOB and TOB noise into command columns 2 and 3 (the step k holds row k + 1)."""
    if pk.n_cmd < 4:
        return
    for i, key in enumerate(("wob", "tob")):
        if sig[key] > 0:
            rows[1:, 2 + i] = rng.normal(0.0, sig[key], rows.shape[0] - 1)


def _python_loop(pk, st, controller, ref, mnoise, rows, nsteps, every, rec, control_dt, meta):
    """Closed loop with a controller stepped from Python (:func:`downhole.sim.loop.run_loop`):
    at t_k it sees the record of t_k (bit velocities with the measurement noise) and its command
    is held over the next ``control_dt``."""
    dt = pk.dt
    if control_dt is None:
        sub = 1
    else:
        sub = int(round(_positive("control_dt", control_dt) / dt))
        if sub < 1 or abs(sub * dt - control_dt) > 1e-9 * control_dt:
            raise DownholeInputError(f"control_dt = {control_dt} s must be a multiple of dt = "
                                     f"{dt} s")
    if nsteps % sub:
        raise DownholeInputError(f"duration must be a multiple of control_dt = {sub * dt} s")
    meta["control_dt"] = sub * dt
    if getattr(controller, "dt", None) is not None:
        controller.dt = sub * dt  # the contract's sample time (downhole.control.base)
    controller.reset()
    nrec = rec.shape[0]
    extra = {k: np.full(nrec, np.nan) for k in ("measured_axial_velocity",
                                                "measured_angular_velocity")}
    cmd_hist = np.full((nrec, pk.n_cmd), np.nan)
    row = np.zeros((1, len(CHANNELS)))
    held = pk.first_command(rows)
    if pk.n_cmd > 2:
        held = np.concatenate([held[:2], rows[0, 2:pk.n_cmd]])
    who = type(controller).__name__
    taken = [0]

    def step(h):
        k = taken[0]
        if pk.n_cmd > 2:
            h[2:] = rows[k + 1, 2:pk.n_cmd]
        status, _ = pk.step(st, h, row)
        if status != 0:
            raise SimulationDiverged(k * dt, _diverged_channel(st["state"]))
        taken[0] = k + 1
        return row[0].copy()

    def measure(k, last):
        obs = dict(zip(CHANNELS, last.tolist()))
        obs["time"] = k * dt
        obs["bit_axial_velocity"] += mnoise[0, k]
        obs["bit_angular_velocity"] += mnoise[1, k]
        return obs

    def on_sample(k, last, h):
        r = k // every if k % every == 0 else (nrec - 1 if k == nsteps else -1)
        if r >= 0:
            rec[r] = last
            cmd_hist[r] = h
            extra["measured_axial_velocity"][r] = last[1] + mnoise[0, k]
            extra["measured_angular_velocity"][r] = last[3] + mnoise[1, k]

    def reference(k, t):
        return {"reference_axial_velocity": float(ref[0, k]),
                "reference_angular_velocity": float(ref[1, k])}

    run_loop(step, controller, rec[0].copy(), nsteps, dt, held=held,
             write=lambda out, seen, h: pk.command(out, h, who), reference=reference,
             every=sub, measure=measure, on_sample=on_sample)
    extra.update(pk.command_channels(cmd_hist))
    return 0, nsteps, extra


def _diverged_channel(state) -> str:
    """The bit channel that ran away (the first of position, velocity, angle, angular
    velocity that is non-finite or beyond the kernel's guard)."""
    for name, row, lim in (("bit_axial_position", 0, 1e9), ("bit_axial_velocity", 1, 1e9),
                           ("bit_angle", 3, 1e12), ("bit_angular_velocity", 4, 1e12)):
        x = state[row, -1]
        if not (abs(x) < lim):
            return name
    return "bit_angular_velocity"
