"""Lumped drill strings as chains: the 4th-order (Eq. 2.1) and 12th-order (Eqs. 2.26-2.31) models.

A :class:`ChainModel` is a configuration of the one mechanics kernel
(:func:`downhole.sim.kernel.run_kernel`): per field (axial, torsional) a chain of DOFs with
diagonal mass, springs and dampers between neighbours (tridiagonal K and C), absolute dampers to
ground, and a coupling of DOF 0 to the top drive (a spring/damper to the commanded displacement,
which is the kernel's hook servo and top-drive PI towards a given reference, or an applied hook
load/torque). The bit acts on the last DOF. Positions are deviations from the static hanging
equilibrium (gravity pre-balanced), unless the parameters ask for the printed, unbalanced form.
:meth:`ChainModel.kernel_pack` builds the kernel's arrays; :func:`downhole.sim.simulate` and
:class:`downhole.string.fem.DirectionalPlant` run them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from downhole.bit.law import bit_forces
from downhole.bit.rock_surface import RockSurfaceSpec, rock_depth, rock_init, rock_init_helix
from downhole.errors import DownholeInputError
from downhole.params import BitParams, LumpedParams, get_preset
from downhole.sim.kernel import CHANNELS as KERNEL_CHANNELS
from downhole.sim.kernel import (
    KernelModel,
    KernelParams,
    kernel_state,
    new_kernel_work,
    new_run_state,
    run_kernel,
)
from downhole.sim.plant import check_start, steady_depth_of_cut, under_rig
from downhole.sim.wave import WaveParams

__all__ = ["CHAIN_CHANNELS", "ChainField", "ChainModel", "ChainPack", "lumped_model"]

#: The channels a lumped run records (the first eleven kernel channels, after the time).
CHAIN_CHANNELS = ("time", *KERNEL_CHANNELS[:11])
DEPTH_OF_CUT_MODES = ("delayed", "approximate")
INTEGRATORS = ("euler", "newmark")


@dataclass(frozen=True)
class ChainField:
    """One field (axial or torsional) of a chain of ``n`` DOFs, SI units.

    Attributes
    ----------
    mass : ndarray (n,)
        Masses (kg) or inertias (kg m^2).
    k_link, c_link : ndarray (n-1,)
        Spring and damper between DOF i and i+1.
    c_abs : ndarray (n,)
        Dampers from each DOF to ground (absolute velocity).
    k_top, c_top : float
        Spring and damper from DOF 0 to the top-drive displacement (displacement-driven top).
    gravity : ndarray (n,)
        Constant loads (only non-zero for the printed, unbalanced model), N or N m.
    """

    mass: np.ndarray
    k_link: np.ndarray
    c_link: np.ndarray
    c_abs: np.ndarray
    k_top: float
    c_top: float
    gravity: np.ndarray

    def __post_init__(self):
        n = len(self.mass)
        if n < 1:
            raise DownholeInputError("a chain field needs at least one DOF")
        if np.any(np.asarray(self.mass) <= 0):
            raise DownholeInputError(f"chain masses must be positive, got {self.mass}")
        for name, size in (("k_link", n - 1), ("c_link", n - 1), ("c_abs", n), ("gravity", n)):
            if len(getattr(self, name)) != size:
                raise DownholeInputError(f"{name} must have {size} entries, got {len(getattr(self, name))}")

    @property
    def n(self) -> int:
        return len(self.mass)

    def stiffness_matrix(self) -> np.ndarray:
        """Dense K including the top spring (for analysis and tests)."""
        n = self.n
        k = np.zeros((n, n))
        k[0, 0] += self.k_top
        for i, kl in enumerate(self.k_link):
            k[i, i] += kl
            k[i + 1, i + 1] += kl
            k[i, i + 1] -= kl
            k[i + 1, i] -= kl
        return k


@dataclass(frozen=True)
class ChainModel:
    """An immutable lumped drill-string description (axial and torsional chains + bit).

    Attributes
    ----------
    name : str
        ``"lumped4"`` or ``"lumped12"``.
    axial, torsional : ChainField
        The two fields; they couple only through the bit law at the last DOF.
    bit : BitParams
        Bit/rock parameters.
    weight : float
        Weight carried by the hook when the string hangs (N); 0 for the printed unbalanced form.
    params : LumpedParams
        The parameters it was built from.
    with_rig : callable or None
        For a chain derived from a described system (:class:`downhole.system.DrillingSystem`):
        ``with_rig()`` returns the chain with the rig's node on top (a
        :class:`~downhole.string.fem.DirectionalModel` of kind ``"lumped"``), which a run with a
        ``top_drive`` / ``hook`` steps. None: a preset's chain, whose top is the ideal velocity
        drive of the seed's Chapter 2.
    """

    name: str
    axial: ChainField
    torsional: ChainField
    bit: BitParams
    weight: float
    params: LumpedParams = field(repr=False)
    with_rig: object = field(default=None, repr=False, compare=False)

    #: What a preset chain's top is (the refusal of a rig names it).
    rigless_top = "this lumped chain is a preset's (Table 2.1): its top is the seed's ideal " \
                  "velocity drive"

    @property
    def n(self) -> int:
        return self.axial.n

    def natural_frequencies(self) -> dict:
        """Undamped natural frequencies (rad/s) of each field with the top clamped."""
        out = {}
        for name, f in (("axial", self.axial), ("torsional", self.torsional)):
            k = f.stiffness_matrix()
            m = np.diag(1.0 / np.sqrt(f.mass))
            out[name] = np.sqrt(np.sort(np.linalg.eigvalsh(m @ k @ m)))
        return out

    #: Default step of :func:`downhole.sim.simulate`, s (the seed's).
    default_dt = 5e-4

    def kernel_pack(self, dt: float, mode: str = "velocity", depth_of_cut: str = "delayed",
                    integrator: str = "euler") -> ChainPack:
        """The kernel arrays of this chain for one step ``dt`` (s), top ``mode`` (``velocity``:
        driven towards a given top position and velocity; ``force``: hook load and surface
        torque applied), depth of cut and integrator (``euler`` or ``newmark``)."""
        return ChainPack(self, dt, mode, depth_of_cut, integrator)

    def run_pack(self, dt: float, depth_of_cut: str, inputs, bit_noise: bool,
                 options: dict) -> ChainPack:
        """The pack :func:`downhole.sim.simulate` runs (see its module docstring): the top
        mode from ``inputs`` (a :class:`~downhole.sim.inputs.SurfaceInputs`); ``options``
        ``integrator``, ``rock_points_per_pitch``, ``rock_memory``; ``top_drive`` and ``hook``
        (:class:`~downhole.params.rig.TopDrive`, :class:`~downhole.params.rig.Hook`) run the
        chain under the rig, as the FEM runs (see :attr:`with_rig`)."""
        opts = dict(options)
        if "top_drive" in opts or "hook" in opts:
            model = under_rig(self, opts.pop("integrator", None))
            rig = {k: opts.pop(k) for k in ("top_drive", "hook") if k in opts}
            opts.pop("rock_points_per_pitch", None)
            if opts.pop("rock_memory", True) is not True or opts:
                raise DownholeInputError(f"a lumped chain under a rig takes the options "
                                         f"top_drive, hook, integrator; got {sorted(opts)}")
            return model.run_pack(dt, depth_of_cut, inputs, bit_noise, rig)
        integrator = opts.pop("integrator", "euler")
        spec = RockSurfaceSpec(self.bit.n_blades, int(opts.pop("rock_points_per_pitch", 512)),
                               bool(opts.pop("rock_memory", True)))
        if opts:
            raise DownholeInputError(f"a lumped model takes the options integrator, "
                                     f"rock_points_per_pitch, rock_memory; got {sorted(opts)}")
        if bit_noise:
            raise DownholeInputError("noise.wob / noise.tob (bit-force noise) is a neutral-model "
                                     "input; the lumped top is a given reference")
        mode = getattr(inputs, "mode", "velocity")
        if inputs is not None and not hasattr(inputs, "sample"):
            raise DownholeInputError(f"a lumped model's inputs are SurfaceInputs.velocity(...) "
                                     f"or SurfaceInputs.force(...), got {inputs!r}")
        pk = ChainPack(self, dt, "force" if mode == "force" else "velocity", depth_of_cut,
                       integrator)
        pk.spec = spec
        return pk


def lumped_model(string: str | LumpedParams = "table_2_1", bit: BitParams | None = None,
                 order: int = 4) -> ChainModel:
    """Build the 4th- or 12th-order lumped model.

    Parameters
    ----------
    string : str or LumpedParams
        A preset name of kind ``lumped`` (``"table_2_1"``, ``"plausible_lumped"``) or parameters.
    bit : BitParams, optional
        Bit parameters; default: the preset's (or Table 2.1's when parameters are given).
    order : {4, 12}
        4: one mass/inertia on a spring and absolute damper to the top drive (Eq. 2.1).
        12: three masses/inertias in series driven through a stiff top servo, with the mass and
        compliance split of :class:`~downhole.params.TwelfthOrderSplit` and absolute dampers
        C_a, C_t shared by mass (correction of Eqs. 2.26-2.31, docs/seed-errata.md: the printed
        equations take forces as inputs and have no ground damping, so they drift).

    Returns
    -------
    ChainModel

    Examples
    --------
    >>> m = lumped_model("table_2_1", order=4)
    >>> round(m.natural_frequencies()["axial"][0], 3)
    0.67
    """
    if isinstance(string, str):
        preset = get_preset(string)
        if preset.kind != "lumped":
            raise DownholeInputError(f"preset {string!r} is of kind {preset.kind!r}, not 'lumped'")
        params: LumpedParams = preset.string
        bit = bit or preset.bit
    elif isinstance(string, LumpedParams):
        params = string
        bit = bit or get_preset("table_2_1").bit
    else:
        raise DownholeInputError(f"string must be a preset name or LumpedParams, got {type(string).__name__}")
    if order not in (4, 12):
        raise DownholeInputError(f"order must be 4 or 12, got {order!r}")
    g = params.g
    weight = params.mass * g if params.gravity_prebalance else 0.0
    unbal = 0.0 if params.gravity_prebalance else 1.0
    if order == 4:
        ax = ChainField(np.array([params.mass]), np.zeros(0), np.zeros(0),
                        np.array([params.axial_damping]), params.axial_stiffness, 0.0,
                        np.array([unbal * params.mass * g]))
        to = ChainField(np.array([params.inertia]), np.zeros(0), np.zeros(0),
                        np.array([params.torsional_damping]), params.torsional_stiffness, 0.0,
                        np.zeros(1))
        return ChainModel("lumped4", ax, to, bit, weight, params)
    split = params.twelfth_order
    ms = np.array(split.mass_shares)
    cs = np.array(split.compliance_shares)

    def field_of(total_m, k, c, grav):
        masses = total_m * ms
        k_top = k / cs[0]
        k_link = k / cs[1:]
        c_top = 2.0 * split.servo_damping_ratio * math.sqrt(k_top * masses[0])
        return ChainField(masses, k_link, np.zeros(2), c * ms, k_top, c_top, grav * masses)

    ax = field_of(params.mass, params.axial_stiffness, params.axial_damping, unbal * g)
    to = field_of(params.inertia, params.torsional_stiffness, params.torsional_damping, 0.0)
    return ChainModel("lumped12", ax, to, bit, weight, params)


def _tridiagonal(diag_extra, links, n):
    """(2, n) tridiagonal rows (diagonal, off-diagonal) of a chain of ``links`` plus
    ``diag_extra`` on the diagonal (the last off-diagonal entry unused)."""
    t = np.zeros((2, n))
    t[0] = np.asarray(diag_extra, float)
    for i, kl in enumerate(np.asarray(links, float)):
        t[0, i] += kl
        t[0, i + 1] += kl
        t[1, i] = -kl
    return t


class ChainPack:
    """Kernel arrays and start states of a :class:`ChainModel` for one (dt, top mode, depth of
    cut, integrator): the chain as a configuration of :func:`~downhole.sim.kernel.run_kernel`.

    The top is a given, massless reference (``KernelParams.given_reference``): in velocity mode
    the axial field's top spring and damper are the kernel's hook servo (``hook_k``,
    ``hook_c``) and the torsional ones its top-drive PI (``ki``, ``kp``), both towards the
    reference position and velocity; in force mode the hook load (less the pre-balanced
    weight) and the surface torque act on DOF 0.
    """

    observation_names = CHAIN_CHANNELS
    kind = "lumped"
    n_cmd = 2
    spec: RockSurfaceSpec | None = None

    def __init__(self, model: ChainModel, dt: float, mode: str, depth_of_cut: str,
                 integrator: str):
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise DownholeInputError(f"dt must be a positive number of seconds, got {dt!r}")
        if mode not in ("velocity", "force"):
            raise DownholeInputError(f"mode must be 'velocity' or 'force', got {mode!r}")
        if depth_of_cut not in DEPTH_OF_CUT_MODES:
            raise DownholeInputError(f"depth_of_cut must be one of {DEPTH_OF_CUT_MODES}, got "
                                     f"{depth_of_cut!r}")
        if integrator not in INTEGRATORS:
            raise DownholeInputError(f"integrator must be one of {INTEGRATORS}, got "
                                     f"{integrator!r}")
        self.model, self.dt, self.mode = model, float(dt), mode
        self.depth_of_cut, self.integrator = depth_of_cut, integrator
        self.approx = depth_of_cut == "approximate"
        n = model.n
        h = 0.5 * self.dt
        rows = []
        for f in (model.axial, model.torsional):
            m = np.zeros((2, n))
            m[0] = f.mass
            k = _tridiagonal(np.zeros(n), f.k_link, n)
            c = _tridiagonal(f.c_abs, f.c_link, n)
            rows.append((m, k, m + h * c + h * h * k, c))
        (ma, ka, la, ca), (mt, kt, lt, ct) = rows
        self.mats = np.vstack([ma, ka, la, mt, kt, lt, ca, ct, np.zeros((2, n))])
        self.Ldense = np.zeros((2, 1, 1))
        self.elem = np.zeros((n, 8))
        self.node = np.column_stack([np.asarray(model.axial.gravity, float), np.zeros(n)])
        self.bitp = model.bit.kernel_params()
        ax, to = model.axial, model.torsional
        self.top = KernelParams(
            velocity_hook=mode == "velocity", hook_k=float(ax.k_top), hook_c=float(ax.c_top),
            hook_load0=0.0, torque_mode=mode == "force", kp=float(to.c_top),
            ki=float(to.k_top), soft_gain=0.0, soft_tau=0.0, mu=0.0, v_eps=1e-3,
            approx_doc=self.approx, node_b=0, node_c=n - 1, hybrid=False, dense=False,
            n_lags_a=0, lag_tau_a=0.0, n_lags_t=0, lag_tau_t=0.0, fb0=0.0, fc0=0.0,
            prebalanced_weight=float(model.weight), explicit_euler=integrator == "euler",
            given_reference=True, rig_node=0, bit_node=n - 1)
        self._wave = (np.zeros((2, 4)), np.zeros(1, np.int64),
                      WaveParams(impedance=0.0, delay_steps=1.0, cap=4, a_init=0.0,
                                 b_init=0.0))
        self._cmd = np.zeros((0, 2))

    @property
    def command_names(self) -> tuple[str, str]:
        return (("top_drive_axial_velocity", "top_drive_angular_velocity")
                if self.mode == "velocity" else ("hook_load", "surface_torque"))

    def default_command(self) -> dict:
        """Velocity mode: at rest; force mode: the hook carries the whole string, no torque."""
        if self.mode == "force":
            return {"hook_load": float(self.model.weight), "surface_torque": 0.0}
        return {name: 0.0 for name in self.command_names}

    def start(self, start: str, top_row: np.ndarray, spec: RockSurfaceSpec | None = None,
              clearance: float = 0.05, input_mode: str | None = None):
        """Kernel state for ``start`` with the top at ``top_row`` (the ``top_ref`` row of
        t = 0: position, angle, velocity, angular velocity; force mode: hook load, torque).
        Returns ``(state dict, record row of t = 0)``."""
        spec = spec or RockSurfaceSpec(self.model.bit.n_blades)
        top_row = np.asarray(top_row, float)
        q, v, surf, istate, rp = _start_state(self.model, start, input_mode or self.mode,
                                              float(top_row[2]), float(top_row[3]), spec,
                                              clearance)
        n = self.model.n
        state = np.zeros((6, n))
        state[0], state[1], state[3], state[4] = q[0], v[0], q[1], v[1]
        run = new_run_state(x_ref=float(top_row[0]), theta_ref=float(top_row[1]))
        st = dict(state=state, run=run, surf=surf, istate=istate, rp=rp,
                  lag=np.zeros((4, 1)))
        rec0 = self._record_and_acceleration(st, top_row)
        return st, rec0

    def _record_and_acceleration(self, st, top_row) -> np.ndarray:
        """The channels of the state ``st`` with the top at ``top_row``; also sets the
        accelerations the Newmark steps start from (the forces of that state over the mass)."""
        s = st["state"]
        n = self.model.n
        ib = n - 1
        xb, vb, thb, wb = s[0, ib], s[1, ib], s[3, ib], s[4, ib]
        if self.approx:
            from downhole.bit.law import approx_depth_of_cut

            d = approx_depth_of_cut(vb, wb, self.bitp)
        else:
            d = rock_depth(st["surf"], st["istate"], st["rp"], xb, thb)
        wob, tob = bit_forces(d, vb, wb, self.bitp)
        top = self.top
        rec = np.zeros(len(KERNEL_CHANNELS))
        rec[0:7] = xb, vb, thb, wb, d, wob, tob
        if self.mode == "velocity":
            fa = top.hook_k * (top_row[0] - s[0, 0]) + top.hook_c * (top_row[2] - s[1, 0])
            ft = top.ki * (top_row[1] - s[3, 0]) + top.kp * (top_row[3] - s[4, 0])
            rec[7:11] = self.model.weight - fa, ft, top_row[2], top_row[3]
            fa_top = fa
        else:
            ft = top_row[1]
            rec[7:11] = top_row[0], ft, s[1, 0], s[4, 0]
            fa_top = self.model.weight - top_row[0]
        for f, (fld, ftop, fbit) in enumerate(((self.model.axial, fa_top, wob),
                                                (self.model.torsional, ft, tob))):
            u, vel = s[3 * f], s[3 * f + 1]
            force = np.asarray(fld.gravity, float) - np.asarray(fld.c_abs, float) * vel
            dq = np.diff(u)
            fl = np.asarray(fld.k_link, float) * dq + np.asarray(fld.c_link, float) * np.diff(vel)
            force[:-1] += fl
            force[1:] -= fl
            force[0] += ftop
            force[ib] -= fbit
            s[3 * f + 2] = force / np.asarray(fld.mass, float)
        return rec

    def record(self, st, top_row) -> np.ndarray:
        """The channels of the state ``st`` (a copy is used) with the top at ``top_row``."""
        tmp = dict(st, state=st["state"].copy())
        return self._record_and_acceleration(tmp, top_row)

    def step_reference(self, st, command, out: np.ndarray | None = None) -> np.ndarray:
        """The ``top_ref`` rows of one step holding ``command`` (velocities: the top moves on
        from the run state's reference position; forces: held), into ``out`` if given."""
        ref = np.zeros((2, 4)) if out is None else out
        c0, c1 = float(command[0]), float(command[1])
        if self.mode == "force":
            ref[0, 0] = ref[1, 0] = c0
            ref[0, 1] = ref[1, 1] = c1
            return ref
        rs = st["run"][0]
        x0, th0 = rs["x_ref"], rs["theta_ref"]
        ref[0, 0], ref[0, 1], ref[0, 2], ref[0, 3] = x0, th0, c0, c1
        ref[1, 0], ref[1, 1], ref[1, 2], ref[1, 3] = x0 + self.dt * c0, th0 + self.dt * c1, c0, c1
        return ref

    def step(self, st, command, rec):
        """One step holding ``command`` (the plant's); ``(status, rows)``."""
        ref = st.get("step_ref")
        if ref is None:
            ref = st["step_ref"] = np.zeros((2, 4))
        return self.run(st, self.step_reference(st, command, ref), rec, 1, 0)

    # ---- the run protocol of downhole.sim.simulate
    def rows(self, inputs, t) -> np.ndarray:
        """The top reference at the step boundaries ``t``: position, angle, velocity, angular
        velocity (force mode: hook load, surface torque in columns 0 and 1)."""
        from downhole.sim.inputs import SurfaceInputs

        inputs = inputs if inputs is not None else SurfaceInputs.velocity()
        pos, vel = inputs.sample(t)
        out = np.empty((len(t), 4))
        out[:, 0], out[:, 1], out[:, 2], out[:, 3] = pos[0], pos[1], vel[0], vel[1]
        return out

    def begin(self, start: str, rows, clearance: float):
        """Kernel state and the record of t = 0 (see :meth:`start`)."""
        return self.start(start, rows[0], self.spec, clearance, input_mode=self.mode)

    def still_rows(self, t) -> np.ndarray:
        """Rows holding :meth:`default_command` (a closed loop's start)."""
        out = np.zeros((len(t), 4))
        c = self.default_command()
        names = self.command_names
        cols = (0, 1) if self.mode == "force" else (2, 3)
        out[:, cols[0]], out[:, cols[1]] = c[names[0]], c[names[1]]
        return out

    def first_command(self, rows) -> np.ndarray:
        """The command held before a controller's first output."""
        return np.array(rows[0, 0:2] if self.mode == "force" else rows[0, 2:4], float)

    def command(self, out, held, who: str) -> None:
        """A controller's output into ``held`` (by :attr:`command_names`)."""
        _named_command(self.command_names, out, held, who)

    def command_channels(self, hist) -> dict:
        """Closed-loop channels of the held commands (none: the record has the top's)."""
        return {}

    def channels(self, rec, rows, idx):
        """The Result's channels, units and attributes."""
        ch = {name: rec[:, i] for i, name in enumerate(CHAIN_CHANNELS[1:])}
        return ch, {}, {"integrator": self.integrator, "input_mode": self.mode}

    def run(self, st, top_ref, rec, rec_every, rec_start=0):
        """Advance ``len(top_ref) - 1`` steps from ``st`` (updated in place); ``(status,
        rows written)``."""
        if st.get("work") is None:
            st["work"] = new_kernel_work(self.model.n)
        ks = kernel_state(dict(st, wa=self._wave, wt=self._wave))
        return run_kernel(KernelModel(self.mats, self.Ldense, self.elem, self.node, self.top,
                                      self.bitp), ks, self._cmd, top_ref,
                          top_ref.shape[0] - 1, self.dt, rec, rec_every, rec_start)


def _named_command(names, out, held, who: str) -> None:
    """Write the commands ``names`` found in the controller output ``out`` into ``held``."""
    if not isinstance(out, dict):
        raise DownholeInputError(f"{who}.command must return a dict of {names}, got {out!r}")
    hit = False
    for i, name in enumerate(names):
        if name in out:
            held[i] = float(out[name])
            hit = True
    if not hit and out:
        raise DownholeInputError(f"{who}.command returned {sorted(out)}; this plant takes "
                                 f"{names}")


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
    n = model.n
    q = np.zeros((2, n))
    v = np.zeros((2, n))
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
    for f, (fld, vel, load) in enumerate(((model.axial, v0, wob), (model.torsional, w0, tob))):
        rhs = np.asarray(fld.gravity, float) - np.asarray(fld.c_abs, float) * vel
        rhs[-1] -= load
        q[f] = np.linalg.solve(fld.stiffness_matrix(), rhs)
        v[f] = vel
    x_bit = q[0, -1]
    if start == "steady":
        return (q, v) + rock_init_helix(spec, x_bit, q[1, -1], d0)
    return (q, v) + rock_init(spec, x_bit + clearance, q[1, -1])
