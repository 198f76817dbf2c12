"""``simulate()``: the one entry point that runs a drill-string model open loop and returns a Result.

Also :class:`LumpedPlant`, the step-by-step (reset/step) form of the same compiled kernel for
closed-loop use with named signals.
"""

from __future__ import annotations

import math

import numpy as np

from downhole.bit.law import bit_forces
from downhole.bit.rock_surface import RockSurfaceSpec, rock_init, rock_init_helix
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.sim.chain_kernel import CHANNELS, run_chain
from downhole.sim.inputs import SurfaceInputs
from downhole.sim.lumped_model import ChainModel
from downhole.sim.plant import Plant, check_start, steady_depth_of_cut
from downhole.sim.result import Result
from downhole.units import si_or_number

__all__ = ["DEPTH_OF_CUT_MODES", "INTEGRATORS", "LumpedPlant", "simulate"]

DEPTH_OF_CUT_MODES = ("delayed", "approximate")
INTEGRATORS = ("euler", "newmark")


def _check(duration, dt, depth_of_cut, integrator, record_dt):
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise DownholeInputError(f"duration must be a positive number of seconds, got {duration!r}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 0 < dt <= duration):
        raise DownholeInputError(f"dt must be in (0, duration], got {dt!r}")
    if depth_of_cut not in DEPTH_OF_CUT_MODES:
        raise DownholeInputError(f"depth_of_cut must be one of {DEPTH_OF_CUT_MODES}, got {depth_of_cut!r}")
    if integrator not in INTEGRATORS:
        raise DownholeInputError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
    if record_dt is not None and not (record_dt >= dt):
        raise DownholeInputError(f"record_dt must be >= dt ({dt}), got {record_dt!r}")


def simulate(model: ChainModel, inputs: SurfaceInputs | None = None, *, duration: float = 20.0,
             dt: float = 5e-4, depth_of_cut: str = "delayed", integrator: str = "euler",
             record_dt: float | None = None, rock_points_per_pitch: int = 512,
             rock_memory: bool = True, attrs: dict | None = None, start: str = "rest",
             clearance: float = 0.05) -> Result:
    """Simulate a lumped drill-string model with fixed steps.

    Parameters
    ----------
    model : ChainModel
        From :func:`downhole.sim.lumped_model.lumped_model`.
    inputs : SurfaceInputs, optional
        Top-drive inputs; default ``SurfaceInputs.velocity(0.01, 10.0)`` (10 mm/s, 10 rad/s).
    duration : float
        Simulated time, s. This and ``dt``, ``record_dt`` and ``clearance`` also accept a
        quantity string (``"20 s"``, ``"0.5 ms"``) or a pint Quantity.
    dt : float
        Time step, s (the seed uses 5e-4 s with explicit Euler).
    depth_of_cut : {"delayed", "approximate"}
        ``delayed``: state-dependent delay from the bit history with rock-surface memory (Eqs.
        2.9-2.10 corrected). ``approximate``: d = 2 pi v / max(omega, omega*) (Eqs. 2.11, 4.16).
    integrator : {"euler", "newmark"}
        Explicit Euler (seed) or trapezoidal/Newmark average acceleration with the stiff bit
        friction applied implicitly (2nd order, stable for stiff strings).
    record_dt : float, optional
        Output sample interval, s (rounded to a multiple of dt); default every step up to
        20 000 samples, then thinned.
    rock_points_per_pitch : int
        Resolution of the rock-surface memory (grid points per blade pitch 2 pi/n).
    rock_memory : bool
        True: depth of cut against the hole bottom (docs/seed-errata.md). False: printed Eq. 2.9.
    attrs : dict, optional
        Extra metadata stored in the Result (e.g. the scenario TOML text).
    start : {"rest", "off_bottom", "steady"}
        Initial state (:data:`downhole.sim.plant.START_MODES`): at rest; moving steadily at the
        inputs' values at t = 0 with the bit ``clearance`` m off bottom; or the steady drilling
        state at those values. The last two need velocity inputs.
    clearance : float
        Bit height above the hole bottom for ``start="off_bottom"``, m.

    Returns
    -------
    Result
        Standard channels (see :data:`downhole.sim.result.CHANNEL_UNITS`).

    Raises
    ------
    DownholeInputError
        Invalid arguments.
    SimulationDiverged
        A channel became non-finite; the message names the time and channel.

    Examples
    --------
    >>> from downhole.sim.lumped_model import lumped_model
    >>> res = simulate(lumped_model("table_2_1"), SurfaceInputs.velocity(0.01, 10.0),
    ...                duration=2.0, dt=5e-4)
    >>> res.time[-1]
    2.0
    """
    if not isinstance(model, ChainModel):
        raise DownholeInputError(f"simulate() takes a lumped ChainModel, got {type(model).__name__}")
    inputs = inputs or SurfaceInputs.velocity()
    duration = si_or_number(duration, "time", "duration")
    dt = si_or_number(dt, "time", "dt")
    record_dt = si_or_number(record_dt, "time", "record_dt")
    clearance = si_or_number(clearance, "length", "clearance")
    _check(duration, dt, depth_of_cut, integrator, record_dt)
    nsteps = int(round(duration / dt))
    if abs(nsteps * dt - duration) > 1e-9 * max(1.0, duration):
        raise DownholeInputError(f"dt = {dt} does not divide duration = {duration}")
    if record_dt is None:
        every = max(1, int(math.ceil((nsteps + 1) / 20000)))
    else:
        every = max(1, int(round(record_dt / dt)))
    t = np.arange(nsteps + 1) * dt
    pos, vel = inputs.sample(t)
    if inputs.mode == "force":
        pos[0] = model.weight - pos[0]  # net axial force on the top DOF (weight pre-balanced)
    spec = RockSurfaceSpec(model.bit.n_blades, rock_points_per_pitch, rock_memory)
    check_start(start)
    q0, v0, surf, istate, rp = _start_state(model, start, inputs.mode, float(vel[0, 0]),
                                            float(vel[1, 0]), spec, clearance)
    state = (q0, v0)
    nrec = nsteps // every + 1 + (1 if nsteps % every else 0)
    out = np.empty((nrec, len(CHANNELS)))
    arrays = model.packed()
    status, kfail, cfail = run_chain(
        *arrays, model.bit.kernel_params(), state[0], state[1], inputs.mode == "force", pos, vel,
        model.weight, 0, nsteps, float(dt), 0 if integrator == "euler" else 1,
        depth_of_cut == "approximate", surf, istate, rp, every, out, 0)
    if status != 0:
        raise SimulationDiverged(kfail * dt, CHANNELS[cfail])
    channels = {name: out[:, i] for i, name in enumerate(CHANNELS) if name != "time"}
    meta = {"model": model.name, "dt": dt, "depth_of_cut": depth_of_cut,
            "integrator": integrator, "input_mode": inputs.mode,
            "bit_radius": model.bit.radius, "n_blades": model.bit.n_blades, "start": start}
    meta.update(attrs or {})
    return Result(out[:, 0], channels, attrs=meta)


def _initial_state(model: ChainModel):
    n = model.n
    q = np.zeros((2, n))
    v = np.zeros((2, n))
    return q, v


def _start_state(model: ChainModel, start: str, mode: str, v0: float, w0: float,
                 spec: RockSurfaceSpec, clearance: float = 0.05):
    """Chain state and rock surface for ``start`` at top velocities (v0, w0).

    ``rest``: zeros, bit on a flat bottom. ``off_bottom``: every DOF moving at (v0, w0), the
    chain deflected by its absolute damping only, the bit ``clearance`` m above a flat bottom.
    ``steady``: the same plus the steady bit forces at depth of cut d = 2 pi v0 / w0 (string
    compressed and wound up), on a helical bottom. Positions are deviations from the hanging
    equilibrium with the top drive at 0 (as for ``rest``). Returns ``(q, v, surf, istate, rp)``.
    """
    check_start(start)
    q, v = _initial_state(model)
    if start == "rest":
        return (q, v) + rock_init(spec, 0.0, 0.0)
    if mode != "velocity":
        raise DownholeInputError(f"start={start!r} needs a velocity-driven top (the set-point "
                                 "is a velocity); a force-driven lumped plant starts from 'rest'")
    if not (isinstance(clearance, (int, float)) and math.isfinite(clearance) and clearance > 0):
        raise DownholeInputError(f"clearance must be a positive distance in m, got {clearance!r}")
    wob = tob = 0.0
    d0 = steady_depth_of_cut(v0, w0) if start == "steady" else 0.0
    if start == "steady":
        wob, tob = bit_forces(d0, v0, w0, model.bit.kernel_params())
    for f, (field, vel, load) in enumerate(((model.axial, v0, wob), (model.torsional, w0, tob))):
        rhs = np.asarray(field.gravity, float) - np.asarray(field.c_abs, float) * vel
        rhs[-1] -= load
        q[f] = np.linalg.solve(field.stiffness_matrix(), rhs)
        v[f] = vel
    x_bit = q[0, -1]
    if start == "steady":
        return (q, v) + rock_init_helix(spec, x_bit, q[1, -1], d0)
    return (q, v) + rock_init(spec, x_bit + clearance, q[1, -1])


class LumpedPlant(Plant):
    """Step-by-step plant over a lumped model (the :class:`~downhole.sim.plant.Plant` contract).

    Commands (named): ``top_drive_axial_velocity`` (m/s) and ``top_drive_angular_velocity``
    (rad/s) for a velocity-driven top, or ``hook_load`` (N) and ``surface_torque`` (N m) when
    ``mode="force"``. Observations: the standard Result channel names.

    Parameters
    ----------
    model : ChainModel
    dt : float
        Step, s.
    mode : {"velocity", "force"}
    depth_of_cut, integrator : str
        As in :func:`simulate`.

    Examples
    --------
    >>> from downhole.sim.lumped_model import lumped_model
    >>> plant = LumpedPlant(lumped_model("table_2_1"), dt=5e-4)
    >>> obs = plant.reset(start="steady", set_point={"top_drive_axial_velocity": 0.01,
    ...                                              "top_drive_angular_velocity": 20.0})
    >>> round(obs["bit_angular_velocity"], 6)
    20.0
    """

    observation_names = tuple(c for c in CHANNELS)

    def __init__(self, model: ChainModel, dt: float = 5e-4, mode: str = "velocity",
                 depth_of_cut: str = "delayed", integrator: str = "euler"):
        dt = si_or_number(dt, "time", "dt")  # "0.5 ms" or a pint quantity
        _check(1.0, min(dt, 1.0), depth_of_cut, integrator, None)
        if mode not in ("velocity", "force"):
            raise DownholeInputError(f"mode must be 'velocity' or 'force', got {mode!r}")
        self.model, self.dt, self.mode = model, float(dt), mode
        self.depth_of_cut, self.integrator = depth_of_cut, integrator
        self._arrays = model.packed()
        self._bitp = model.bit.kernel_params()
        self._out = np.empty((2, len(CHANNELS)))
        self.reset()

    @property
    def command_names(self) -> tuple[str, str]:
        return (("top_drive_axial_velocity", "top_drive_angular_velocity") if self.mode == "velocity"
                else ("hook_load", "surface_torque"))

    def default_command(self) -> dict:
        """Velocity mode: at rest; force mode: the hook carries the whole string, no torque."""
        if self.mode == "force":
            return {"hook_load": self.model.weight, "surface_torque": 0.0}
        return {n: 0.0 for n in self.command_names}

    def _reset(self, start: str, set_point: dict, clearance: float = 0.05) -> dict:
        spec = RockSurfaceSpec(self.model.bit.n_blades)
        cmd = np.array([set_point[n] for n in self.command_names])
        self._q, self._v, self._surf, self._istate, self._rp = _start_state(
            self.model, start, self.mode, float(cmd[0]), float(cmd[1]), spec, clearance)
        self._k = 0
        self._top = np.zeros(2)  # top-drive displacement
        self._cmd = cmd
        return self._observe()

    def _inputs(self, cmd_now, cmd_next):
        pos = np.empty((2, 2))
        vel = np.zeros((2, 2))
        if self.mode == "force":
            pos[0] = self.model.weight - np.array([cmd_now[0], cmd_next[0]])
            pos[1] = [cmd_now[1], cmd_next[1]]
        else:
            vel[:, 0] = cmd_now
            vel[:, 1] = cmd_next
            pos[:, 0] = self._top
            pos[:, 1] = self._top + self.dt * cmd_next
        return pos, vel

    def _observe(self) -> dict:
        pos, vel = self._inputs(self._cmd, self._cmd)
        q, v = self._q.copy(), self._v.copy()
        surf, ist = self._surf.copy(), self._istate.copy()
        run_chain(*self._arrays, self._bitp, q, v, self.mode == "force", pos, vel,
                  self.model.weight, self._k, 0, self.dt, 0, self.depth_of_cut == "approximate",
                  surf, ist, self._rp, 1, self._out, 0)
        return {name: float(self._out[0, i]) for i, name in enumerate(CHANNELS)}

    def _step(self, new: np.ndarray) -> dict:
        """Apply ``new`` (held over the step) and advance one ``dt``; returns observations."""
        pos, vel = self._inputs(new, new)
        status, _, c = run_chain(*self._arrays, self._bitp, self._q, self._v, self.mode == "force",
                                 pos, vel, self.model.weight, self._k, 1, self.dt,
                                 0 if self.integrator == "euler" else 1,
                                 self.depth_of_cut == "approximate", self._surf, self._istate,
                                 self._rp, 1, self._out, 0)
        if status != 0:
            raise SimulationDiverged(self._k * self.dt, CHANNELS[c])
        self._k += 1
        self._top = pos[:, 1]
        self._cmd = new
        return {name: float(self._out[1, i]) for i, name in enumerate(CHANNELS)}
