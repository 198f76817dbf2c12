"""The neutral-type distributed drill string of seed Ch. 3 as a configuration of the mechanics core:
one wave segment (surface to bit) per field, the bit mass and inertia at the bottom, and a damper
(alpha_A, alpha_T) to the commanded velocity at the massless top (seed Eqs. 3.1-3.6).

Eliminating the waves gives the neutral delay-differential equations of Eq. 3.9 with the delays
tau = L sqrt(rho/E), L sqrt(rho/G) (Eq. 3.10 prints them inverted); :meth:`NeutralModel.ndde`
returns its matrices (Eq. 3.13) for control design. :func:`simulate_neutral` runs the wave form
(compiled open loop, or closed loop through a controller's compiled runner built from this
module's per-step functions, or any controller in a Python loop) and returns a Result.

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
from dataclasses import dataclass

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_force_slopes, bit_forces
from downhole.bit.rock_surface import (
    RockSurfaceSpec,
    rock_advance,
    rock_depth,
    rock_init,
    rock_init_helix,
)
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.params import BitParams, NeutralStringParams, get_preset
from downhole.sim.plant import Plant, check_start, steady_depth_of_cut
from downhole.sim.references import as_reference
from downhole.sim.result import Result
from downhole.sim.wave import (
    WaveSegment,
    segments_from_pipe,
    wave_read_at,
    wave_read_plan,
    wave_source_forces,
    wave_state,
    wave_step_at,
)
from downhole.units import si_or_number

__all__ = [
    "NEUTRAL_CHANNELS",
    "NOMINAL_U_A",
    "NOMINAL_U_T",
    "NDDEMatrices",
    "NeutralModel",
    "NeutralPlant",
    "neutral_model",
    "simulate_neutral",
]

#: docs/seed-errata.md: open-loop commands giving 10 mm/s and 20 rad/s with Table 3.1.
NOMINAL_U_A = 1.147224
NOMINAL_U_T = 22.5196

NEUTRAL_CHANNELS = (
    "time", "bit_axial_position", "bit_axial_velocity", "bit_angle", "bit_angular_velocity",
    "depth_of_cut", "wob", "tob", "hook_load", "surface_torque", "top_drive_axial_velocity",
    "top_drive_angular_velocity", "command_axial", "command_angular",
)
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


# ----------------------------------------------------------------------------------------------
# compiled kernel: per-step functions shared by the open-loop runner below and by the compiled
# closed-loop runners that controllers offer through ``neutral_runner`` (see simulate_neutral)
# ----------------------------------------------------------------------------------------------
#: Names, in order, of the plant arguments (``plant_args``) that :func:`simulate_neutral` hands to
#: a controller's compiled closed-loop runner; they are the first positional arguments of
#: :func:`_run_neutral` and are passed on to :func:`neutral_wave_start`,
#: :func:`neutral_top_and_bit`, :func:`neutral_record` and :func:`neutral_advance`.
NEUTRAL_KERNEL_ARGS = ("za", "zt", "m_b", "i_b", "alpha_a", "alpha_t", "f_top", "m_s_g", "grav",
                       "bitp", "approx", "ha", "pa", "wpa", "ht", "pt", "wpt", "surf", "istate",
                       "rp")


@njit(cache=True, inline="always")
def neutral_wave_start(ha, pa, wpa, ht, pt, wpt):
    """Wave clocks, the loop-invariant read plan ``(cap_a, cap_t, off_a, fr_a, off_t, fr_t)``
    and the incoming waves at the current time: ``(na, nt, plan, a_in, b_in, a_in_t, b_in_t)``.
    (The per-step functions group arguments in tuples: a call with more than 30 arguments is
    not inlined by numba.)"""
    na = pa[0]
    nt = pt[0]
    cap_a = wpa.cap
    cap_t = wpt.cap
    off_a, fr_a = wave_read_plan(wpa.delay_steps)
    off_t, fr_t = wave_read_plan(wpt.delay_steps)
    a_in, b_in = wave_read_at(ha, na, off_a, fr_a, cap_a, wpa.a_init, wpa.b_init)
    a_in_t, b_in_t = wave_read_at(ht, nt, off_t, fr_t, cap_t, wpt.a_init, wpt.b_init)
    return na, nt, (cap_a, cap_t, off_a, fr_a, off_t, fr_t), a_in, b_in, a_in_t, b_in_t


@njit(cache=True, inline="always")
def neutral_top_and_bit(za, zt, alpha_a, alpha_t, f_top, bitp, approx, surf, istate, rp,
                        x, v, th, w, a_in, b_in, a_in_t, b_in_t, ua, ut, fwob, ftob):
    """The algebraic part of one step at t_k: the massless top nodes under the surface commands
    (``ua``, ``ut``; line force 2 Z b_in - Z v_top) and the bit forces (plus the force noise
    ``fwob``, ``ftob``). Returns ``(vtop, wtop, d, wob, tob)``."""
    sa_top, _ = wave_source_forces(za, a_in, b_in)
    st_top, _ = wave_source_forces(zt, a_in_t, b_in_t)
    vtop = (sa_top + alpha_a * ua - f_top) / (za + alpha_a)
    wtop = (st_top + alpha_t * ut) / (zt + alpha_t)
    if approx:
        d = approx_depth_of_cut(v, w, bitp)
    else:
        d = rock_depth(surf, istate, rp, x, th)
    wob, tob = bit_forces(d, v, w, bitp)
    wob += fwob
    tob += ftob
    return vtop, wtop, d, wob, tob


@njit(cache=True, inline="always")
def neutral_record(out, rec, t, x, v, th, w, d, wob, tob, vtop, wtop, ua, ut, alpha_a, alpha_t,
                   f_top, m_s_g):
    """Write the row ``rec`` of :data:`NEUTRAL_CHANNELS` (hook load N(0) + M_S g, surface torque
    alpha_T (U_T - omega_top)); returns the first non-finite channel index, 0 if none."""
    out[rec, 0] = t
    out[rec, 1] = x
    out[rec, 2] = v
    out[rec, 3] = th
    out[rec, 4] = w
    out[rec, 5] = d
    out[rec, 6] = wob
    out[rec, 7] = tob
    out[rec, 8] = alpha_a * (vtop - ua) + f_top + m_s_g
    out[rec, 9] = alpha_t * (ut - wtop)
    out[rec, 10] = vtop
    out[rec, 11] = wtop
    out[rec, 12] = ua
    out[rec, 13] = ut
    for c in range(1, 14):
        if not math.isfinite(out[rec, c]):
            return c
    return 0


@njit(cache=True, inline="always")
def neutral_advance(za, zt, m_b, i_b, grav, bitp, approx, ha, wpa, ht, wpt, surf, istate, rp,
                    plan, na, nt, x, v, th, w, a_in, b_in, a_in_t, b_in_t, top_bit, dt):
    """Advance from t_k to t_{k+1}: push the outgoing waves of t_k, read the incoming ones of
    t_{k+1}, step the bit node (trapezoidal on the line force at the bit: F_C of t_k, 2 Z a_in of
    t_{k+1} with the end damper implicit; bit forces with implicit frozen slopes) and the rock
    surface. ``plan`` is from :func:`neutral_wave_start`, ``top_bit`` = ``(vtop, wtop, d, wob,
    tob)`` from :func:`neutral_top_and_bit` at t_k. Returns ``(na, nt, x, v, th, w, a_in, b_in,
    a_in_t, b_in_t)`` at t_{k+1}."""
    cap_a, cap_t, off_a, fr_a, off_t, fr_t = plan
    vtop, wtop, d, wob, tob = top_bit
    _, fa_line = wave_step_at(ha, na, cap_a, za, vtop, v, a_in, b_in)
    _, ft_line = wave_step_at(ht, nt, cap_t, zt, wtop, w, a_in_t, b_in_t)
    na += 1
    nt += 1
    a1, b1 = wave_read_at(ha, na, off_a, fr_a, cap_a, wpa.a_init, wpa.b_init)
    a1t, b1t = wave_read_at(ht, nt, off_t, fr_t, cap_t, wpt.a_init, wpt.b_init)
    _, sa1 = wave_source_forces(za, a1, b1)
    _, st1 = wave_source_forces(zt, a1t, b1t)
    ca, ct = bit_force_slopes(d, v, w, bitp, approx)
    v1 = (m_b * v / dt + 0.5 * fa_line + 0.5 * sa1 + grav - wob + ca * v) / (
        m_b / dt + 0.5 * za + ca)
    w1 = (i_b * w / dt + 0.5 * ft_line + 0.5 * st1 - tob + ct * w) / (
        i_b / dt + 0.5 * zt + ct)
    xprev = x
    thprev = th
    x += 0.5 * dt * (v + v1)
    th += 0.5 * dt * (w + w1)
    if not approx:
        rock_advance(surf, istate, rp, thprev, xprev, th, x)
    return na, nt, x, v1, th, w1, a1, b1, a1t, b1t


@njit(cache=True)
def _run_neutral(za, zt, m_b, i_b, alpha_a, alpha_t, f_top, m_s_g, grav, bitp, approx,
                 ha, pa, wpa, ht, pt, wpt, surf, istate, rp,
                 u_in, fnoise, nsteps, dt, every, out, bstate, t0):
    """Open loop: advance the wave model ``nsteps`` steps under the commands ``u_in`` (2, nsteps
    + 1) from the bit state ``bstate`` = [x, v, theta, omega] at time ``t0`` (updated in place;
    the wave buffers and rock surface carry the rest of the state). Records t0 + k dt for k = 0,
    every, ..., nsteps; returns (status, step, channel). The outgoing waves of the last time are
    not pushed, so a later call continues the run."""
    x = bstate[0]
    v = bstate[1]
    th = bstate[2]
    w = bstate[3]
    na, nt, plan, a_in, b_in, a_in_t, b_in_t = neutral_wave_start(ha, pa, wpa, ht, pt, wpt)
    rec = 0
    for k in range(nsteps + 1):
        ua = u_in[0, k]
        ut = u_in[1, k]
        top_bit = neutral_top_and_bit(
            za, zt, alpha_a, alpha_t, f_top, bitp, approx, surf, istate, rp,
            x, v, th, w, a_in, b_in, a_in_t, b_in_t, ua, ut, fnoise[0, k], fnoise[1, k])
        vtop, wtop, d, wob, tob = top_bit
        if k % every == 0 or k == nsteps:
            c = neutral_record(out, rec, t0 + k * dt, x, v, th, w, d, wob, tob, vtop, wtop,
                               ua, ut, alpha_a, alpha_t, f_top, m_s_g)
            if c != 0:
                pa[0] = na
                pt[0] = nt
                return 1, k, c
            rec += 1
        if k == nsteps:
            break
        na, nt, x, v, th, w, a_in, b_in, a_in_t, b_in_t = neutral_advance(
            za, zt, m_b, i_b, grav, bitp, approx, ha, wpa, ht, wpt, surf, istate, rp, plan,
            na, nt, x, v, th, w, a_in, b_in, a_in_t, b_in_t, top_bit, dt)
    bstate[0] = x
    bstate[1] = v
    bstate[2] = th
    bstate[3] = w
    pa[0] = na
    pt[0] = nt
    return 0, nsteps, 0


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


class NeutralPlant(Plant):
    """Step-by-step neutral-type plant (the :class:`~downhole.sim.plant.Plant` contract) over
    the same compiled kernel as :func:`simulate_neutral`.

    Commands (named, held over the step), the same names as at every other fidelity:
    ``top_drive_axial_velocity`` (m/s): the top velocity command relative to the hanging
    equilibrium, U_A - M_S g / alpha_A, so that 0 holds the string still; and
    ``top_drive_angular_velocity`` (U_T, rad/s). Observations: ``time`` and the channels of
    :data:`NEUTRAL_CHANNELS` (``bit_axial_velocity``, ``bit_angular_velocity``, ``wob``,
    ``tob``, ``hook_load``, ``surface_torque``, the top nodes' actual velocities
    ``top_drive_*_velocity`` and the seed-convention commands ``command_axial`` (U_A) and
    ``command_angular`` (U_T)).

    ``reset(start=...)``: ``"rest"`` (hanging still, bit touching the rock), ``"off_bottom"``
    (moving at the set-point, bit ``clearance`` m above a flat bottom) or ``"steady"`` (the
    steady drilling state under the set-point commands; the bit velocities are the root of
    v = u_A - W/alpha_A, omega = U_T - T/alpha_T with the bit law at d = 2 pi v/omega).

    Parameters
    ----------
    model : NeutralModel or str
        The string (a preset name such as ``"table_3_1"`` works).
    dt : float
        Plant step, s (<= tau1).
    depth_of_cut : {"delayed", "approximate"}
        Depth of cut from the rock-surface memory (delayed, Eqs. 2.9-2.10) or the
        approximation d = 2 pi v / omega.
    rock_points_per_pitch : int
        Resolution of the rock-surface memory.

    Examples
    --------
    >>> plant = NeutralPlant("table_3_1", dt=1e-4)
    >>> obs = plant.reset()                       # hanging at rest, bit on bottom, zero WOB
    >>> u = {"top_drive_axial_velocity": NOMINAL_U_A - plant.model.hang_command,
    ...      "top_drive_angular_velocity": NOMINAL_U_T}
    >>> obs = plant.reset(start="steady", set_point=u)
    >>> round(obs["bit_angular_velocity"], 2)
    20.0
    """

    command_names = ("top_drive_axial_velocity", "top_drive_angular_velocity")
    observation_names = NEUTRAL_CHANNELS

    def __init__(self, model: NeutralModel | str = "table_3_1", dt: float = 1e-4,
                 depth_of_cut: str = "delayed", rock_points_per_pitch: int = 512):
        dt = si_or_number(dt, "time", "dt")  # "0.5 ms" or a pint quantity
        if not isinstance(model, NeutralModel):
            model = neutral_model(model)
        self.model = model
        self.dt = _check_positive("dt", dt)
        if self.dt > model.tau1:
            raise DownholeInputError(f"dt = {dt} s exceeds the axial wave delay tau1 = "
                                     f"{model.tau1:.6g} s")
        if depth_of_cut not in ("delayed", "approximate"):
            raise DownholeInputError(f"depth_of_cut must be 'delayed' or 'approximate', got "
                                     f"{depth_of_cut!r}")
        self.depth_of_cut = depth_of_cut
        self._rpp = int(rock_points_per_pitch)
        p = model.params
        self._consts = (model.axial.impedance, model.torsional.impedance, p.bit_mass,
                        p.bit_inertia, p.alpha_axial, p.alpha_torsional,
                        (p.string_mass + p.bit_mass) * p.g, p.string_mass * p.g,
                        p.bit_mass * p.g, model.bit.kernel_params(), depth_of_cut == "approximate")
        self._out = np.empty((2, len(NEUTRAL_CHANNELS)))
        self.reset()

    @property
    def time(self) -> float:
        """Current time, s."""
        return self._k * self.dt

    def _reset(self, start: str, set_point: dict, clearance: float = 0.05) -> dict:
        m = self.model
        u_rel = float(set_point["top_drive_axial_velocity"])
        u_t = float(set_point["top_drive_angular_velocity"])
        self._waves, self._rock, self._bstate = _neutral_start(
            m, self.dt, start, u_rel, u_t, self._rpp, clearance)
        self._k = 0
        # rest: the commands before t = 0 held the string still whatever the set-point
        self._u = (np.array([m.hang_command, 0.0]) if start == "rest"
                   else np.array([u_rel + m.hang_command, u_t]))
        return self._advance(self._u, 0, None)

    def _advance(self, u, steps, fnoise):
        n = max(steps, 1)
        u_in = np.empty((2, n + 1))
        u_in[0], u_in[1] = u[0], u[1]
        fn = np.zeros((2, n + 1)) if fnoise is None else fnoise
        bstate = self._bstate if steps > 0 else self._bstate.copy()
        ha, pa, wpa, ht, pt, wpt = self._waves
        if steps == 0:  # observe only: run on copies
            ha, pa, ht, pt = ha.copy(), pa.copy(), ht.copy(), pt.copy()
        surf, ist, rp = self._rock
        if steps == 0:
            surf, ist = surf.copy(), ist.copy()
        status, kfail, cfail = _run_neutral(
            *self._consts, ha, pa, wpa, ht, pt, wpt, surf, ist, rp, u_in, fn, steps, self.dt,
            max(steps, 1), self._out, bstate, self._k * self.dt)
        if status != 0:
            raise SimulationDiverged((self._k + kfail) * self.dt, NEUTRAL_CHANNELS[cfail])
        self._k += steps
        row = self._out[1 if steps > 0 else 0]
        return {name: float(row[i]) for i, name in enumerate(NEUTRAL_CHANNELS)}

    def _step(self, command: np.ndarray) -> dict:
        """Hold ``command`` (relative axial, angular) over one step of ``dt``."""
        self._u = np.array([command[0] + self.model.hang_command, command[1]])
        return self._advance(self._u, 1, None)

    def _step_noisy(self, u, steps, fnoise):
        """``steps`` steps under the seed-convention commands ``u = (U_A, U_T)`` with bit-force
        noise (the Python closed loop of :func:`simulate_neutral`)."""
        self._u = u
        return self._advance(u, steps, fnoise)


def simulate_neutral(model: NeutralModel | NeutralStringParams | str = "table_3_1",
                     bit: BitParams | None = None, *, duration: float = 10.0, dt: float = 1e-4,
                     controller=None, inputs=None, reference=None, noise=None,
                     depth_of_cut: str = "delayed", record_dt: float | None = None,
                     seed: int = 0, rock_points_per_pitch: int = 512,
                     control_dt: float | None = None, python_loop: bool = False,
                     attrs: dict | None = None, start: str = "rest",
                     clearance: float = 0.05) -> Result:
    """Simulate the neutral-type (wave) model, open loop or closed loop.

    Parameters
    ----------
    model : NeutralModel, NeutralStringParams or str
        The string (a preset name such as ``"table_3_1"`` works).
    bit : BitParams, optional
        Overrides the model's bit (e.g. a perturbed epsilon for a sensitivity study).
    duration, dt : float
        Simulated time and step, s (dt <= tau1; default 1e-4).
    controller : object, optional
        Closed loop: any object with ``reset()`` and ``command(t, observation, reference) ->
        {"command_axial": U_A, "command_angular": U_T}`` runs in a Python loop over a
        :class:`NeutralPlant` (observation: the named channels, velocities with the measurement
        noise; reference: array [axial m/s, angular rad/s]). Compiled fast path (the extension
        point, duck-typed): if the controller has ``neutral_runner(dt)`` and it returns a
        callable ``runner(plant_args, ref, mnoise, fnoise, nsteps, dt, every, out)``, the loop
        runs there instead. ``plant_args`` are the kernel arguments named by
        :data:`NEUTRAL_KERNEL_ARGS`, ``ref`` and ``mnoise`` (2, nsteps + 1) the sampled
        reference and measurement noise, ``fnoise`` (2, nsteps + 1) the bit-force noise and
        ``out`` the record (rows every ``every`` steps and the last, columns
        :data:`NEUTRAL_CHANNELS`); it returns ``(status, step, channel, extra)`` (status 0 or 1
        for a non-finite channel, ``extra`` a dict of further recorded channels). The runner is
        built from this module's compiled per-step functions (:func:`neutral_top_and_bit`,
        :func:`neutral_record`, :func:`neutral_advance`), so the physics is the open-loop
        kernel's; :meth:`EIDController.neutral_runner
        <downhole.control.eid.controller.EIDController.neutral_runner>` is one. Returning
        ``None`` falls back to the Python loop. The attribute ``label`` (default the class name)
        names the controller in the result's attributes.
    inputs : SurfaceInputs or tuple, optional
        Open-loop commands (U_A, U_T) in the seed's convention (U_A includes M_S g/alpha_A):
        ``SurfaceInputs.velocity(axial=U_A, angular=U_T)`` or a pair of signals (constant,
        ``(t, values)`` or ``f(t)``). Default the nominal (1.147224 m/s, 22.5196 rad/s), which
        gives 10 mm/s and 20 rad/s. Ignored with a controller.
    reference : Reference or pair of signals, optional
        Closed-loop reference (bit axial velocity m/s, bit angular velocity rad/s); default the
        controller's ``reference`` attribute if it has one, else 10 mm/s and 20 rad/s. See
        :mod:`downhole.sim.references`.
    noise : dict, optional
        White noise: ``{"axial": sigma_v, "angular": sigma_w}`` measurement noise (standard
        deviation per controller sample, m/s and rad/s) and optionally ``"wob"``, ``"tob"``
        (N, N m) as bit-force noise (per plant step).
    depth_of_cut : {"delayed", "approximate"}
        Depth of cut from the rock-surface memory (delayed, Eqs. 2.9-2.10) or the
        approximation d = 2 pi v / omega.
    record_dt : float, optional
        Output interval, s; default: every step up to 20 000 samples, then thinned.
    seed : int
        Noise seed.
    rock_points_per_pitch : int
        Resolution of the rock-surface memory (grid points per blade pitch, default 512).
    control_dt : float, optional
        Python-loop controllers only: controller sample time (a multiple of dt; default dt).
        The command is held between samples.
    python_loop : bool
        Ignore a controller's compiled ``neutral_runner`` and step it through the Python loop
        (the EID gives the same numbers either way; for checking controllers stepped from
        Python, e.g. in the SIL loop).
    attrs : dict, optional
        Extra metadata merged into the result's attributes.
    start : {"rest", "off_bottom", "steady"}
        Initial state (:data:`downhole.sim.plant.START_MODES`), open loop only: hanging at
        rest; moving at the commands of t = 0 with the bit ``clearance`` m off a flat bottom; or
        the steady drilling state under the commands of t = 0 (see :class:`NeutralPlant`). A
        closed loop starts from rest (the controllers' states are not initialized at an
        equilibrium).
    clearance : float
        Bit height above the hole bottom for ``start="off_bottom"``, m.

    Returns
    -------
    Result
        Standard channels plus ``command_axial``/``command_angular`` (U_A, U_T); with a controller
        also the reference and measured velocities, and for the EID its disturbance estimates and
        predictions. The attribute ``bit_radius`` is set (for MSE).

    Raises
    ------
    DownholeInputError
        Bad arguments (named). SimulationDiverged: a channel went non-finite.
    """
    if not isinstance(model, NeutralModel):
        model = neutral_model(model, bit)
    elif bit is not None:
        model = model.with_bit(bit)
    duration = _check_positive("duration", si_or_number(duration, "time", "duration"))
    dt = _check_positive("dt", si_or_number(dt, "time", "dt"))
    record_dt = si_or_number(record_dt, "time", "record_dt")
    control_dt = si_or_number(control_dt, "time", "control_dt")
    clearance = si_or_number(clearance, "length", "clearance")
    if depth_of_cut not in ("delayed", "approximate"):
        raise DownholeInputError(f"depth_of_cut must be 'delayed' or 'approximate', got "
                                 f"{depth_of_cut!r}")
    if dt > model.tau1:
        raise DownholeInputError(f"dt = {dt} s exceeds the axial wave delay tau1 = "
                                 f"{model.tau1:.6g} s")
    nsteps = int(round(duration / dt))
    if nsteps < 1:
        raise DownholeInputError(f"duration = {duration} s is shorter than one step dt = {dt} s")
    if record_dt is None:
        every = max(1, int(math.ceil((nsteps + 1) / 20000)))
    else:
        every = max(1, int(round(_check_positive("record_dt", record_dt) / dt)))
    t = np.arange(nsteps + 1) * dt
    p = model.params
    g = p.g

    rng = np.random.default_rng(seed)
    noise = dict(noise or {})
    unknown = set(noise) - {"axial", "angular", "wob", "tob"}
    if unknown:
        raise DownholeInputError(f"noise: unknown keys {sorted(unknown)}; expected axial, "
                                 "angular, wob, tob")
    mnoise = np.zeros((2, nsteps + 1))
    fnoise = np.zeros((2, nsteps + 1))
    for i, key in enumerate(("axial", "angular")):
        s = float(noise.get(key, 0.0))
        if not s >= 0:
            raise DownholeInputError(f"noise.{key} must be >= 0, got {s}")
        if s > 0:
            mnoise[i] = rng.normal(0.0, s, nsteps + 1)
    for i, key in enumerate(("wob", "tob")):
        s = float(noise.get(key, 0.0))
        if not s >= 0:
            raise DownholeInputError(f"noise.{key} must be >= 0, got {s}")
        if s > 0:
            fnoise[i] = rng.normal(0.0, s, nsteps + 1)
    meta = {"model": model.name, "dt": dt, "depth_of_cut": depth_of_cut,
            "bit_radius": model.bit.radius, "n_blades": model.bit.n_blades,
            "controller": "open-loop", "tau1": model.tau1, "tau2": model.tau2,
            "epsilon": model.bit.epsilon}

    closed = controller is not None
    check_start(start)
    if closed and start != "rest":
        raise DownholeInputError(f"start={start!r} needs an open-loop run: a closed loop "
                                 "starts from 'rest' (the controller's integrators and "
                                 "predictor have no equilibrium initialization)")
    meta["start"] = start
    u_in = np.zeros((2, nsteps + 1))
    ref = np.zeros((2, nsteps + 1))
    runner = None
    if closed:
        if not (hasattr(controller, "command") and hasattr(controller, "reset")):
            raise DownholeInputError("controller must have reset() and command(t, observation, "
                                     f"reference); got {type(controller).__name__}")
        if reference is None:
            reference = getattr(controller, "reference", None)
        reference = as_reference(reference)
        ref[:] = reference.sample(t)
        meta["reference"] = reference.name
        meta["controller"] = getattr(controller, "label", type(controller).__name__)
        hook = getattr(controller, "neutral_runner", None)
        if not python_loop and hook is not None:
            runner = hook(dt)
        if runner is None:
            meta.update(attrs or {})
            return _simulate_python_loop(model, controller, dt, nsteps, every, ref, mnoise,
                                         fnoise, depth_of_cut, rock_points_per_pitch,
                                         control_dt, meta)
    else:
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
        u_in[0] = _sample(sigs[0], t, "inputs axial (U_A)")
        u_in[1] = _sample(sigs[1], t, "inputs angular (U_T)")

    (ha, pa, wpa, ht, pt, wpt), (surf, istate, rp), bstate = _neutral_start(
        model, dt, start, float(u_in[0, 0]) - model.hang_command, float(u_in[1, 0]),
        rock_points_per_pitch, clearance)
    nrec = nsteps // every + 1 + (1 if nsteps % every else 0)
    out = np.empty((nrec, len(NEUTRAL_CHANNELS)))
    plant_args = (model.axial.impedance, model.torsional.impedance, p.bit_mass, p.bit_inertia,
                  p.alpha_axial, p.alpha_torsional, (p.string_mass + p.bit_mass) * g,
                  p.string_mass * g, p.bit_mass * g, model.bit.kernel_params(),
                  depth_of_cut == "approximate", ha, pa, wpa, ht, pt, wpt, surf, istate, rp)
    if runner is None:
        status, kfail, cfail = _run_neutral(*plant_args, u_in, fnoise, nsteps, dt, every, out,
                                            bstate, 0.0)
        extra = {}
    else:
        status, kfail, cfail, extra = runner(plant_args, ref, mnoise, fnoise, nsteps, dt, every,
                                             out)
    if status != 0:
        raise SimulationDiverged(kfail * dt, NEUTRAL_CHANNELS[cfail])
    channels = {name: out[:, i] for i, name in enumerate(NEUTRAL_CHANNELS) if name != "time"}
    if closed:
        tr = out[:, 0]
        idx = np.minimum(np.round(tr / dt).astype(int), nsteps)
        channels["reference_axial_velocity"] = ref[0, idx]
        channels["reference_angular_velocity"] = ref[1, idx]
        channels.update(extra)
    meta.update(attrs or {})
    return Result(out[:, 0], channels, units=_EXTRA_UNITS, attrs=meta)


def _simulate_python_loop(model, controller, dt, nsteps, every, ref, mnoise, fnoise,
                          depth_of_cut, rock_points_per_pitch, control_dt, meta) -> Result:
    """Closed loop with a controller stepped from Python over a :class:`NeutralPlant`."""
    if control_dt is None:
        sub = 1
    else:
        sub = int(round(_check_positive("control_dt", control_dt) / dt))
        if sub < 1 or abs(sub * dt - control_dt) > 1e-9 * control_dt:
            raise DownholeInputError(f"control_dt = {control_dt} s must be a multiple of dt = "
                                     f"{dt} s")
    if nsteps % sub:
        raise DownholeInputError(f"duration must be a multiple of control_dt = {sub * dt} s")
    plant = NeutralPlant(model, dt, depth_of_cut, rock_points_per_pitch)
    if getattr(controller, "dt", None) is not None:
        controller.dt = sub * dt  # the contract's sample time (downhole.control.base)
    controller.reset()
    rec_every = max(1, int(round(every / sub))) * sub
    names = NEUTRAL_CHANNELS
    rows, meas = [], []
    obs = plant.reset()
    for k in range(0, nsteps + 1, sub):
        o = dict(obs)
        o["bit_axial_velocity"] += mnoise[0, k]
        o["bit_angular_velocity"] += mnoise[1, k]
        cmd = controller.command(k * dt, o, {"reference_axial_velocity": float(ref[0, k]),
                                             "reference_angular_velocity": float(ref[1, k])})
        if not isinstance(cmd, dict):
            raise DownholeInputError(f"{type(controller).__name__}.command must return a dict "
                                     f"with {NeutralPlant.command_names}, got {cmd!r}")
        u = plant.command_vector(cmd)
        u[0] += model.hang_command
        if k % rec_every == 0 or k == nsteps:
            # the record at t_k shows the top nodes under the new command (as the compiled path)
            rec = plant._advance(u, 0, fnoise[:, k:k + 1])
            rows.append([rec[n] for n in names])
            meas.append((o["bit_axial_velocity"], o["bit_angular_velocity"], k))
        if k == nsteps:
            break
        obs = plant._step_noisy(u, sub, fnoise[:, k:k + sub + 1])
    out = np.array(rows)
    mk = np.array(meas)
    idx = mk[:, 2].astype(int)
    channels = {name: out[:, i] for i, name in enumerate(names) if name != "time"}
    channels["reference_axial_velocity"] = ref[0, idx]
    channels["reference_angular_velocity"] = ref[1, idx]
    channels["measured_axial_velocity"] = mk[:, 0]
    channels["measured_angular_velocity"] = mk[:, 1]
    meta["control_dt"] = sub * dt
    return Result(out[:, 0], channels, units=_EXTRA_UNITS, attrs=meta)
