"""``simulate()``: the one entry point that runs a lumped drill-string model open loop and returns
a Result, through the one mechanics kernel (:func:`downhole.sim.kernel.run_kernel`).

The step-by-step form of the same runs is :class:`downhole.string.fem.DirectionalPlant`, which
takes a lumped :class:`~downhole.sim.lumped_model.ChainModel` as well.
"""

from __future__ import annotations

import math

import numpy as np

from downhole.bit.rock_surface import RockSurfaceSpec
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.sim.inputs import SurfaceInputs
from downhole.sim.kernel import CHANNELS
from downhole.sim.lumped_model import (
    CHAIN_CHANNELS,
    DEPTH_OF_CUT_MODES,
    INTEGRATORS,
    ChainModel,
)
from downhole.sim.plant import check_start
from downhole.sim.result import Result
from downhole.units import si_or_number

__all__ = ["DEPTH_OF_CUT_MODES", "INTEGRATORS", "simulate"]


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
    top_ref = np.empty((nsteps + 1, 4))
    top_ref[:, 0], top_ref[:, 1], top_ref[:, 2], top_ref[:, 3] = pos[0], pos[1], vel[0], vel[1]
    spec = RockSurfaceSpec(model.bit.n_blades, rock_points_per_pitch, rock_memory)
    check_start(start)
    pk = model.kernel_pack(float(dt), "force" if inputs.mode == "force" else "velocity",
                           depth_of_cut, integrator)
    st, rec0 = pk.start(start, top_ref[0], spec, clearance, input_mode=inputs.mode)
    nrec = nsteps // every + 1 + (1 if nsteps % every else 0)
    rec = np.empty((nrec, len(CHANNELS)))
    rec[0] = rec0
    n_main = (nsteps // every) * every
    status, rows = pk.run(st, top_ref[:n_main + 1], rec, every, 1)
    if status == 0 and n_main < nsteps:
        status, r2 = pk.run(st, top_ref[n_main:], rec, nsteps - n_main, 1 + rows)
        rows += r2
    if status != 0:
        raise SimulationDiverged(float(st["run"]["time"][0]), _diverged_channel(st["state"]))
    time = np.arange(nrec) * every * dt
    time[-1] = nsteps * dt
    channels = {name: rec[:, i] for i, name in enumerate(CHAIN_CHANNELS[1:])}
    meta = {"model": model.name, "dt": dt, "depth_of_cut": depth_of_cut,
            "integrator": integrator, "input_mode": inputs.mode,
            "bit_radius": model.bit.radius, "n_blades": model.bit.n_blades, "start": start}
    meta.update(attrs or {})
    return Result(time, channels, attrs=meta)


def _diverged_channel(state) -> str:
    """The bit channel that ran away (the first of position, velocity, angle, angular
    velocity that is non-finite or beyond the kernel's guard)."""
    for name, row, lim in (("bit_axial_position", 0, 1e9), ("bit_axial_velocity", 1, 1e9),
                           ("bit_angle", 3, 1e12), ("bit_angular_velocity", 4, 1e12)):
        x = state[row, -1]
        if not (abs(x) < lim):
            return name
    return "bit_angular_velocity"
