"""Hardware-in-the-loop (seed Fig. 6.9): the string model without its bit, and a software rig.

In HIL the drill bit model is replaced by a laboratory rig. The plant sends the velocities of
the string's last node (``last_node_axial_velocity`` v_M, ``last_node_angular_velocity``
omega_M) over the link; the rig drives its bit with them and returns the measured bit
velocities (``bit_axial_velocity`` v_B, ``bit_angular_velocity`` omega_B).

:class:`HILStringPlant` is the string of a directional model as its linear FEM (the model's
design FEM on the same nodes, exact zero-order-hold step, top drive torque-driven, hook
slack-off force; wellbore friction is not included) with the bit replaced by a spring-damper
coupling to the rig's bit: the force on the last node is
``F = k_a (x_B - x_M) + c_a (v_B - v_M)`` (x_B integrated from the returned v_B), and likewise
the torque with ``k_t, c_t``. :class:`SoftwareRig` is a rig in software (bit mass and inertia
with the Detournay law and the approximated depth of cut, the same coupling seen from the bit
side); it is a controller-shaped object, so :meth:`ControllerClient.serve` runs it as the rig at
the other end of the link, exactly where real hardware would be.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from downhole.bit.law import approx_depth_of_cut, bit_force_slopes, bit_forces
from downhole.errors import DownholeInputError
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

__all__ = ["COUPLING", "HILStringPlant", "SoftwareRig", "build_hil_plant"]

#: Default coupling (k_a N/m, c_a N s/m, k_t N m/rad, c_t N m s/rad).
COUPLING = (1e7, 1e5, 1e4, 2e3)


class HILStringPlant:
    """Linear FEM string whose last node is coupled to a rig's bit (see module docstring).

    Parameters
    ----------
    dmodel : DirectionalModel
        The string (a hybrid uses its design FEM on the same nodes).
    dt : float
        Step, s.
    coupling : (k_a, c_a, k_t, c_t)
        Stiffnesses and dampers coupling the last node to the rig's bit: N/m, N s/m, N m/rad,
        N m s/rad.
    top_drive_inertia : float
        Top-drive inertia, kg m^2.

    Raises
    ------
    DownholeInputError
        If ``dt`` is not positive.

    Notes
    -----
    Commands: ``slack_off_force`` (N), ``surface_torque`` (N m), ``bit_axial_velocity`` (m/s),
    ``bit_angular_velocity`` (rad/s; the last two from the rig).
    """

    command_names = ("slack_off_force", "surface_torque", "bit_axial_velocity",
                     "bit_angular_velocity")

    def __init__(self, dmodel, dt: float = 1e-3, coupling=COUPLING,
                 top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA):
        if not dt > 0:
            raise DownholeInputError(f"dt must be > 0 s, got {dt!r}")
        self.dmodel = dmodel
        self.dt = float(dt)
        self.coupling = tuple(float(c) for c in coupling)
        A_d, B_d = dmodel.linear_model(dt, top_drive_inertia)
        ns = A_d.shape[0]
        n2 = ns // 2
        self.n = n2 // 2
        Gam = dmodel.nodal_force_map(dt, top_drive_inertia)
        last = 2 * (self.n - 1)
        self.A_d = np.ascontiguousarray(A_d)
        self.B = np.ascontiguousarray(np.hstack([B_d, Gam[:, [last, last + 1]]]))
        self.i_x, self.i_a = last, last + 1
        self.i_v, self.i_w = n2 + last, n2 + last + 1
        self.weight = float(dmodel.buoyed_weight)
        self.reset()

    def reset(self) -> dict:
        self.z = np.zeros(self.A_d.shape[0])
        self.xb = np.zeros(2)  # rig bit displacement / angle (integrated from its velocities)
        self.k = 0
        self._f = np.zeros(2)
        self._u = np.zeros(4)
        return self._obs(0.0, 0.0)

    def _obs(self, vb, wb) -> dict:
        z, n2 = self.z, self.z.size // 2
        return {"time": self.k * self.dt, "last_node_axial_velocity": float(z[self.i_v]),
                "last_node_angular_velocity": float(z[self.i_w]),
                "bit_axial_velocity": float(vb), "bit_angular_velocity": float(wb),
                "wob": float(-self._f[0]), "tob": float(-self._f[1]),
                "hook_load": self.weight - float(self._u[0]), "surface_torque": float(self._u[1]),
                "top_drive_axial_velocity": float(z[n2]),
                "top_drive_angular_velocity": float(z[n2 + 1])}

    def step(self, command: dict) -> dict:
        """Advance the string one ``dt`` with the surface commands and the rig's bit velocities.

        The coupling force and torque between the last node and the rig's bit (springs and dampers
        ``coupling``) act on the last node; the rig's bit position and angle are integrated from
        its velocities.

        Parameters
        ----------
        command : dict
            ``slack_off_force`` (N), ``surface_torque`` (N m), ``bit_axial_velocity`` (m/s) and
            ``bit_angular_velocity`` (rad/s).

        Returns
        -------
        dict
            The observation: ``time`` (s), last-node and bit velocities (m/s, rad/s), ``wob`` (N)
            and ``tob`` (N m) (the coupling loads), ``hook_load`` (N), ``surface_torque`` (N m) and
            the top-drive velocities (m/s, rad/s).

        Raises
        ------
        DownholeInputError
            If a command is missing.
        SimulationDiverged
            If the string state is no longer finite.
        """
        try:
            s, tq, vb, wb = (float(command[k]) for k in self.command_names)
        except KeyError as exc:
            raise DownholeInputError(f"command lacks {exc.args[0]!r}; expected "
                                     f"{self.command_names}") from None
        ka, ca, kt, ct = self.coupling
        z = self.z
        fa = ka * (self.xb[0] - z[self.i_x]) + ca * (vb - z[self.i_v])
        ft = kt * (self.xb[1] - z[self.i_a]) + ct * (wb - z[self.i_w])
        self._f[:] = fa, ft
        self._u[:] = s, tq, fa, ft
        self.z = self.A_d @ z + self.B @ self._u
        self.xb[0] += self.dt * vb
        self.xb[1] += self.dt * wb
        self.k += 1
        if not np.all(np.isfinite(self.z)):
            from downhole.errors import SimulationDiverged

            raise SimulationDiverged(self.k * self.dt, "hil string state")
        return self._obs(vb, wb)


class RigParams(NamedTuple):
    """The software rig's bit and coupling as its compiled step takes them (SI units)."""

    mass: float
    inertia: float
    k_a: float
    c_a: float
    k_t: float
    c_t: float


@njit(cache=True)
def _rig_step(st, vm, wm, dt, par, bitp):
    """Advance the rig's bit one step (implicit in the coupling dampers and bit slopes).

    st = [x_B, v_B, a_B, w_B, x_M, a_M]; par a :class:`RigParams`."""
    m, J, ka, ca, kt, ct = par.mass, par.inertia, par.k_a, par.c_a, par.k_t, par.c_t
    xb, vb, ab, wb, xm, am = st[0], st[1], st[2], st[3], st[4], st[5]
    d = approx_depth_of_cut(vb, wb, bitp)
    w0, t0 = bit_forces(d, vb, wb, bitp)
    sa, sw = bit_force_slopes(d, vb, wb, bitp, True)
    fa = ka * (xm - xb) + ca * vm - w0 + sa * vb
    ft = kt * (am - ab) + ct * wm - t0 + sw * wb
    vb1 = (m * vb + dt * fa) / (m + dt * (ca + sa))
    wb1 = (J * wb + dt * ft) / (J + dt * (ct + sw))
    st[0] = xb + dt * vb1
    st[1] = vb1
    st[2] = ab + dt * wb1
    st[3] = wb1
    st[4] = xm + dt * vm
    st[5] = am + dt * wm


class SoftwareRig:
    """A laboratory rig in software: bit + rock behind the HIL link.

    Controller-shaped (``reset()``, ``command(t, observation, reference)``): it reads
    ``last_node_axial_velocity`` / ``last_node_angular_velocity`` and returns
    ``bit_axial_velocity`` / ``bit_angular_velocity``.

    Parameters
    ----------
    bit : BitParams
        The rig's bit and rock.
    dt : float
        Step, s (the plant's).
    mass, inertia : float
        Bit (and rig spindle) mass, kg, and inertia, kg m^2.
    coupling : (k_a, c_a, k_t, c_t)
        Must equal the plant's.
    """

    def __init__(self, bit, dt: float = 1e-3, mass: float = 500.0, inertia: float = 5.0,
                 coupling=COUPLING):
        self.bitp = bit.kernel_params()
        self.dt = float(dt)
        k_a, c_a, k_t, c_t = (float(c) for c in coupling)
        self.par = RigParams(mass=float(mass), inertia=float(inertia), k_a=k_a, c_a=c_a, k_t=k_t,
                             c_t=c_t)
        self.reset()

    def reset(self) -> None:
        self.st = np.zeros(6)

    def command(self, t, observation, reference=None) -> dict:
        """Bit velocities answering the string's last-node velocities (one step).

        Parameters
        ----------
        t : float
            Time, s (unused).
        observation : mapping
            ``last_node_axial_velocity`` (m/s) and ``last_node_angular_velocity`` (rad/s).
        reference : mapping, optional
            Unused (controller signature).

        Returns
        -------
        dict
            ``bit_axial_velocity`` (m/s) and ``bit_angular_velocity`` (rad/s) of the rig's bit
            after the step.
        """
        _rig_step(self.st, float(observation["last_node_axial_velocity"]),
                  float(observation["last_node_angular_velocity"]), self.dt, self.par,
                  self.bitp)
        return {"bit_axial_velocity": float(self.st[1]),
                "bit_angular_velocity": float(self.st[3])}


def build_hil_plant(model: str = "hybrid68", *, dt: float = 1e-3, wob: float = 120e3,
                    surface_torque: float = 15e3, coupling=COUPLING):
    """A :class:`~downhole.sil.plants.SilPlant` over :class:`HILStringPlant` (HIL mode).

    Default (open-loop) command: slack-off ``wob`` and ``surface_torque``; safe: both 0. The
    rig's bit velocities are merged in by the runtime.

    Parameters
    ----------
    model : str, optional
        A hybrid preset name (default ``"hybrid68"``); any other name gives the default FEM
        string.
    dt : float, optional
        Step, s (default 1e-3).
    wob : float, optional
        Open-loop slack-off force, N (default 120e3).
    surface_torque : float, optional
        Open-loop surface torque, N m (default 15e3).
    coupling : (k_a, c_a, k_t, c_t), optional
        Coupling stiffnesses and dampers between the last node and the rig's bit: N/m,
        N s/m, N m/rad, N m s/rad (must equal the rig's).

    Returns
    -------
    SilPlant
        Commands ``slack_off_force`` and ``surface_torque``; ``bit_axial_velocity`` and
        ``bit_angular_velocity`` pass through from the rig.

    Raises
    ------
    DownholeInputError
        If ``dt`` is not positive or a command is outside its admissible range.
    """
    from downhole.sil.plants import SilPlant
    from downhole.string.fem import fem_model
    from downhole.string.hybrid import HYBRID_PRESETS, hybrid_model

    dm = hybrid_model(model) if model in HYBRID_PRESETS else fem_model(n_elements=107)
    hp = HILStringPlant(dm, dt, coupling)
    sp = SilPlant(_SurfaceOnly(hp), ("slack_off_force", "surface_torque"),
                  {"slack_off_force": wob, "surface_torque": surface_torque},
                  {"slack_off_force": 0.0, "surface_torque": 0.0}, name=f"{dm.name} (HIL string)",
                  info={"model": model, "interface": "hil", "n_states": dm.n_states})
    sp.rig_bit = dm.bit
    sp.passthrough = ("bit_axial_velocity", "bit_angular_velocity")
    return sp


class _SurfaceOnly:
    """Adapter letting SilPlant validate only the surface commands (the runtime adds the rig's
    bit velocities; without them the bit is held at the last node's velocity)."""

    def __init__(self, hp: HILStringPlant):
        self.hp = hp
        self.dt = hp.dt

    def reset(self):
        return self.hp.reset()

    def step(self, cmd):
        c = dict(cmd)
        if "bit_axial_velocity" not in c:
            c["bit_axial_velocity"] = float(self.hp.z[self.hp.i_v])
            c["bit_angular_velocity"] = float(self.hp.z[self.hp.i_w])
        return self.hp.step(c)
