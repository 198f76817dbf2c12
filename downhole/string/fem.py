"""Directional drill-string FEM: axial-torsional bar elements along measured depth (seed Sec. 4.2).

:func:`fem_model` meshes a :class:`~downhole.string.drillstring.DrillString` along a
:class:`~downhole.well.WellPath` into 2-node bar elements carrying two 1-D fields along measured
depth (axial displacement, twist angle). There is no cos-angle "rotation" (seed Eqs. 4.3-4.5,
docs/seed-errata.md): curvature enters only through gravity (rho A g cos(inclination), lumped
exactly as w * delta-TVD per element) and soft-string wellbore contact. Damping is Rayleigh (alpha0
M + beta0 K) or modal. The model is an immutable :class:`DirectionalModel`;
:func:`downhole.sim.simulate` runs it (the one compiled kernel, :mod:`downhole.sim.kernel`, implicit
Newmark) from the static equilibrium and :class:`DirectionalPlant` steps it one dt at a time
(a lumped :class:`~downhole.sim.lumped_model.ChainModel` too).
``DirectionalModel.linear_model`` exports the discrete linear model (A_d, B_d); the non-dimensional
control-affine form for the DHP design (Eqs. 4.13-4.19, 4.25) is built from it on the control side,
:func:`downhole.control.affine.from_directional`.
"""

from __future__ import annotations

import itertools
import math
import weakref
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_banded

from downhole.bit.rock_surface import RockSurfaceSpec, rock_init
from downhole.contact.softstring import normal_weight
from downhole.errors import DownholeInputError, SimulationDiverged
from downhole.params import BitParams, DirectionalWellParams
from downhole.params.presets import get_preset
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA, Hook, TopDrive
from downhole.sim.kernel import (
    CHANNELS,
    KernelModel,
    KernelParams,
    kernel_state,
    new_kernel_work,
    new_run_state,
    run_kernel,
)
from downhole.sim.lumped_model import ChainModel
from downhole.sim.plant import Plant, under_rig
from downhole.sim.wave import WaveParams
from downhole.string.drillstring import DrillString
from downhole.string.neutral import NeutralModel
from downhole.string.zoh import StateSpace, zoh
from downhole.units import si_or_number
from downhole.well import WellPath

__all__ = [
    "EXTRA_UNITS",
    "DirectionalModel",
    "DirectionalPlant",
    "fem_from_nodes",
    "fem_model",
    "table_5_1_setup",
]

#: Units of the extra (non-standard) channels written by the directional models.
EXTRA_UNITS = {"force_b": "N", "torque_b": "N*m", "force_c": "N", "torque_c": "N*m",
               "top_drive_angle": "rad"}


@dataclass(frozen=True, eq=False)
class DirectionalModel:
    """Immutable description of a directional FEM or hybrid model (matrices in SI units).

    Attributes
    ----------
    name, kind : str
        Label; ``"fem"`` or ``"hybrid"``.
    well : WellPath
    string : DrillString
    bit : BitParams
    node_md : ndarray (n,)
        Measured depth of each node, m (top first; bit last).
    Ma, Ka, Ca, Mt, Kt, Ct : ndarray (2, n)
        Tridiagonal mass, stiffness and damping per field: row 0 diagonal, row 1 off-diagonal
        (last entry unused). The torsional mass includes no top drive (added at run time).
    Cdense : ndarray (2, n, n) or None
        Dense damping per field (modal damping) or None (Rayleigh, tridiagonal).
    gravity : ndarray (n,)
        Nodal axial gravity force (buoyed), N, downward positive.
    elem : ndarray (n, 8)
        Per element: length, dt/ds (3), w g_perp (3), contact flag.
    radius : ndarray (n,)
        Torque arm of contact friction at each node, m (pipe outer radius, stabilizer radius).
    mu, v_eps : float
        Wellbore friction coefficient and regularization velocity (m/s).
    node_b, node_c : int
        Node indices of B and C (hybrid: ends of the wave segment; FEM: nodes at those depths).
    wave : dict or None
        Hybrid only: wave segments and their damping treatment.
    """

    name: str
    kind: str
    well: WellPath
    string: DrillString
    bit: BitParams
    node_md: np.ndarray
    Ma: np.ndarray
    Ka: np.ndarray
    Ca: np.ndarray
    Mt: np.ndarray
    Kt: np.ndarray
    Ct: np.ndarray
    Cdense: np.ndarray | None
    gravity: np.ndarray
    elem: np.ndarray
    radius: np.ndarray
    mu: float
    v_eps: float
    node_b: int
    node_c: int
    wave: dict | None = None
    info: dict = field(default_factory=dict)

    #: Default step of :func:`downhole.sim.simulate`, s (the real-time testbed's).
    default_dt = 1e-3

    def run_pack(self, dt: float, depth_of_cut: str, inputs, bit_noise: bool,
                 options: dict) -> _Packed:
        """The pack :func:`downhole.sim.simulate` runs; ``options``: ``top_drive`` (default
        :class:`~downhole.params.rig.TopDrive`) and ``hook`` (default
        :class:`~downhole.params.rig.Hook`)."""
        opts = dict(options)
        top_drive = opts.pop("top_drive", None) or TopDrive()
        hook = opts.pop("hook", None) or Hook()
        if opts:
            raise DownholeInputError(f"a {self.kind} model takes the options top_drive and "
                                     f"hook (commands go into inputs); got {sorted(opts)}")
        if bit_noise:
            raise DownholeInputError("noise.wob / noise.tob (bit-force noise) is a neutral-model "
                                     "input")
        return _packed(self, dt, top_drive, hook, depth_of_cut)

    @property
    def n_nodes(self) -> int:
        return int(self.node_md.size)

    @property
    def n_states(self) -> int:
        """Number of mechanical states (4 per node), the seed's state count."""
        return 4 * self.n_nodes

    @property
    def buoyed_weight(self) -> float:
        """Axial buoyed weight carried by hook + bit in static equilibrium, N."""
        w = float(self.gravity.sum())
        if self.wave is not None:
            w += self.wave["line_weight"]
        return w

    def __repr__(self) -> str:
        return (f"DirectionalModel({self.name!r}, {self.kind}, {self.n_nodes} nodes = "
                f"{self.n_states} states, md {self.node_md[0]:g}..{self.node_md[-1]:g} m)")

    # ---------------------------------------------------------------- natural frequencies
    def natural_frequencies(self, field: str = "axial", count: int = 5, top: str = "free",
                            bottom: str = "free") -> np.ndarray:
        """Lowest natural frequencies (Hz) of the undamped string, FEM only.

        ``top``/``bottom`` = ``"fixed"`` or ``"free"`` (top drive inertia not included)."""
        from scipy.linalg import eigh

        if self.kind not in ("fem", "lumped"):
            raise DownholeInputError("natural_frequencies is defined for FEM (and lumped) "
                                     "models only")
        M = _tri_dense(self.Ma if field == "axial" else self.Mt)
        K = _tri_dense(self.Ka if field == "axial" else self.Kt)
        keep = np.ones(self.n_nodes, bool)
        if top == "fixed":
            keep[0] = False
        if bottom == "fixed":
            keep[-1] = False
        w2 = eigh(K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], eigvals_only=True)
        f = np.sqrt(np.clip(w2, 0, None)) / (2 * math.pi)
        f = f[f > 1e-9 * max(1.0, f.max())] if top == bottom == "free" else f
        return f[:count]

    # ---------------------------------------------------------------- linear export
    def design_model(self, n_bc: int = 1) -> DirectionalModel:
        """The FEM this model is linearized on: itself for a FEM; for a hybrid, a FEM with the
        same AB and CD nodes and ``n_bc`` elements for the straight section BC (the delay line
        has no finite state; with ``n_bc = 1`` the state count equals the hybrid's)."""
        if self.kind in ("fem", "lumped"):
            return self
        iB, iC = self.node_b, self.node_c
        md = np.concatenate([self.node_md[:iB + 1],
                             np.linspace(self.node_md[iB], self.node_md[iC], n_bc + 1)[1:-1],
                             self.node_md[iC:]])
        inf = self.info
        return fem_from_nodes(self.well, self.string, self.bit, md, damping=inf["damping"],
                              rayleigh_alpha=inf["rayleigh_alpha"],
                              rayleigh_beta=inf["rayleigh_beta"], modal_ratio=inf["modal_ratio"],
                              friction=self.mu, v_eps=self.v_eps, mass=inf["mass"],
                              md_b=self.node_md[iB], md_c=self.node_md[iC],
                              name=f"{self.name} design FEM")

    def continuous_linear_model(self, top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA):
        """Continuous ``(A, B, names)`` of Eq. 4.14 with B = [0; +M^-1 B_u] (docs/seed-errata.md).

        States (seed Eq. 4.13 layout): [x_1, alpha_1, ..., x_N, alpha_N, then their velocities],
        deviations from the static hanging equilibrium. Inputs: ``slack_off_force`` (N, downward
        at the top node) and ``surface_torque`` (N m on the top node). Top drive inertia is added
        to node 1's angular DOF; no PI (the controller supplies the torque).
        """
        m = self.design_model()
        n = m.n_nodes
        M = np.zeros((2 * n, 2 * n))
        K = np.zeros((2 * n, 2 * n))
        C = np.zeros((2 * n, 2 * n))
        Ma, Mt = _tri_dense(m.Ma), _tri_dense(m.Mt)
        Mt[0, 0] += top_drive_inertia
        ia, it = np.arange(0, 2 * n, 2), np.arange(1, 2 * n, 2)
        M[np.ix_(ia, ia)] = Ma
        M[np.ix_(it, it)] = Mt
        K[np.ix_(ia, ia)] = _tri_dense(m.Ka)
        K[np.ix_(it, it)] = _tri_dense(m.Kt)
        if m.Cdense is not None:
            C[np.ix_(ia, ia)] = m.Cdense[0]
            C[np.ix_(it, it)] = m.Cdense[1]
        else:
            C[np.ix_(ia, ia)] = _tri_dense(m.Ca)
            C[np.ix_(it, it)] = _tri_dense(m.Ct)
        Minv = np.linalg.inv(M)
        A = np.block([[np.zeros((2 * n, 2 * n)), np.eye(2 * n)], [-Minv @ K, -Minv @ C]])
        Bu = np.zeros((2 * n, 2))
        Bu[0, 0] = 1.0
        Bu[1, 1] = 1.0
        B = np.vstack([np.zeros((2 * n, 2)), Minv @ Bu])
        names = ([f"x_{i + 1}" if j == 0 else f"alpha_{i + 1}" for i in range(n) for j in (0, 1)]
                 + [f"v_{i + 1}" if j == 0 else f"omega_{i + 1}" for i in range(n) for j in (0, 1)])
        return A, B, names, Minv

    def linear_model(self, dt: float, top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA):
        """Discrete linear model at step ``dt`` by exact zero-order hold (expm).

        Replaces the seed's truncated Taylor series (Eq. 4.15), which diverges with beta0 = 0.03
        (|lambda dt| up to ~78 at dt = 1e-3 on fine meshes). See :meth:`continuous_linear_model`
        for the state and input layout.

        Returns
        -------
        StateSpace
            :class:`downhole.string.zoh.StateSpace` with ``A`` (4N, 4N), ``B`` (4N, 2), the
            whole state as output (``C = I``, ``D = 0``), ``dt`` and the state names
            (``x_1, alpha_1, ..., v_1, omega_1, ...``) and input names (``slack_off_force``,
            ``surface_torque``). It unpacks as the pair ``A_d, B_d``; ``.to_control()`` gives
            python-control's ``ss`` when ``control`` is installed.
        """
        if not dt > 0:
            raise DownholeInputError(f"dt must be > 0 s, got {dt!r}")
        A, B, names, _ = self.continuous_linear_model(top_drive_inertia)
        A_d, B_d = zoh(A, B, dt)
        return StateSpace.full_state(A_d, B_d, dt, names, ("slack_off_force", "surface_torque"))

    def nodal_force_map(self, dt: float,
                        top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA) -> np.ndarray:
        """ZOH map of arbitrary held nodal forces: ``Gamma = int_0^dt e^{A s} ds [0; M^-1]``.

        A force pair ``f`` (2N,: axial force and torque per node, in the state's interleaved
        order) held over one step adds ``Gamma @ f`` to the discrete state of
        :meth:`linear_model`.

        Returns
        -------
        ndarray (4N, 2N)
        """
        if not dt > 0:
            raise DownholeInputError(f"dt must be > 0 s, got {dt!r}")
        A, _, _, Minv = self.continuous_linear_model(top_drive_inertia)
        n2 = Minv.shape[0]
        return zoh(A, np.vstack([np.zeros((n2, n2)), Minv]), dt)[1]


# ------------------------------------------------------------------------------ helpers
def _tri_dense(T):
    n = T.shape[1]
    D = np.diag(T[0].copy())
    if n > 1:
        D += np.diag(T[1, :-1], 1) + np.diag(T[1, :-1], -1)
    return D


def hanging_tension(m: DirectionalModel) -> np.ndarray:
    """Element tensions of ``m`` in the static hanging state with zero WOB, N (the normal force
    of the soft-string friction in the control-design models)."""
    u = _static_axial(m, wob=0.0)
    return -m.Ka[1, :-1] * (u[1:] - u[:-1])


def _mesh(keys, n_elements, min_per_interval=1):
    keys = np.unique(np.asarray(keys, float))
    lengths = np.diff(keys)
    total = lengths.sum()
    counts = np.maximum(min_per_interval, np.round(n_elements * lengths / total).astype(int))
    # fix rounding so that the total matches when possible
    while counts.sum() > n_elements and np.any(counts > min_per_interval):
        j = int(np.argmin(np.where(counts > min_per_interval, lengths / counts, np.inf)))
        counts[j] -= 1
    while counts.sum() < n_elements:
        j = int(np.argmax(lengths / counts))
        counts[j] += 1
    md = [keys[0]]
    for a, b, c in zip(keys[:-1], keys[1:], counts):
        md.extend(np.linspace(a, b, c + 1)[1:])
    return np.array(md)


#: Longest element of the mesh derived from the description (:func:`fem_model` and
#: :func:`~downhole.string.hybrid.hybrid_model` without element / node counts), m.
MAX_ELEMENT_LENGTH = 50.0
#: Largest change of direction along one element of the derived mesh (curved parts), rad.
MAX_ELEMENT_ANGLE = math.radians(2.0)
#: Survey stations closer than this fraction of ``max_element_length`` to a node already placed
#: are not made nodes of the derived mesh (a dense gyro survey); joints always are.
_STATION_SPACING = 0.2


def _joints(string, lo, hi, top_md):
    """Measured depths of the string's section joints strictly inside (lo, hi)."""
    return [top_md + float(b) for b in string.boundaries[1:-1] if lo < top_md + b < hi]


def _count_keys(well, string, lo, hi, top_md):
    """Node depths that a mesh of given element count keeps: lo, hi, every survey station and
    string joint in between (the seed's meshes)."""
    keys = [lo, hi] + [m for m in well.stations["md"] if lo < m < hi]
    keys += _joints(string, lo, hi, top_md)
    return np.unique(np.round(np.array(keys, float), 9))


def _station_curvature(well):
    """Survey stations (md) and the curvature (rad/m) of each interval between them."""
    md = np.asarray(well.stations["md"], float)
    return md, np.asarray(well.curvature(0.5 * (md[:-1] + md[1:])), float)


def _derived_md(well, string, lo, hi, top_md, max_element_length=MAX_ELEMENT_LENGTH,
                max_element_angle=MAX_ELEMENT_ANGLE):
    """Node depths from lo to hi derived from the description: a node at every string joint,
    at every survey station where the path changes direction (the ends of a straight run and
    the stations of curved parts; stations closer than ``_STATION_SPACING *
    max_element_length`` to a node already placed are skipped), then each interval split into
    equal elements no longer than ``max_element_length`` and turning by at most
    ``max_element_angle`` (the largest curvature over the interval)."""
    st, kappa = _station_curvature(well)
    hard = [lo, hi] + _joints(string, lo, hi, top_md)
    curved = kappa > 1e-12
    bends = [m for i, m in enumerate(st)
             if lo < m < hi and ((i > 0 and curved[i - 1]) or (i < curved.size and curved[i]))]
    keys = sorted(set(np.round(hard, 9)))
    gap = _STATION_SPACING * max_element_length
    for m in bends:
        j = int(np.searchsorted(keys, m))
        near = min(abs(m - keys[j - 1]) if j > 0 else np.inf,
                   abs(keys[j] - m) if j < len(keys) else np.inf)
        if near >= gap:
            keys.insert(j, float(m))
    md = [keys[0]]
    for a, b in itertools.pairwise(keys):
        # largest curvature of the station intervals overlapping [a, b]
        i0 = max(int(np.searchsorted(st, a, side="right")) - 1, 0)
        i1 = min(int(np.searchsorted(st, b, side="left")), kappa.size)
        k = float(np.max(kappa[i0:i1])) if i1 > i0 else 0.0
        h = max_element_length if k <= 0 else min(max_element_length, max_element_angle / k)
        n = max(1, math.ceil((b - a) / h - 1e-9))
        md.extend(np.linspace(a, b, n + 1)[1:])
    return np.array(md)


def _check_int(name, value, lo):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise DownholeInputError(f"{name} must be an integer, got {value!r}")
    if value < lo:
        raise DownholeInputError(f"{name} must be >= {lo}, got {value}")
    return int(value)


def _check_mesh_sizes(max_element_length, max_element_angle):
    h = si_or_number(max_element_length, "length", "max_element_length")
    a = si_or_number(max_element_angle, "angle", "max_element_angle")
    for name, v, hi in (("max_element_length", h, 1e4), ("max_element_angle", a, math.pi)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) \
                or not (0 < v <= hi) or not math.isfinite(v):
            raise DownholeInputError(f"{name} must be a number in (0, {hi:g}] (SI), got {v!r}")
    return float(h), float(a)


def _assemble_chain(well, string, md, top_md, mass="consistent"):
    """Element matrices of one chain with nodes at measured depths ``md``."""
    n = md.size
    L = np.diff(md)
    if np.any(L <= 0):
        raise DownholeInputError("node measured depths must increase strictly")
    mid = 0.5 * (md[:-1] + md[1:])
    s_mid = mid - top_md
    EA = string.property_at(s_mid, "area") * string.property_at(s_mid, "young_modulus")
    GJ = string.property_at(s_mid, "polar_moment") * string.property_at(s_mid, "shear_modulus")
    rA = string.property_at(s_mid, "linear_mass")
    rJ = string.property_at(s_mid, "linear_inertia")
    wb = string.buoyed_weight_per_length(s_mid)
    Ma, Mt, Ka, Kt = (np.zeros((2, n)) for _ in range(4))
    for e in range(n - 1):
        for arr, val in ((Ka, EA[e] / L[e]), (Kt, GJ[e] / L[e])):
            arr[0, e] += val
            arr[0, e + 1] += val
            arr[1, e] -= val
        for arr, val in ((Ma, rA[e] * L[e]), (Mt, rJ[e] * L[e])):
            if mass == "consistent":
                arr[0, e] += val / 3
                arr[0, e + 1] += val / 3
                arr[1, e] += val / 6
            else:
                arr[0, e] += val / 2
                arr[0, e + 1] += val / 2
    tvd = well.tvd(md)
    grav = np.zeros(n)
    dz = np.diff(tvd)
    grav[:-1] += 0.5 * wb * dz
    grav[1:] += 0.5 * wb * dz
    elem = np.zeros((n, 8))
    elem[:-1, 0] = L
    elem[:-1, 1:4] = well.curvature_vector(mid)
    elem[:-1, 4:7] = normal_weight(well.tangent(mid), wb)
    elem[:-1, 7] = 1.0
    od = string.property_at(s_mid, "outer_diameter")
    radius = np.zeros(n)
    radius[:-1] = np.maximum(radius[:-1], od / 2)
    radius[1:] = np.maximum(radius[1:], od / 2)
    return dict(Ma=Ma, Mt=Mt, Ka=Ka, Kt=Kt, grav=grav, elem=elem, radius=radius)


def _apply_stabilizers(string, md, radius, bit_md):
    for st in string.stabilizers:
        j = int(np.argmin(np.abs(md - (bit_md - st.distance_from_bit))))
        radius[j] = max(radius[j], st.outer_diameter / 2)


def _damping(Ma, Ka, Mt, Kt, damping, alpha, beta, modal_ratio):
    if damping == "rayleigh":
        return alpha * Ma + beta * Ka, alpha * Mt + beta * Kt, None
    if damping == "modal":
        from scipy.linalg import eigh

        out = []
        for M, K in ((Ma, Ka), (Mt, Kt)):
            Md, Kd = _tri_dense(M), _tri_dense(K)
            w2, phi = eigh(Kd, Md)
            w = np.sqrt(np.clip(w2, 0, None))
            C = Md @ phi @ np.diag(2 * modal_ratio * w) @ phi.T @ Md
            out.append(0.5 * (C + C.T))
        Ca = np.zeros_like(Ma)
        Ct = np.zeros_like(Mt)
        Ca[0] = np.diag(out[0])
        Ct[0] = np.diag(out[1])
        Ca[1, :-1] = np.diag(out[0], 1)
        Ct[1, :-1] = np.diag(out[1], 1)
        return Ca, Ct, np.stack(out)
    raise DownholeInputError(f"damping must be 'rayleigh' or 'modal', got {damping!r}")


def table_5_1_setup(params: DirectionalWellParams | None = None):
    """Well, string and bit of the seed's Table 5.1 (corrected, docs/seed-errata.md)."""
    from downhole.string.drillstring import DrillString

    p = params or get_preset("table_5_1").string
    well = WellPath.table_5_1(p)
    string = DrillString.uniform(well.total_depth, p.pipe, g=p.g)
    return well, string, get_preset("table_5_1").bit, p


def fem_model(well: WellPath | None = None, string: DrillString | None = None,
              bit: BitParams | None = None, *, n_elements: int | None = None,
              max_element_length: float = MAX_ELEMENT_LENGTH,
              max_element_angle: float = MAX_ELEMENT_ANGLE,
              damping: str = "rayleigh", rayleigh_alpha: float | None = None,
              rayleigh_beta: float | None = None, modal_ratio: float = 0.03,
              friction: float | None = None, v_eps: float = 1e-3, mass: str = "consistent",
              md_b: float | None = None, md_c: float | None = None,
              name: str | None = None) -> DirectionalModel:
    """Mesh a drill string in a well into axial-torsional bar elements.

    Parameters
    ----------
    well, string, bit : optional
        Default: the seed's Table 5.1 setup (:func:`table_5_1_setup`). The string hangs from
        the top with its bit at the well's total depth (string length <= well depth).
    n_elements : int, optional
        Number of elements (>= 1), spread over the survey stations and string joints (each
        interval between them gets at least one): the seed's meshes (432-state FEM:
        ``n_elements=107``, 108 nodes). Default (None): the mesh derived from the description,
        with a node at every string joint and at every survey station where the path turns, and
        elements no longer than ``max_element_length`` and turning by at most
        ``max_element_angle`` (the Table 5.1 well: 102 elements).
    max_element_length : float or quantity
        Longest element of the derived mesh, m (default 50 m).
    max_element_angle : float or quantity
        Largest change of direction along one element of the derived mesh, rad (default 2 deg).
    damping : {"rayleigh", "modal"}
        Rayleigh alpha0 M + beta0 K (Table 5.1: 0.05, 0.03) or modal (``modal_ratio`` of
        critical in every mode; dense, slower).
    rayleigh_alpha, rayleigh_beta : float, optional
        Default 0.05 1/s and 0.03 s (Table 5.1, as :class:`~downhole.system.DrillingSystem`).
    friction : float, optional
        Wellbore friction coefficient; 0 disables contact. Default: Table 5.1's 0.5 when the
        well is Table 5.1's (no ``well`` given), else 0 (as
        :class:`~downhole.system.DrillingSystem` and the scenario key ``model.friction``).
    v_eps : float
        Friction regularization velocity, m/s.
    mass : {"consistent", "lumped"}
    md_b, md_c : float, optional
        Depths reported as B and C (forces/torques there); default Table 5.1's 2000 and 3000 m.

    Returns
    -------
    DirectionalModel

    Raises
    ------
    DownholeInputError
        Too few elements (the message names the count that works), a string longer than the
        well, bad damping or mass names.

    Examples
    --------
    >>> m = fem_model(n_elements=107)
    >>> m.n_states
    432
    >>> fem_model().n_nodes          # derived: nodes at 0, 3000 m (kick-off) and the bit
    103
    """
    well0, string0, bit0, p = table_5_1_setup()
    seed_well = well is None
    well = well or well0
    string = string or (string0 if well is well0 else
                        DrillString.uniform(well.total_depth, p.pipe, g=p.g))
    bit = bit or bit0
    if n_elements is not None:
        n_elements = _check_int("n_elements", n_elements, 1)
    h, angle = _check_mesh_sizes(max_element_length, max_element_angle)
    if mass not in ("consistent", "lumped"):
        raise DownholeInputError(f"mass must be 'consistent' or 'lumped', got {mass!r}")
    if string.length > well.total_depth + 1e-6:
        raise DownholeInputError(
            f"string length {string.length:g} m exceeds the well's total depth "
            f"{well.total_depth:g} m")
    alpha = p.rayleigh_alpha if rayleigh_alpha is None else float(rayleigh_alpha)
    beta = p.rayleigh_beta if rayleigh_beta is None else float(rayleigh_beta)
    mu = (p.wellbore_friction if seed_well else 0.0) if friction is None else float(friction)
    if alpha < 0 or beta < 0 or mu < 0 or v_eps <= 0:
        raise DownholeInputError(
            f"rayleigh_alpha, rayleigh_beta, friction must be >= 0 and v_eps > 0; got "
            f"{alpha}, {beta}, {mu}, {v_eps}")
    top_md = well.total_depth - string.length
    if n_elements is None:
        md = _derived_md(well, string, top_md, well.total_depth, top_md, h, angle)
        label = f"fem {md.size - 1} elements (derived)"
    else:
        keys = _count_keys(well, string, top_md, well.total_depth, top_md)
        if n_elements < keys.size - 1:
            raise DownholeInputError(
                f"n_elements = {n_elements} is too few: the survey stations and string joints "
                f"split the string into {keys.size - 1} sections, each needs at least one "
                f"element; give n_elements >= {keys.size - 1} (scenario key "
                "model.fem.n_elements) or leave it unset for the mesh derived from the "
                f"description (nodes at every joint, elements <= {h:g} m)")
        md = _mesh(keys, n_elements)
        label = f"fem {n_elements} elements"
    md_b = p.length_ab if md_b is None else md_b
    md_c = p.length_ab + p.length_bc if md_c is None else md_c
    return fem_from_nodes(well, string, bit, md, damping=damping, rayleigh_alpha=alpha,
                          rayleigh_beta=beta, modal_ratio=modal_ratio, friction=mu, v_eps=v_eps,
                          mass=mass, md_b=md_b, md_c=md_c, name=name or label)


def chain_with_rig(chain: ChainModel, well: WellPath, string: DrillString, top_md: float,
                   string_mass: float, string_inertia: float) -> DirectionalModel:
    """A lumped chain of a described system with the rig's node on top, as a model the FEM's
    pack steps (kind ``"lumped"``): the top drive and the hook act on that node exactly as on
    a FEM's top node (:class:`_Packed`), so a command means the same actuator at every fidelity.

    Node 0 carries the string's mass and polar inertia that the chain does not (the chain's
    masses are matched to the first natural frequency with the top clamped, docs/scenarios.md),
    so the whole string's inertia turns and hoists; the top drive's inertia and the block mass
    are added at run time. The chain's top spring and damper join node 0 to the chain's first
    node; the buoyed weight is spread over the nodes by mass (the hook carries it at rest).

    Parameters
    ----------
    chain : ChainModel
        The chain (gravity pre-balanced) of :meth:`downhole.system.DrillingSystem.build`.
    well, string : WellPath, DrillString
        The description (kept on the model for reports).
    top_md : float
        Measured depth of the top of the string, m.
    string_mass, string_inertia : float
        The string's total mass (kg) and polar inertia (kg m^2).

    Returns
    -------
    DirectionalModel
    """
    n = chain.n + 1

    def field_mats(fld, total):
        mass = np.concatenate([[max(total - float(np.sum(fld.mass)), 1e-6 * total)],
                               np.asarray(fld.mass, float)])
        k_links = np.concatenate([[fld.k_top], np.asarray(fld.k_link, float)])
        c_links = np.concatenate([[fld.c_top], np.asarray(fld.c_link, float)])
        c_ground = np.concatenate([[0.0], np.asarray(fld.c_abs, float)])
        M = np.zeros((2, n))
        M[0] = mass
        K = np.zeros((2, n))
        C = np.zeros((2, n))
        C[0] = c_ground
        for i, (kl, cl) in enumerate(zip(k_links, c_links)):
            K[0, i] += kl
            K[0, i + 1] += kl
            K[1, i] = -kl
            C[0, i] += cl
            C[0, i + 1] += cl
            C[1, i] = -cl
        return M, K, C

    Ma, Ka, Ca = field_mats(chain.axial, string_mass)
    Mt, Kt, Ct = field_mats(chain.torsional, string_inertia)
    gravity = chain.weight * Ma[0] / float(np.sum(Ma[0]))
    return DirectionalModel(
        name=f"{chain.name} with the rig", kind="lumped", well=well, string=string,
        bit=chain.bit, node_md=np.linspace(top_md, well.total_depth, n), Ma=Ma, Ka=Ka, Ca=Ca,
        Mt=Mt, Kt=Kt, Ct=Ct, Cdense=None, gravity=gravity, elem=np.zeros((n, 8)),
        radius=np.zeros(n), mu=0.0, v_eps=1e-3, node_b=0, node_c=n - 1, wave=None,
        info={"chain": chain.name})


def fem_from_nodes(well, string, bit, md, *, damping="rayleigh", rayleigh_alpha=0.05,
                   rayleigh_beta=0.03, modal_ratio=0.03, friction=0.0, v_eps=1e-3,
                   mass="consistent", md_b=2000.0, md_c=3000.0, name="fem") -> DirectionalModel:
    """A FEM with nodes at the given measured depths (top of string first, bit last)."""
    md = np.asarray(md, float)
    top_md = well.total_depth - string.length
    if md.size < 2 or abs(md[0] - top_md) > 1e-6 or abs(md[-1] - well.total_depth) > 1e-6:
        raise DownholeInputError(
            f"node depths must run from the string top ({top_md:g} m) to the bit "
            f"({well.total_depth:g} m) with at least 2 nodes")
    ch = _assemble_chain(well, string, md, top_md, mass)
    _apply_stabilizers(string, md, ch["radius"], well.total_depth)
    Ca, Ct, Cd = _damping(ch["Ma"], ch["Ka"], ch["Mt"], ch["Kt"], damping, rayleigh_alpha,
                          rayleigh_beta, modal_ratio)
    nb = int(np.argmin(np.abs(md - md_b)))
    nc = int(np.argmin(np.abs(md - md_c)))
    return DirectionalModel(
        name=name, kind="fem", well=well, string=string, bit=bit,
        node_md=md, Ma=ch["Ma"], Ka=ch["Ka"], Ca=Ca, Mt=ch["Mt"], Kt=ch["Kt"], Ct=Ct, Cdense=Cd,
        gravity=ch["grav"], elem=ch["elem"], radius=ch["radius"], mu=float(friction),
        v_eps=float(v_eps), node_b=nb, node_c=nc, wave=None,
        info={"damping": damping, "rayleigh_alpha": rayleigh_alpha,
              "rayleigh_beta": rayleigh_beta, "modal_ratio": modal_ratio, "mass": mass})


# ------------------------------------------------------------------------ static state
def _solve_pinned(Kdiag, Koff, f, pin, value):
    """Solve the tridiagonal K u = f with u[pin] = value (free-free chain pinned at one node)."""
    n = Kdiag.size
    u = np.zeros(n)
    u[pin] = value
    if n == 1:
        return u
    keep = np.array([i for i in range(n) if i != pin])
    rhs = f[keep].copy()
    if pin - 1 >= 0:
        rhs[pin - 1] -= Koff[pin - 1] * value
    if pin + 1 < n:
        rhs[pin] -= Koff[pin] * value  # index shift: keep[pin] == pin + 1
    d = Kdiag[keep]
    o = np.array([Koff[keep[i]] if keep[i + 1] == keep[i] + 1 else 0.0
                  for i in range(keep.size - 1)])
    ab = np.zeros((3, keep.size))
    ab[0, 1:] = o
    ab[1] = d
    ab[2, :-1] = o
    u[keep] = solve_banded((1, 1), ab, rhs)
    return u


def _static_axial(m: DirectionalModel, wob: float) -> np.ndarray:
    """Static axial displacements (bit node at 0) with the bit carrying ``wob`` N."""
    n = m.n_nodes
    W = m.buoyed_weight
    f = m.gravity.copy()
    f[0] -= W - wob
    f[-1] -= wob
    if m.wave is None:
        return _solve_pinned(m.Ka[0], m.Ka[1], f, n - 1, 0.0)
    iB, iC = m.node_b, m.node_c
    fb0, fc0, delta = _line_preload(m, wob)
    f[iB] += fb0
    f[iC] += fc0
    u = np.zeros(n)
    u[iC:] = _solve_pinned(m.Ka[0, iC:], m.Ka[1, iC:], f[iC:], n - 1 - iC, 0.0)
    u[:iB + 1] = _solve_pinned(m.Ka[0, :iB + 1], m.Ka[1, :iB + 1], f[:iB + 1], iB,
                               u[iC] - delta)
    return u


def _line_preload(m: DirectionalModel, wob: float):
    """Static forces of the wave segment on B and C (downward) and its static elongation."""
    from downhole.sim.wave import line_preload

    wv = m.wave
    n_c = float(m.gravity[m.node_c:].sum()) - wob
    wl = wv["line_weight"]
    fb0, fc0 = line_preload(n_c, wl)
    delta = (n_c * wv["length"] + 0.5 * wl * wv["length"]) / wv["EA"]
    return fb0, fc0, delta


def _wob_depth(bit: BitParams, wob: float) -> float:
    """Depth of cut d with WOB(d, v=0, omega=0) = wob (bisection), m."""
    from downhole.bit.law import bit_forces

    if wob <= 0:
        return 0.0
    p = bit.kernel_params()
    lo, hi = 0.0, 1e-3
    while bit_forces(hi, 0.0, 0.0, p)[0] < wob:
        hi *= 2.0
        if hi > 10.0:
            raise DownholeInputError(f"initial WOB {wob:g} N cannot be carried by the bit law")
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if bit_forces(mid, 0.0, 0.0, p)[0] < wob:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------ start states
def _tri_ones(T):
    """``T @ 1`` for a tridiagonal (2, n) matrix (row 0 diagonal, row 1 off-diagonal)."""
    out = T[0].copy()
    out[:-1] += T[1, :-1]
    out[1:] += T[1, :-1]
    return out


def _directional_start(pk: _Packed, start: str, ax_cmd: float, tq_cmd: float,
                       clearance: float = 0.05):
    """Kernel state and the record of t = 0 for ``start`` under the commands
    ``(ax_cmd, tq_cmd)`` (hook load N or block velocity m/s; speed set-point rad/s or surface
    torque N m).

    ``rest`` is the static equilibrium of :meth:`_Packed.initial_state`. ``off_bottom`` and
    ``steady`` move every node at the bit velocities (v, omega): the string is stretched by
    gravity and compressed by WOB, and wound up by TOB, by the wall friction of the soft-string
    contact (normal forces from the steady tension, friction c = mu N / |(v, r omega)|,
    regularized as in the kernel) and by the damping forces C 1 v, C 1 omega (Rayleigh: the
    mass-proportional part; K 1 = 0). Accelerations are zero; the hook servo reference, the PI
    integrator angle and the soft-torque low-pass hold the steady top forces; the wave
    segment (hybrid) moves uniformly and carries the steady tension and torque at C beyond
    its static preload; its lag cascades hold their steady inputs. With a force-driven hook
    the ROP is the root of WOB(2 pi v / omega, v, omega) = buoyed weight - hook load - axial
    drag (the bit law at the hook's WOB); with a torque-driven top drive omega is the root of
    the torque balance. Returns ``(state dict, record row)``.
    """
    from scipy.optimize import brentq

    from downhole.bit.law import approx_depth_of_cut, bit_forces
    from downhole.bit.rock_surface import rock_init_helix
    from downhole.contact.softstring import contact_elements, element_normal_half
    from downhole.sim.plant import check_start
    from downhole.string.wave import initial_waves, wave_push, wave_state

    check_start(start)
    st = pk.initial_state()
    if start == "rest":
        return st, _initial_record(pk, st)
    m, td, hook = pk.model, pk.top_drive, pk.hook
    n, iB, iC = m.n_nodes, m.node_b, m.node_c
    bp = pk.bitp
    force_hook = hook.mode == "force"
    torque_td = td.mode == "torque"
    if start == "off_bottom":
        if not (isinstance(clearance, (int, float)) and math.isfinite(clearance)
                and clearance > 0):
            raise DownholeInputError(f"clearance must be a positive distance in m, got "
                                     f"{clearance!r}")
        if force_hook or torque_td:
            raise DownholeInputError(
                "start='off_bottom' needs a velocity-driven hook (Hook(mode='velocity')) and a "
                "speed-controlled top drive: off bottom nothing but drag balances a hook load "
                "or a surface torque, so the string has no steady motion to start from")
    if not torque_td and not td.ki > 0:
        raise DownholeInputError("a moving start needs the top drive's integral gain ki > 0 "
                                 "(the PI integrator holds the steady surface torque)")
    steady = start == "steady"
    W = m.buoyed_weight
    ca1 = (m.Cdense[0] @ np.ones(n)) if m.Cdense is not None else _tri_ones(m.Ca)
    ct1 = (m.Cdense[1] @ np.ones(n)) if m.Cdense is not None else _tri_ones(m.Ct)
    ce = contact_elements(m.elem) if m.mu > 0 else np.empty(0, np.int64)
    r = m.radius
    hybrid = m.wave is not None
    u = st["state"][0].copy()
    th = np.zeros(n)

    def depth(v, w):
        if pk.approx:
            return approx_depth_of_cut(v, w, bp)
        return 2.0 * math.pi * v / w

    def bit(v, w):
        if not steady:
            return 0.0, 0.0
        return bit_forces(depth(v, w), v, w, bp)

    def drags(nrm, v, w):
        c = m.mu * nrm / np.sqrt(v * v + (r * w) ** 2 + m.v_eps ** 2) if m.mu > 0 else 0.0 * nrm
        return ca1 * v + c * v, ct1 * w + c * r * r * w

    v = 0.01 if force_hook else float(ax_cmd)  # first guesses of the roots
    w = 10.0 if torque_td else float(tq_cmd)
    if steady and not torque_td and not w > 0:
        raise DownholeInputError(f"a steady drilling start needs a positive top-drive speed "
                                 f"set-point, got {w!r} rad/s")
    if steady and not force_hook and not v > 0:
        raise DownholeInputError(f"a steady drilling start needs a positive block velocity, "
                                 f"got {v!r} m/s")
    for _ in range(60):
        nrm = np.zeros(n)
        for e in ce:
            half = element_normal_half(m.elem, e, -m.Ka[1, e] * (u[e + 1] - u[e]))
            nrm[e] += half
            nrm[e + 1] += half

        def res_v(vv, ww, nrm=nrm):
            da, _ = drags(nrm, vv, ww)
            return W - da.sum() - bit(vv, ww)[0] - ax_cmd

        def res_w(ww, vv, nrm=nrm):
            _, dt_ = drags(nrm, vv, ww)
            return tq_cmd - dt_.sum() - bit(vv, ww)[1]

        def v_of(ww, v_hook=v, res_v=res_v):
            if not force_hook:
                return v_hook
            try:
                return brentq(res_v, 1e-9, 1.0, args=(ww,), xtol=1e-15)
            except ValueError:
                raise DownholeInputError(
                    f"no steady drilling state under hook_load = {ax_cmd:g} N: the weight "
                    f"left for the bit (buoyed weight {W:g} N minus hook load and drag) "
                    "gives no rate of penetration in (0, 1] m/s by the bit law; start "
                    "from 'rest' or lower the hook load") from None

        if torque_td:
            try:
                w = brentq(lambda ww, res_w=res_w, v_of=v_of: res_w(ww, v_of(ww)), 1e-2, 100.0,
                           xtol=1e-13)
            except ValueError:
                raise DownholeInputError(
                    f"no steady rotation under surface_torque = {tq_cmd:g} N m within "
                    "[0.01, 100] rad/s: the torque does not balance TOB, wall friction and "
                    "damping there") from None
        v = v_of(w)
        wob, tob = bit(v, w)
        da, dt_ = drags(nrm, v, w)
        fa = m.gravity - da
        fa[-1] -= wob
        ft = -dt_
        ft[-1] -= tob
        hl = fa.sum() + (m.wave["line_weight"] if hybrid else 0.0)
        ts = -ft.sum()
        fa[0] -= hl
        ft[0] += ts
        u_new, th = _steady_fields(m, fa, ft, iB, iC, hybrid)
        if np.max(np.abs(u_new - u)) <= 1e-12 * max(1.0, np.max(np.abs(u_new))):
            u = u_new
            break
        u = u_new
    state = np.zeros((6, n))
    state[0], state[1], state[3], state[4] = u, v, th, w
    st["state"] = state
    run = st["run"]
    run["ubit0"] = u[-1]
    if not force_hook:
        run["x_ref"] = u[0] + (pk.top.hook_load0 - hl) / hook.servo_stiffness
    if not torque_td:
        run["theta_ref"] = th[0] + ts / td.ki
    if hybrid and iB == 0:
        tq0 = ts  # the line starts at the top node (the neutral line): it carries the torque
    else:
        tq0 = m.Kt[1, 0] * (th[1] - th[0]) if n > 1 else 0.0
    run["soft_lowpass"] = tq0
    spec = RockSurfaceSpec(m.bit.n_blades)
    d0 = depth(v, w) if steady else 0.0
    if steady:
        st["surf"], st["istate"], st["rp"] = rock_init_helix(spec, u[-1], th[-1], d0)
    else:
        st["surf"], st["istate"], st["rp"] = rock_init(spec, u[-1] + clearance, th[-1])
    rec = np.zeros(len(CHANNELS))
    rec[1], rec[2], rec[3], rec[4] = v, th[-1], w, d0
    rec[5], rec[6] = bit_forces(d0, v, w, bp) if steady else (0.0, 0.0)
    rec[7], rec[8], rec[9], rec[10], rec[15] = hl, tq0, v, w, th[0]
    rec[16] = tq_cmd
    if hybrid:
        segs = m.wave["segments"]
        n_c = float(m.gravity[iC:].sum() - da[iC:].sum()) - wob  # tension at C
        t_c = float(dt_[iC:].sum()) + tob  # torque the line delivers to C
        fb0 = pk.top.fb0
        fc0 = pk.top.fc0
        n_dyn = n_c + fc0  # fc0 = -(preload tension at C)
        wa = wave_state(segs[0], pk.dt, v, n_dyn)
        wt = wave_state(segs[1], pk.dt, w, -t_c)
        a0, b0 = initial_waves(segs[0].impedance, v, n_dyn)
        a0t, b0t = initial_waves(segs[1].impedance, w, -t_c)
        wave_push(*wa, a0, b0)
        wave_push(*wt, a0t, b0t)
        st["wa"], st["wt"] = wa, wt
        lag = st["lag"]
        lag[0], lag[1], lag[2], lag[3] = b0, a0, b0t, a0t
        rec[11], rec[12], rec[13], rec[14] = fb0 + n_dyn, t_c, -fc0 + n_dyn, t_c
    else:
        ten = -m.Ka[1, :-1] * (u[1:] - u[:-1])
        tor = m.Kt[1, :-1] * (th[1:] - th[:-1])

        def at(x, i):
            if 0 < i < x.size:
                return 0.5 * (x[i - 1] + x[i])
            return x[min(max(i, 0), x.size - 1)]
        rec[11], rec[12], rec[13], rec[14] = at(ten, iB), at(tor, iB), at(ten, iC), at(tor, iC)
    return st, rec


def _steady_fields(m: DirectionalModel, fa, ft, iB, iC, hybrid):
    """Static displacements and angles (bit node at 0) under balanced nodal loads ``fa``,
    ``ft``; in a hybrid the wave segment carries the tension and torque at C to B."""
    n = m.n_nodes
    if not hybrid:
        return (_solve_pinned(m.Ka[0], m.Ka[1], fa, n - 1, 0.0),
                _solve_pinned(m.Kt[0], m.Kt[1], ft, n - 1, 0.0))
    wv = m.wave
    n_c = float(fa[iC:].sum())  # tension at C (the loads below C hang from it)
    t_c = -float(ft[iC:].sum())  # torque at C
    fa, ft = fa.copy(), ft.copy()
    fa[iC] -= n_c
    ft[iC] += t_c
    fa[iB] += n_c + wv["line_weight"]
    ft[iB] -= t_c
    u, th = np.zeros(n), np.zeros(n)
    u[iC:] = _solve_pinned(m.Ka[0, iC:], m.Ka[1, iC:], fa[iC:], n - 1 - iC, 0.0)
    th[iC:] = _solve_pinned(m.Kt[0, iC:], m.Kt[1, iC:], ft[iC:], n - 1 - iC, 0.0)
    seg_t = wv["segments"][1]
    L = wv["length"]
    delta = (n_c * L + 0.5 * wv["line_weight"] * L) / wv["EA"]
    twist = t_c * seg_t.delay / seg_t.impedance  # T L / GJ with GJ = Z L / tau
    u[:iB + 1] = _solve_pinned(m.Ka[0, :iB + 1], m.Ka[1, :iB + 1], fa[:iB + 1], iB,
                               u[iC] - delta)
    th[:iB + 1] = _solve_pinned(m.Kt[0, :iB + 1], m.Kt[1, :iB + 1], ft[:iB + 1], iB,
                                th[iC] + twist)
    return u, th


# ------------------------------------------------------------------------ kernel packing
def _copy_wave(w):
    """A fresh copy of a wave segment's compiled state ``(hist, pos, wp)`` (wp is immutable)."""
    hist, pos, wp = w
    return hist.copy(), pos.copy(), wp


class _Packed:
    """Kernel arrays for one (model, dt, top drive, hook, depth-of-cut) combination."""

    def __init__(self, model: DirectionalModel, dt: float, top_drive: TopDrive, hook: Hook,
                 depth_of_cut: str):
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise DownholeInputError(f"dt must be a positive number of seconds, got {dt!r}")
        if depth_of_cut not in ("delayed", "approximate"):
            raise DownholeInputError(
                f"depth_of_cut must be 'delayed' or 'approximate', got {depth_of_cut!r}")
        self.model, self.dt, self.top_drive, self.hook = model, float(dt), top_drive, hook
        self.approx = depth_of_cut == "approximate"
        n = model.n_nodes
        Ma, Mt = model.Ma.copy(), model.Mt.copy()
        Ma[0, 0] += hook.block_mass
        Mt[0, 0] += top_drive.inertia
        h = 0.5 * dt
        La = Ma + h * model.Ca + h * h * model.Ka
        Lt = Mt + h * model.Ct + h * h * model.Kt
        self.mats = np.vstack([Ma[0], Ma[1], model.Ka[0], model.Ka[1], La[0], La[1],
                               Mt[0], Mt[1], model.Kt[0], model.Kt[1], Lt[0], Lt[1],
                               model.Ca[0], model.Ca[1], model.Ct[0], model.Ct[1],
                               np.zeros(n), np.zeros(n)])
        if model.Cdense is not None:
            Ld = np.zeros((2, n, n))
            Ld[0] = _tri_dense(Ma) + h * model.Cdense[0] + h * h * _tri_dense(model.Ka)
            Ld[1] = _tri_dense(Mt) + h * model.Cdense[1] + h * h * _tri_dense(model.Kt)
            self.mats[4] = np.diagonal(Ld[0])
            self.mats[10] = np.diagonal(Ld[1])
            self.Ldense = Ld
        else:
            self.Ldense = np.zeros((2, 1, 1))
        self.node = np.column_stack([model.gravity, model.radius])
        self.elem = np.ascontiguousarray(model.elem)
        self.bitp = model.bit.kernel_params()
        self.hook_load0 = model.buoyed_weight - hook.wob
        wv = model.wave
        fb0 = fc0 = 0.0
        if wv is not None:
            fb0, fc0, _ = _line_preload(model, hook.wob)
            for seg in wv["segments"]:
                seg.delay_steps(dt)  # raises if the line is shorter than one step
        top = KernelParams(
            velocity_hook=hook.mode != "force", hook_k=float(hook.servo_stiffness),
            hook_c=float(hook.servo_damping), hook_load0=float(self.hook_load0),
            torque_mode=top_drive.mode == "torque", kp=float(top_drive.kp),
            ki=float(top_drive.ki),
            soft_gain=float(top_drive.soft_gain) if top_drive.mode == "soft_torque" else 0.0,
            soft_tau=float(top_drive.soft_tau), mu=float(model.mu), v_eps=float(model.v_eps),
            approx_doc=self.approx, node_b=int(model.node_b), node_c=int(model.node_c),
            hybrid=wv is not None, dense=model.Cdense is not None,
            n_lags_a=int(wv["n_lags"]) if wv is not None else 0,
            lag_tau_a=float(wv["lag_tau"][0]) if wv is not None else 0.0,
            n_lags_t=int(wv["n_lags"]) if wv is not None else 0,
            lag_tau_t=float(wv["lag_tau"][1]) if wv is not None else 0.0,
            fb0=float(fb0), fc0=float(fc0), rig_node=0, bit_node=n - 1)
        self.top = top
        self._template = None
        self.record0 = None
        self._no_ref = np.zeros((1, 4))

    observation_names = (*CHANNELS, "time", "last_node_axial_velocity",
                         "last_node_angular_velocity")

    @property
    def command_names(self) -> tuple[str, str]:
        ax = "hook_load" if self.hook.mode == "force" else "top_drive_axial_velocity"
        tq = ("surface_torque" if self.top_drive.mode == "torque"
              else "top_drive_angular_velocity")
        return ax, tq

    def default_command(self) -> dict:
        """The hook's static hook load (buoyed weight - ``hook.wob``) or block velocity, and
        the top drive's ``speed``."""
        ax = self.hook_load0 if self.hook.mode == "force" else self.hook.velocity
        return dict(zip(self.command_names, (float(ax), float(self.top_drive.speed))))

    def start(self, start: str, command, clearance: float = 0.05):
        """Kernel state and the record of t = 0 for ``start`` under ``command`` (see
        :func:`_directional_start`)."""
        return _directional_start(self, start, float(command[0]), float(command[1]), clearance)

    def initial_state(self):
        """Static equilibrium: bit on bottom carrying the hook's WOB, everything at rest
        (fresh arrays; the equilibrium itself is computed once per packing)."""
        if self._template is None:
            self._template = self._initial_state()
        t = self._template
        return dict(state=t["state"].copy(), run=t["run"].copy(), surf=t["surf"].copy(),
                    istate=t["istate"].copy(), rp=t["rp"],
                    wa=_copy_wave(t["wa"]), wt=_copy_wave(t["wt"]),
                    lag=t["lag"].copy())

    def _initial_state(self):
        from downhole.sim.wave import wave_state

        model = self.model
        n = model.n_nodes
        state = np.zeros((6, n))
        state[0] = _static_axial(model, self.hook.wob)
        run = new_run_state(x_ref=state[0, 0],  # hook servo reference position
                            ubit0=state[0, -1])
        spec = RockSurfaceSpec(model.bit.n_blades)
        d0 = 0.0 if self.approx else _wob_depth(model.bit, self.hook.wob)
        surf, istate, rp = rock_init(spec, state[0, -1] - d0 / model.bit.n_blades, 0.0)
        if model.wave is not None:
            wa = wave_state(model.wave["segments"][0], self.dt)
            wt = wave_state(model.wave["segments"][1], self.dt)
            from downhole.sim.wave import wave_push

            wave_push(*wa, 0.0, 0.0)
            wave_push(*wt, 0.0, 0.0)
        else:
            wa = (np.zeros((2, 4)), np.zeros(1, np.int64),
                  WaveParams(impedance=0.0, delay_steps=1.0, cap=4, a_init=0.0, b_init=0.0))
            wt = wa
        lag = np.zeros((4, max(1, self.top.n_lags_a)))
        return dict(state=state, run=run, surf=surf, istate=istate, rp=rp, wa=wa, wt=wt,
                    lag=lag)

    def run(self, st, rows, rec, rec_every, rec_start=0):
        """Advance ``len(rows) - 1`` steps, step k holding ``rows[k + 1]``; ``(status, rows
        written)``."""
        return self._kernel(st, np.ascontiguousarray(rows[1:, :2]), rec, rec_every, rec_start)

    def _kernel(self, st, cmd, rec, rec_every, rec_start):
        if st.get("work") is None:
            st["work"] = new_kernel_work(self.model.n_nodes, self.top.dense)
        return run_kernel(KernelModel(self.mats, self.Ldense, self.elem, self.node, self.top,
                                      self.bitp), kernel_state(st), cmd, self._no_ref,
                          cmd.shape[0], self.dt, rec, rec_every, rec_start)

    def step(self, st, command, rec):
        """One step holding ``command``; ``(status, rows)``."""
        cmd = st.setdefault("cmd", np.zeros((1, 2)))
        cmd[0] = command[:2]
        return self._kernel(st, cmd, rec, 1, 0)

    # ---- the run protocol of downhole.sim.simulate
    kind = "directional"
    n_cmd = 2

    def rows(self, inputs, t) -> np.ndarray:
        """The commands at the step boundaries ``t`` from ``inputs``, a mapping of command name
        (:attr:`command_names`) to signal; missing ones are the hook's and top drive's own."""
        names = self.command_names
        inputs = {} if inputs is None else inputs
        if not isinstance(inputs, dict):
            raise DownholeInputError(f"a {self.model.kind} model's inputs are a mapping of "
                                     f"{names} to signals, got {type(inputs).__name__}")
        extra = set(inputs) - set(names)
        if extra:
            raise DownholeInputError(f"inputs: {sorted(extra)} is not a command of this "
                                     f"{self.model.kind} model with a {self.hook.mode} hook and "
                                     f"a {self.top_drive.mode} top drive; it takes {names}")
        out = np.empty((len(t), 2))
        dflt = self.default_command()
        out[:, 0] = (_signal(inputs[names[0]], t, names[0]) if names[0] in inputs
                     else dflt[names[0]])
        out[:, 1] = (_signal(inputs[names[1]], t, names[1]) if names[1] in inputs
                     else self.top_drive.command(t))
        return out

    def still_rows(self, t) -> np.ndarray:
        """Rows holding :meth:`default_command` (a closed loop's start)."""
        c = self.default_command()
        out = np.empty((len(t), 2))
        out[:, 0], out[:, 1] = c[self.command_names[0]], c[self.command_names[1]]
        return out

    def begin(self, start: str, rows, clearance: float):
        """Kernel state and the record of t = 0 under the commands of the first step."""
        r = rows[1] if len(rows) > 1 else rows[0]
        return _directional_start(self, start, float(r[0]), float(r[1]), clearance)

    def first_command(self, rows) -> np.ndarray:
        """The command held before a controller's first output."""
        return np.array(rows[0, :2], float)

    def command(self, out, held, who: str) -> None:
        """A controller's output into ``held`` (by :attr:`command_names`)."""
        from downhole.sim.lumped_model import _named_command

        _named_command(self.command_names, out, held, who)

    def command_channels(self, hist) -> dict:
        """Closed-loop channels of the held commands (none: the record has the top's)."""
        return {}

    def channels(self, rec, rows, idx):
        """The Result's channels, units and attributes."""
        m = self.model
        ch = {name: rec[:, i].copy() for i, name in enumerate(CHANNELS)}
        if rows is not None:
            ch["reference_angular_velocity"][0] = rows[0, 1]
        if self.top_drive.mode == "torque":
            del ch["reference_angular_velocity"]
        return ch, dict(EXTRA_UNITS), {
            "model_kind": m.kind, "n_states": m.n_states, "top_drive_mode": self.top_drive.mode,
            "hook_mode": self.hook.mode, "node_md": m.node_md.tolist()}


_PACKS: weakref.WeakKeyDictionary[DirectionalModel, dict] = weakref.WeakKeyDictionary()


def _packed(model: DirectionalModel, dt: float, top_drive: TopDrive, hook: Hook,
            depth_of_cut: str) -> _Packed:
    """The kernel arrays of a (model, dt, top drive, hook, depth of cut) combination, built
    once and reused (the model and the settings are immutable; run state is always fresh)."""
    try:
        key = (float(dt), top_drive, hook, depth_of_cut)
        hash(key)
    except TypeError:
        return _Packed(model, dt, top_drive, hook, depth_of_cut)
    per_model = _PACKS.setdefault(model, {})
    pk = per_model.get(key)
    if pk is None:
        if len(per_model) > 4:
            per_model.clear()
        pk = per_model[key] = _Packed(model, dt, top_drive, hook, depth_of_cut)
    return pk


def _signal(sig, t, name):
    """A command signal sampled at the step times ``t``."""
    from downhole.sim.inputs import sample_signal

    if callable(sig):
        try:
            return sample_signal(sig, t, name)
        except (TypeError, ValueError, DownholeInputError):
            return np.array([float(sig(tt)) for tt in t])  # a scalar-only callable
    return sample_signal(sig, t, name)


def _initial_record(pk: _Packed, st) -> np.ndarray:
    """Channels at t = 0 (a zero-length run of the kernel records nothing, so compute here)."""
    if pk.record0 is None:
        pk.record0 = _initial_record_compute(pk, st)
    return pk.record0.copy()


def _initial_record_compute(pk: _Packed, st) -> np.ndarray:
    m = pk.model
    u = st["state"][0]
    out = np.zeros(len(CHANNELS))
    d0 = 0.0 if pk.approx else _wob_depth(m.bit, pk.hook.wob)
    from downhole.bit.law import bit_forces

    w, tq = bit_forces(d0, 0.0, 0.0, pk.bitp)
    out[4], out[5], out[6] = d0, w, tq
    out[7] = pk.hook_load0
    ten = -m.Ka[1, :-1] * (u[1:] - u[:-1])
    if m.wave is None:
        def at(i):
            if 0 < i < ten.size:
                return 0.5 * (ten[i - 1] + ten[i])
            return ten[min(max(i, 0), ten.size - 1)]
        out[11] = at(m.node_b)
        out[13] = at(m.node_c)
    else:
        fb0, fc0, _ = _line_preload(m, pk.hook.wob)
        out[11], out[13] = fb0, -fc0
    return out


class DirectionalPlant(Plant):
    """Step-by-step plant over the one kernel (the :class:`~downhole.sim.plant.Plant`
    contract): a directional FEM or hybrid model, a lumped chain model or the neutral model.

    Directional models. Commands (named, all held over the step): ``hook_load`` (N; or
    ``top_drive_axial_velocity`` m/s with a velocity hook) and ``top_drive_angular_velocity``
    (speed set-point, rad/s; PI/soft-torque top drive) or ``surface_torque`` (N m;
    ``TopDrive(mode="torque")``). Observations: the standard channels (``bit_axial_velocity``,
    ``bit_angular_velocity``, ``wob``, ``tob``, ``hook_load``, ``surface_torque``,
    ``top_drive_*_velocity``, ...), forces at B and C, ``time`` and, for hardware-in-the-loop,
    ``last_node_axial_velocity`` and ``last_node_angular_velocity`` (the string's last node,
    where a rig replaces the bit). ``reset(start=...)``: ``"rest"`` (static equilibrium, bit
    carrying ``hook.wob``), ``"off_bottom"`` or ``"steady"`` (see :func:`downhole.sim.simulate`).

    Lumped models (:class:`~downhole.sim.lumped_model.ChainModel`). Commands:
    ``top_drive_axial_velocity`` (m/s) and ``top_drive_angular_velocity`` (rad/s) for a
    velocity-driven top (``mode="velocity"``), or ``hook_load`` (N) and ``surface_torque``
    (N m) when ``mode="force"``. Observations: the standard Result channel names and ``time``.
    ``integrator``: ``"euler"`` (the seed's Chapter 2 scheme) or ``"newmark"``.

    The neutral model (:class:`~downhole.string.neutral.NeutralModel`). Commands:
    ``top_drive_axial_velocity`` relative to the hanging equilibrium (U_A - M_S g / alpha_A,
    m/s) and ``top_drive_angular_velocity`` (U_T, rad/s), the dampers' commanded velocities;
    observations as for a lumped model.

    Parameters
    ----------
    model : DirectionalModel, ChainModel or NeutralModel
    dt : float
        Step, s (default the model's ``default_dt``: 1e-3 for a directional model, the
        real-time testbed's; 5e-4 for a lumped one, the seed's; 1e-4 for the neutral one).
    top_drive, hook : optional
        The rig (directional models; see :meth:`DirectionalModel.run_pack`).
    depth_of_cut : {"delayed", "approximate"}
    mode : {"velocity", "force"}
        Lumped models: how the top is driven.
    integrator : {"euler", "newmark"}
        Lumped models (directional ones always step with Newmark).

    Examples
    --------
    >>> from downhole.sim.lumped_model import lumped_model
    >>> plant = DirectionalPlant(lumped_model("table_2_1"), dt=5e-4)
    >>> obs = plant.reset(start="steady", set_point={"top_drive_axial_velocity": 0.01,
    ...                                              "top_drive_angular_velocity": 20.0})
    >>> round(obs["bit_angular_velocity"], 6)
    20.0
    """

    def __init__(self, model: DirectionalModel | ChainModel | NeutralModel,
                 dt: float | None = None, *,
                 top_drive: TopDrive | None = None, hook: Hook | None = None,
                 depth_of_cut: str = "delayed", mode: str = "velocity",
                 integrator: str | None = None):
        if isinstance(model, (ChainModel, NeutralModel)) and (top_drive is not None
                                                             or hook is not None):
            model = under_rig(model, integrator)  # the chain / the line under the rig's node
        neutral = isinstance(model, NeutralModel)
        lumped = isinstance(model, ChainModel) or neutral
        if dt is None:
            kind = getattr(model, "kind", None)
            dt = (1e-4 if neutral or kind == "neutral" else
                  5e-4 if lumped or kind == "lumped" else 1e-3)
        dt = si_or_number(dt, "time", "dt")  # "0.5 ms" or a pint quantity
        self.model = model
        self._neutral = neutral
        if neutral:
            if top_drive is not None or hook is not None or mode != "velocity":
                raise DownholeInputError("the neutral model's top is its damper pair (alpha_A, "
                                         "alpha_T) driven by velocity commands: no top_drive, "
                                         "hook or mode")
            if integrator not in (None, "newmark"):
                raise DownholeInputError(f"the neutral model steps its bit with Newmark, got "
                                         f"integrator={integrator!r}")
            self._pk = model.kernel_pack(dt, depth_of_cut)
            self.mode = mode
            integrator = "newmark"
        elif lumped:
            if top_drive is not None or hook is not None:
                raise DownholeInputError("a lumped model's top is its top spring and damper: "
                                         "give mode='velocity' or 'force', no top_drive/hook")
            self._pk = model.kernel_pack(dt, mode, depth_of_cut, integrator or "euler")
            self.mode = mode
        else:
            if integrator not in (None, "newmark"):
                raise DownholeInputError(f"a directional model steps with Newmark, got "
                                         f"integrator={integrator!r}")
            self.top_drive = top_drive or TopDrive()
            self.hook = hook or Hook()
            self._pk = _Packed(model, dt, self.top_drive, self.hook, depth_of_cut)
        self.depth_of_cut = depth_of_cut
        self.integrator = integrator or ("euler" if lumped else "newmark")
        self._lumped = lumped
        self.observation_names = self._pk.observation_names
        self.dt = float(dt)
        self._rec = np.zeros((1, len(CHANNELS)))
        self.reset()

    @property
    def command_names(self) -> tuple[str, str]:
        return self._pk.command_names

    def default_command(self) -> dict:
        """Directional: the hook's static hook load (buoyed weight - ``hook.wob``) or block
        velocity, and the top drive's ``speed``. Lumped: at rest (velocity mode) or the hook
        carrying the whole string, no torque (force mode)."""
        return self._pk.default_command()

    def _observe(self, rec) -> dict:
        if self._lumped:
            obs = dict(zip(self.observation_names[1:], rec[:11].tolist()))
            obs["time"] = self._k * self.dt
            return obs
        obs = dict(zip(CHANNELS, rec.tolist()))
        obs["time"] = self.time
        s = self._st["state"]
        obs["last_node_axial_velocity"] = float(s[1, -1])
        obs["last_node_angular_velocity"] = float(s[4, -1])
        return obs

    def _reset(self, start: str, set_point: dict, clearance: float = 0.05) -> dict:
        cmd = np.array([float(set_point[k]) for k in self.command_names])
        self._k = 0
        if self._neutral:
            self._st, rec0 = self._pk.start(start, cmd, clearance)
        elif self._lumped:
            row = self._pk.step_reference({"run": new_run_state()}, cmd)[0]
            self._st, rec0 = self._pk.start(start, row, clearance=clearance)
        else:
            self._st, rec0 = self._pk.start(start, cmd, clearance)
        self._obs = self._observe(rec0)
        return dict(self._obs)

    @property
    def time(self) -> float:
        return float(self._st["run"]["time"][0])

    def node_fields(self) -> dict[str, np.ndarray]:
        """The nodal state now (copies, one value per node of ``model.node_md``, or per DOF of
        a lumped chain): ``axial_position`` (m, along measured depth, downwards),
        ``axial_velocity`` (m/s), ``axial_acceleration`` (m/s^2), ``angle`` (rad),
        ``angular_velocity`` (rad/s), ``angular_acceleration`` (rad/s^2). State feedback and
        observers read these."""
        s = self._st["state"]
        return {"axial_position": s[0].copy(), "axial_velocity": s[1].copy(),
                "axial_acceleration": s[2].copy(), "angle": s[3].copy(),
                "angular_velocity": s[4].copy(), "angular_acceleration": s[5].copy()}

    def _step(self, command: np.ndarray) -> dict:
        """Hold ``command`` over one step and advance ``dt``; returns the new observation."""
        status, _ = self._pk.step(self._st, command, self._rec)
        if status != 0:
            raise SimulationDiverged(self.time, "bit_angular_velocity")
        self._k += 1
        self._obs = self._observe(self._rec[0])
        return dict(self._obs)
