"""The neutral-type distributed drill string of seed Ch. 3 as a configuration of the mechanics core:
one wave segment (surface to bit) per field, the bit mass and inertia at the bottom, and a damper
(alpha_A, alpha_T) to the commanded velocity at the massless top (seed Eqs. 3.1-3.6).

Eliminating the waves gives the neutral delay-differential equations of Eq. 3.9 with the delays
tau = L sqrt(rho/E), L sqrt(rho/G) (Eq. 3.10 prints them inverted); :meth:`NeutralModel.ndde`
returns its matrices (Eq. 3.13) for control design. The wave form runs on the one mechanics
kernel (:func:`downhole.sim.kernel.run_kernel`) as a two-node configuration (:class:`NeutralPack`:
the massless top node with its dampers to the commands, the wave joint, the bit node);
:func:`downhole.sim.simulate` runs it open loop, or closed loop through a controller's compiled
runner (which steps the same kernel) or any controller in a Python loop, and returns a Result;
:class:`downhole.string.fem.DirectionalPlant` steps it.

Conventions. Velocities positive downward / forward. The top boundary is the seed's
``N(0) = alpha_A (v_top - U_A) + (M_S + M_B) g`` (Eq. 3.5) with the string weight carried at the
top, so U_A = M_S g / alpha_A holds the string hanging still; ``U_A = v + (W + M_S g)/alpha_A``
drills at ROP v with WOB W (Eq. 3.9 at steady state). At t = 0 the string hangs at rest (uniform
tension M_B g, the bit touching the rock with zero WOB; U_A = M_S g / alpha_A and U_T = 0 before
t = 0). Reported hook load = N(0) + M_S g (= (M_S + M_B) g - WOB at steady state); surface torque
= alpha_T (U_T - omega_top).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from downhole.bit.law import approx_depth_of_cut, bit_forces
from downhole.bit.rock_surface import RockSurfaceSpec, rock_depth, rock_init, rock_init_helix
from downhole.errors import DownholeInputError
from downhole.params import BitParams, NeutralStringParams, get_preset
from downhole.sim.kernel import (
    CHANNELS,
    KernelModel,
    KernelParams,
    kernel_state,
    new_kernel_work,
    new_run_state,
    run_kernel,
)
from downhole.sim.plant import check_start, steady_depth_of_cut, under_rig
from downhole.sim.wave import (
    WaveSegment,
    segments_from_pipe,
    wave_incoming,
    wave_push,
    wave_state,
)

__all__ = [
    "NOMINAL_U_A",
    "NOMINAL_U_T",
    "NDDEMatrices",
    "NeutralModel",
    "NeutralPack",
    "neutral_model",
]

#: docs/seed-errata.md: open-loop commands giving 10 mm/s and 20 rad/s with Table 3.1.
NOMINAL_U_A = 1.147224
NOMINAL_U_T = 22.5196

_EXTRA_UNITS = {"command_axial": "m/s", "command_angular": "rad/s",
                "measured_axial_velocity": "m/s", "measured_angular_velocity": "rad/s",
                "eid_disturbance_axial": "m/s", "eid_disturbance_angular": "rad/s",
                "eid_prediction_axial": "m/s", "eid_prediction_angular": "rad/s"}


@dataclass(frozen=True)
class NDDEMatrices:
    """Design model of seed Eq. 3.13 (all matrices 2x2 diagonal; state x = [v_bit, omega_bit]).

    ``x' = A0 x + A1 x(t-h1) + A2 x(t-h2) + G1 x'(t-h1) + G2 x'(t-h2) + Bd d + B u(t - tau)``
    with ``u = [U_A - M_S g/alpha_A, U_T]``, ``d = [-W + Gamma1 W(t-h1), -T + Upsilon1 T(t-h2)]``,
    ``h = 2 tau`` and the input delays ``tau = (tau1, tau2)``.

    Attributes
    ----------
    A0, A1, A2, G1, G2, B, Bd, C : ndarray, shape (2, 2)
        The matrices of the equation above (``C`` the output map, the identity).
    h1, h2 : float
        State delays 2 tau1 and 2 tau2, s.
    tau : (float, float)
        Input delays (tau1, tau2), s.
    u_offset : (float, float)
        Input offsets (M_S g/alpha_A in m/s, 0).
    """

    A0: np.ndarray
    A1: np.ndarray
    A2: np.ndarray
    G1: np.ndarray
    G2: np.ndarray
    B: np.ndarray
    Bd: np.ndarray
    C: np.ndarray
    h1: float
    h2: float
    tau: tuple[float, float]
    u_offset: tuple[float, float]

    def channel(self, i: int) -> dict:
        """Scalar coefficients of channel ``i`` (0 axial, 1 torsional).

        Parameters
        ----------
        i : int
            0 for the axial channel, 1 for the torsional one.

        Returns
        -------
        dict
            ``a0`` (A0 entry, 1/s), ``a1`` (the delayed-state coefficient, A1 for axial, A2 for
            torsional, 1/s), ``g1`` (the neutral coefficient, G1 or G2, dimensionless), ``b``
            (input gain, 1/s), ``h`` (state delay 2 tau, s), ``tau`` (input delay, s) and
            ``offset`` (input offset: M_S g/alpha_A in m/s for axial, 0 for torsional).
        """
        a1 = self.A1[0, 0] if i == 0 else self.A2[1, 1]
        g1 = self.G1[0, 0] if i == 0 else self.G2[1, 1]
        return {"a0": float(self.A0[i, i]), "a1": float(a1), "g1": float(g1),
                "b": float(self.B[i, i]), "h": self.h1 if i == 0 else self.h2,
                "tau": self.tau[i], "offset": self.u_offset[i]}


@dataclass(frozen=True)
class NeutralModel:
    """Immutable neutral-type model: parameters plus derived wave segments and coefficients.

    Use :func:`neutral_model` to build it.

    Parameters
    ----------
    params : NeutralStringParams
        The string.
    bit : BitParams
        The bit.
    axial, torsional : WaveSegment
        The string's axial and torsional wave segments (surface to bit).
    name : str
        Label (default ``"neutral"``).
    """

    params: NeutralStringParams
    bit: BitParams
    axial: WaveSegment
    torsional: WaveSegment
    name: str = "neutral"
    #: For a model derived from a described system (:class:`downhole.system.DrillingSystem`):
    #: ``with_rig()`` returns the same line and lumped bottom under the rig's top node (a
    #: :class:`~downhole.string.fem.DirectionalModel` of kind ``"neutral"``), which a run with a
    #: ``top_drive`` / ``hook`` steps. None: the seed's model (Table 3.1), whose top is the
    #: damper pair alpha_A, alpha_T.
    with_rig: object = field(default=None, repr=False, compare=False)

    #: What the seed's model's top is (the refusal of a rig names it).
    rigless_top = "this neutral model is the seed's (Table 3.1): its top is the damper pair " \
                  "alpha_A, alpha_T"

    # --- Eq. 3.9 coefficients -----------------------------------------------------------------
    @property
    def tau1(self) -> float:
        """Axial one-way delay L sqrt(rho/E), s."""
        return self.axial.delay

    @property
    def tau2(self) -> float:
        """Torsional one-way delay L sqrt(rho/G), s."""
        return self.torsional.delay

    @property
    def gammas(self) -> tuple[float, float, float]:
        """(Gamma1, Gamma2, Gamma3) of Eq. 3.9 (EA/c_A = Z_axial)."""
        z, a, m = self.axial.impedance, self.params.alpha_axial, self.params.bit_mass
        return (a - z) / (a + z), z / m, 2 * a * z / (m * (a + z))

    @property
    def upsilons(self) -> tuple[float, float, float]:
        """(Upsilon1, Upsilon2, Upsilon3) of Eq. 3.9 (GJ/c_T = Z_torsional)."""
        z, a, m = self.torsional.impedance, self.params.alpha_torsional, self.params.bit_inertia
        return (a - z) / (a + z), z / m, 2 * a * z / (m * (a + z))

    @property
    def hang_command(self) -> float:
        """U_A that holds the string hanging still: M_S g / alpha_A, m/s."""
        return self.params.string_mass * self.params.g / self.params.alpha_axial

    def steady_inputs(self, rop: float, omega: float, wob: float, tob: float) -> tuple[float, float]:
        """Open-loop commands (U_A, U_T) for a steady state.

        U_A = v + (W + M_S g)/alpha_A, U_T = omega + T/alpha_T.

        Parameters
        ----------
        rop : float
            Bit axial velocity v, m/s.
        omega : float
            Bit angular velocity, rad/s.
        wob : float
            Weight on bit W, N.
        tob : float
            Torque on bit T, N m.

        Returns
        -------
        (U_A, U_T) : tuple of float
            Axial command, m/s, and angular command, rad/s.
        """
        p = self.params
        return (rop + (wob + p.string_mass * p.g) / p.alpha_axial, omega + tob / p.alpha_torsional)

    def steady_state(self, u_axial: float, u_angular: float, iterations: int = 200):
        """Steady drilling state (v, omega, W, T) under constant commands.

        With the approximated depth of cut d = 2 pi v/omega: a damped fixed-point iteration of
        v = U_A - (W + M_S g)/alpha_A, omega = U_T - T/alpha_T.

        Parameters
        ----------
        u_axial : float
            Axial command U_A, m/s.
        u_angular : float
            Angular command U_T, rad/s.
        iterations : int, optional
            Number of fixed-point iterations (default 200; no convergence check).

        Returns
        -------
        (v, omega, wob, tob) : tuple of float
            Bit axial velocity (m/s), angular velocity (rad/s), weight on bit (N) and torque on bit
            (N m).
        """
        p = self.params
        bp = self.bit.kernel_params()
        v, w = u_axial - self.hang_command, u_angular
        for _ in range(iterations):
            d = approx_depth_of_cut(max(v, 0.0), max(w, 1e-9), bp)
            wob, tob = bit_forces(d, v, w, bp)
            v_new = u_axial - (wob + p.string_mass * p.g) / p.alpha_axial
            w_new = u_angular - tob / p.alpha_torsional
            v, w = 0.5 * (v + v_new), 0.5 * (w + w_new)
        return v, w, wob, tob

    def ndde(self) -> NDDEMatrices:
        """Matrices of the design model (Eq. 3.13) with the corrected delays."""
        g1, g2, g3 = self.gammas
        u1, u2, u3 = self.upsilons
        d = np.diag
        return NDDEMatrices(
            A0=d([-g2, -u2]), A1=d([-g1 * g2, 0.0]), A2=d([0.0, -u1 * u2]),
            G1=d([g1, 0.0]), G2=d([0.0, u1]), B=d([g3, u3]),
            Bd=d([1.0 / self.params.bit_mass, 1.0 / self.params.bit_inertia]), C=np.eye(2),
            h1=2 * self.tau1, h2=2 * self.tau2, tau=(self.tau1, self.tau2),
            u_offset=(self.hang_command, 0.0))

    #: Default step of :func:`downhole.sim.simulate`, s.
    default_dt = 1e-4

    def run_pack(self, dt: float, depth_of_cut: str, inputs, bit_noise: bool,
                 options: dict) -> NeutralPack:
        """The pack :func:`downhole.sim.simulate` runs; ``options``: ``rock_points_per_pitch``;
        ``top_drive`` and ``hook`` run the line under the rig (see :attr:`with_rig`)."""
        opts = dict(options)
        if "top_drive" in opts or "hook" in opts:
            model = under_rig(self)
            rig = {k: opts.pop(k) for k in ("top_drive", "hook") if k in opts}
            opts.pop("rock_points_per_pitch", None)
            if opts:
                raise DownholeInputError(f"the neutral line under a rig takes the options "
                                         f"top_drive, hook; got {sorted(opts)}")
            return model.run_pack(dt, depth_of_cut, inputs, bit_noise, rig)
        rpp = int(opts.pop("rock_points_per_pitch", 512))
        if opts:
            raise DownholeInputError(f"the neutral model takes the option "
                                     f"rock_points_per_pitch; got {sorted(opts)}")
        return NeutralPack(self, dt, depth_of_cut, rpp, bit_noise)

    def kernel_pack(self, dt: float, depth_of_cut: str = "delayed",
                    rock_points_per_pitch: int = 512, bit_noise: bool = False) -> NeutralPack:
        """The model as a configuration of the one kernel (see :class:`NeutralPack`).

        Parameters
        ----------
        dt : float
            Step, s (at most tau1).
        depth_of_cut : {"delayed", "approximate"}
            Depth-of-cut model.
        rock_points_per_pitch : int
            Resolution of the rock-surface memory.
        bit_noise : bool
            Commands carry WOB and TOB disturbances.

        Returns
        -------
        NeutralPack
        """
        return NeutralPack(self, dt, depth_of_cut, rock_points_per_pitch, bit_noise)

    def with_bit(self, bit: BitParams) -> NeutralModel:
        """Same string, another bit (e.g. a perturbed epsilon).

        Parameters
        ----------
        bit : BitParams
            The new bit parameters.

        Returns
        -------
        NeutralModel
        """
        return NeutralModel(self.params, bit, self.axial, self.torsional, self.name)


def neutral_model(string: NeutralStringParams | str = "table_3_1",
                  bit: BitParams | None = None) -> NeutralModel:
    """Build a :class:`NeutralModel` from parameters or a preset name.

    Parameters
    ----------
    string : NeutralStringParams or str
        String parameters, or a preset name of kind ``neutral`` (``"table_3_1"``).
    bit : BitParams, optional
        Bit parameters; default the preset's bit (Table 3.1's for a NeutralStringParams).

    Returns
    -------
    NeutralModel

    Raises
    ------
    DownholeInputError
        Unknown or wrong-kind preset, or |Gamma1| >= 1 / |Upsilon1| >= 1 (unstable difference
        operator; impossible with positive alpha and impedance, checked anyway).
    """
    name = "neutral"
    if isinstance(string, str):
        try:
            pre = get_preset(string)
        except KeyError as exc:
            raise DownholeInputError(str(exc.args[0])) from None
        if pre.kind != "neutral":
            raise DownholeInputError(f"preset {string!r} is a {pre.kind} preset; the neutral model "
                                     "needs a 'neutral' preset such as 'table_3_1'")
        name = f"neutral:{string}"
        bit = bit or pre.bit
        string = pre.string
    elif not isinstance(string, NeutralStringParams):
        raise DownholeInputError(f"string must be NeutralStringParams or a preset name, got "
                                 f"{type(string).__name__}")
    if bit is None:
        bit = get_preset("table_3_1").bit
    ax, to = segments_from_pipe(string.pipe, string.length)
    model = NeutralModel(string, bit, ax, to, name)
    for label, val in (("Gamma1", model.gammas[0]), ("Upsilon1", model.upsilons[0])):
        if not abs(val) < 1.0:
            raise DownholeInputError(f"|{label}| = {abs(val):.6g} >= 1: the difference operator "
                                     "of the neutral model is unstable")
    return model


def _check_positive(name, value):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x <= 0:
        raise DownholeInputError(f"{name} must be a positive finite number, got {value!r}")
    return x


def _sample(sig, t, name):
    from downhole.sim.inputs import sample_signal

    return sample_signal(sig, t, name)


def _neutral_steady(model: NeutralModel, u_rel: float, u_t: float):
    """Steady drilling state ``(v, omega, W, T)`` of the neutral model under the constant
    commands ``u_rel = U_A - M_S g / alpha_A`` (m/s) and ``U_T`` (rad/s): the root of
    ``v = u_rel - W / alpha_A``, ``omega = U_T - T / alpha_T`` with the bit law at the steady
    depth of cut d = 2 pi v / omega (Eq. 3.9 at rest in a frame moving with the bit)."""
    from scipy.optimize import fsolve

    p = model.params
    bp = model.bit.kernel_params()
    if not (u_t > 0):
        raise DownholeInputError(f"a steady drilling start needs a positive angular set-point, "
                                 f"got top_drive_angular_velocity = {u_t!r} rad/s")

    def res(z):
        v, w = z
        wob, tob = bit_forces(steady_depth_of_cut(v, w) if w > 0 else 0.0, v, w, bp)
        return [(v - u_rel + wob / p.alpha_axial) / max(abs(u_rel), 1e-6),
                (w - u_t + tob / p.alpha_torsional) / u_t]

    v0, w0, _, _ = model.steady_state(u_rel + model.hang_command, u_t)
    # Newton from a few starts (the fixed-point iterate, the commands, half the axial command):
    # the first that converges to a cutting state wins
    guesses = [(v0, w0), (max(u_rel, 1e-6), u_t), (max(0.5 * u_rel, 1e-6), 0.9 * u_t)]
    for guess in guesses:
        (v, w), _info, ok, _ = fsolve(res, guess, full_output=True, xtol=1e-13)
        if ok == 1 and v > 0 and w > 0 and max(abs(x) for x in res((v, w))) <= 1e-9:
            break
    if ok != 1 or not (v > 0 and w > 0) or max(abs(x) for x in res((v, w))) > 1e-9:
        raise DownholeInputError(
            f"no steady drilling state of the neutral model at top_drive_axial_velocity = "
            f"{u_rel:g} m/s, top_drive_angular_velocity = {u_t:g} rad/s (the bit does not cut "
            f"steadily: v = {v:.4g} m/s, omega = {w:.4g} rad/s); start from 'rest' or "
            "'off_bottom', or raise the axial set-point")
    wob, tob = bit_forces(steady_depth_of_cut(v, w), v, w, bp)
    return float(v), float(w), float(wob), float(tob)


def _neutral_start(model: NeutralModel, dt: float, start: str, u_rel: float, u_t: float,
                   rock_points_per_pitch: int, clearance: float = 0.05):
    """Wave buffers, rock surface and bit state ``[x, v, theta, omega]`` for ``start``.

    ``rest``: hanging still (uniform tension M_B g in the line, the string weight carried at the
    top), the bit touching a flat bottom with zero WOB. ``off_bottom``: the whole string moving
    at (u_rel, U_T) (no bit force, so the top damper carries nothing but the weight), the bit
    ``clearance`` m above a flat bottom. ``steady``: the steady drilling state of
    :func:`_neutral_steady`: the line moving at (v, omega) and carrying M_B g - W axially and
    the torque T (tension N_T = -T in the wave variables, the line dragging its top backward),
    the bit on a helical bottom of depth of cut 2 pi v / omega. Returns
    ``(waves, rock, bstate)`` with ``waves = (ha, pa, wpa, ht, pt, wpt)``.
    """
    check_start(start)
    p = model.params
    spec = RockSurfaceSpec(model.bit.n_blades, int(rock_points_per_pitch), True)
    bstate = np.zeros(4)
    if start == "rest":
        waves = (wave_state(model.axial, dt, 0.0, p.bit_mass * p.g)
                 + wave_state(model.torsional, dt, 0.0, 0.0))
        return waves, rock_init(spec, 0.0, 0.0), bstate
    if start == "off_bottom":
        if not (isinstance(clearance, (int, float)) and math.isfinite(clearance)
                and clearance > 0):
            raise DownholeInputError(f"clearance must be a positive distance in m, got "
                                     f"{clearance!r}")
        v, w, wob, tob = u_rel, u_t, 0.0, 0.0
        rock = rock_init(spec, clearance, 0.0)
    else:
        v, w, wob, tob = _neutral_steady(model, u_rel, u_t)
        rock = rock_init_helix(spec, 0.0, 0.0, steady_depth_of_cut(v, w))
    waves = (wave_state(model.axial, dt, v, p.bit_mass * p.g - wob)
             + wave_state(model.torsional, dt, w, -tob))
    bstate[1], bstate[3] = v, w
    return waves, rock, bstate


class NeutralPack:
    """The neutral model as a configuration of the one kernel
    (:func:`~downhole.sim.kernel.run_kernel`) for one (dt, depth of cut, rock resolution).

    Two nodes: the massless top (node 0, with the damper alpha to the commanded velocity: the
    kernel's velocity hook with no spring, and its top-drive PI with no integral gain) and the
    bit (node 1, mass M_B, inertia I_B, weight M_B g), joined by the wave line (the kernel's wave
    joint from B = node 0 to C = node 1). The string weight M_S g is carried at the top (the
    recorded hook load adds it). Commands: ``top_drive_axial_velocity`` relative to the hanging
    equilibrium (U_A - M_S g / alpha_A) and ``top_drive_angular_velocity`` (U_T), held over a
    step; the top node answers at the end of the step (its mass is zero, so the Newmark step
    gives the seed's algebraic top boundary, Eq. 3.5). The bit force is linearly implicit (the
    law linearized at the start of each step, as the seed's scheme), at dt <= tau1.

    Parameters
    ----------
    model : NeutralModel
        The model.
    dt : float
        Step, s (at most the axial delay tau1).
    depth_of_cut : {"delayed", "approximate"}
        Depth of cut from the rock-surface memory or d = 2 pi v / omega.
    rock_points_per_pitch : int
        Resolution of the rock-surface memory.
    bit_noise : bool
        The commands carry two more columns, WOB and TOB disturbances (N, N m).
    """

    observation_names = ("time", *CHANNELS[:11])
    command_names = ("top_drive_axial_velocity", "top_drive_angular_velocity")

    def __init__(self, model: NeutralModel, dt: float, depth_of_cut: str = "delayed",
                 rock_points_per_pitch: int = 512, bit_noise: bool = False):
        dt = _check_positive("dt", dt)
        if dt > model.tau1:
            raise DownholeInputError(f"dt = {dt} s exceeds the axial wave delay tau1 = "
                                     f"{model.tau1:.6g} s")
        if depth_of_cut not in ("delayed", "approximate"):
            raise DownholeInputError(f"depth_of_cut must be 'delayed' or 'approximate', got "
                                     f"{depth_of_cut!r}")
        self.model, self.dt, self.depth_of_cut = model, dt, depth_of_cut
        self.approx = depth_of_cut == "approximate"
        self.rock_points_per_pitch = int(rock_points_per_pitch)
        p = model.params
        self.mats = np.zeros((18, 2))
        self.mats[0, 1] = self.mats[4, 1] = p.bit_mass
        self.mats[6, 1] = self.mats[10, 1] = p.bit_inertia
        self.Ldense = np.zeros((2, 1, 1))
        self.elem = np.zeros((2, 8))
        self.node = np.array([[0.0, 0.0], [p.bit_mass * p.g, 0.0]])
        self.bitp = model.bit.kernel_params()
        self.top = KernelParams(
            velocity_hook=True, hook_k=0.0, hook_c=float(p.alpha_axial),
            hook_load0=float(p.bit_mass * p.g), torque_mode=False,
            kp=float(p.alpha_torsional), ki=0.0, soft_gain=0.0, soft_tau=0.0, mu=0.0,
            v_eps=1e-3, approx_doc=self.approx, node_b=0, node_c=1, hybrid=True, dense=False,
            n_lags_a=0, lag_tau_a=1.0, n_lags_t=0, lag_tau_t=1.0, fb0=0.0, fc0=0.0,
            prebalanced_weight=float(p.string_mass * p.g), bit_iterations=1,
            bit_disturbance=bool(bit_noise), rig_node=0, bit_node=1)
        self.n_cmd = 4 if bit_noise else 2
        self._no_ref = np.zeros((1, 4))

    def default_command(self) -> dict:
        """Hanging still: both relative commands zero."""
        return {name: 0.0 for name in self.command_names}

    def start(self, start: str, command, clearance: float = 0.05):
        """Kernel state and the record of t = 0 for ``start`` (see :func:`_neutral_start`)
        with the top under ``command`` (relative axial, angular; ``rest``: the commands before
        t = 0 hold the string still whatever the set-point)."""
        m, p = self.model, self.model.params
        u_rel, u_t = float(command[0]), float(command[1])
        (ha, pa, wpa, ht, pt, wpt), (surf, istate, rp), b = _neutral_start(
            m, self.dt, start, u_rel, u_t, self.rock_points_per_pitch, clearance)
        if start == "rest":
            u_rel = u_t = 0.0
        za, zt = wpa.impedance, wpt.impedance
        a_in, b_in = wave_incoming(ha, pa, wpa)
        ta_in, tb_in = wave_incoming(ht, pt, wpt)
        vtop = (2 * za * b_in + p.alpha_axial * u_rel - p.bit_mass * p.g) / (za + p.alpha_axial)
        wtop = (2 * zt * tb_in + p.alpha_torsional * u_t) / (zt + p.alpha_torsional)
        wave_push(ha, pa, wpa, vtop - b_in, b[1] - a_in)  # the outgoing waves of t = 0
        wave_push(ht, pt, wpt, wtop - tb_in, b[3] - ta_in)
        d = (approx_depth_of_cut(b[1], b[3], self.bitp) if self.approx
             else rock_depth(surf, istate, rp, b[0], b[2]))
        wob, tob = bit_forces(d, b[1], b[3], self.bitp)
        state = np.zeros((6, 2))
        state[1, 0], state[4, 0] = vtop, wtop
        state[0, 1], state[1, 1], state[3, 1], state[4, 1] = b
        state[2, 1] = (p.bit_mass * p.g + 2 * za * a_in - za * b[1] - wob) / p.bit_mass
        state[5, 1] = (2 * zt * ta_in - zt * b[3] - tob) / p.bit_inertia
        rec0 = np.zeros(len(CHANNELS))
        rec0[:11] = (b[0], b[1], b[2], b[3], d, wob, tob,
                     (p.bit_mass + p.string_mass) * p.g - p.alpha_axial * (u_rel - vtop),
                     p.alpha_torsional * (u_t - wtop), vtop, wtop)
        st = dict(state=state, run=new_run_state(), surf=surf, istate=istate, rp=rp,
                  wa=(ha, pa, wpa), wt=(ht, pt, wpt), lag=np.zeros((4, 1)),
                  work=new_kernel_work(2), cmd=np.zeros((1, self.n_cmd)))
        return st, rec0

    def kernel_model(self) -> KernelModel:
        """The model's part of the :func:`~downhole.sim.kernel.run_kernel` arguments (compiled
        closed loops call the kernel step by step with it and :func:`kernel_state`)."""
        return KernelModel(self.mats, self.Ldense, self.elem, self.node, self.top, self.bitp)

    def _kernel(self, st, cmd, rec, rec_every, rec_start):
        return run_kernel(self.kernel_model(), kernel_state(st), cmd, self._no_ref,
                          cmd.shape[0], self.dt, rec, rec_every, rec_start)

    def run(self, st, rows, rec, rec_every, rec_start=0):
        """Advance ``len(rows) - 1`` steps, step k holding ``rows[k + 1]`` (relative axial,
        angular [, WOB and TOB disturbances]); ``(status, rows written)``."""
        return self._kernel(st, np.ascontiguousarray(rows[1:]), rec, rec_every, rec_start)

    def step(self, st, command, rec):
        """One step holding ``command``; ``(status, rows)``."""
        cmd = st["cmd"]
        cmd[0, :] = command[:cmd.shape[1]]
        return self._kernel(st, cmd, rec, 1, 0)

    # ---- the run protocol of downhole.sim.simulate
    kind = "neutral"

    def rows(self, inputs, t) -> np.ndarray:
        """The relative commands (U_A - hang, U_T[, 0, 0]) at the step boundaries ``t`` from the
        seed's (U_A, U_T) ``inputs`` (default the nominal)."""
        ua, ut = _open_loop_inputs(inputs, t)
        out = np.empty((len(t), self.n_cmd))
        out[:, 0] = ua
        out[:, 0] -= self.model.hang_command
        out[:, 1] = ut
        out[:, 2:] = 0.0
        return out

    def still_rows(self, t) -> np.ndarray:
        """Rows holding the string still (a closed loop's start)."""
        return np.zeros((len(t), self.n_cmd))

    def begin(self, start: str, rows, clearance: float):
        """Kernel state and the record of t = 0 (see :meth:`start`)."""
        return self.start(start, rows[0], clearance)

    def first_command(self, rows) -> np.ndarray:
        """The command held before a controller's first output."""
        return np.array(rows[0, :2], float)

    def command(self, out, held, who: str) -> None:
        """A controller's output into ``held``: the plant's names, or the seed's
        ``command_axial`` (U_A, including M_S g / alpha_A) and ``command_angular``."""
        held[0], held[1] = _relative_command(out, self.model.hang_command, who)

    def command_channels(self, hist) -> dict:
        """The held commands as the seed's U_A, U_T."""
        return {"command_axial": hist[:, 0] + self.model.hang_command,
                "command_angular": hist[:, 1].copy()}

    def channels(self, rec, rows, idx):
        """The Result's channels (open loop: with U_A, U_T), units and attributes."""
        ch = {name: rec[:, i] for i, name in enumerate(CHANNELS[:11])}
        if rows is not None:
            ch.update(self.command_channels(rows[idx]))
        m = self.model
        return ch, dict(_EXTRA_UNITS), {"tau1": m.tau1, "tau2": m.tau2,
                                        "epsilon": m.bit.epsilon}


def _open_loop_inputs(inputs, t) -> tuple:
    """The open-loop commands (U_A, U_T) sampled at ``t``: two arrays like ``t``, or a number
    for a constant."""
    if inputs is None:
        inputs = (NOMINAL_U_A, NOMINAL_U_T)
    if hasattr(inputs, "mode"):
        if inputs.mode != "velocity":
            raise DownholeInputError("the neutral model takes velocity commands (U_A, U_T); "
                                     f"got SurfaceInputs.{inputs.mode}")
        sigs = (inputs.axial, inputs.angular)
    else:
        try:
            sigs = tuple(inputs)
        except TypeError:
            raise DownholeInputError("inputs must be SurfaceInputs.velocity(U_A, U_T) or a "
                                     f"pair of signals, got {inputs!r}") from None
        if len(sigs) != 2:
            raise DownholeInputError(f"inputs: expected (U_A, U_T), got {len(sigs)} items")
    return tuple(_constant_or_sample(sig, t, name) for sig, name in
                 zip(sigs, ("inputs axial (U_A)", "inputs angular (U_T)")))


def _constant_or_sample(sig, t, name):
    """A finite number as it is (numpy broadcasts it), any other signal sampled at ``t``."""
    if isinstance(sig, (int, float)) and not isinstance(sig, bool) and math.isfinite(sig):
        return float(sig)
    return _sample(sig, t, name)


def _relative_command(out, hang: float, who: str) -> tuple[float, float]:
    """A controller's command as (relative axial, angular): the plant's names, or the seed's
    ``command_axial`` (U_A, including M_S g / alpha_A) and ``command_angular``."""
    if not isinstance(out, dict):
        raise DownholeInputError(f"{who}.command must return a dict with "
                                 f"{NeutralPack.command_names}, got {out!r}")
    if "top_drive_axial_velocity" in out and "top_drive_angular_velocity" in out:
        return float(out["top_drive_axial_velocity"]), float(out["top_drive_angular_velocity"])
    if "command_axial" in out and "command_angular" in out:
        return float(out["command_axial"]) - hang, float(out["command_angular"])
    raise DownholeInputError(f"{who}.command must return {NeutralPack.command_names} (or "
                             f"command_axial, command_angular), got {sorted(out)}")
