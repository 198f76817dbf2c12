"""Discrete-time control-affine models ``z_{k+1} = f(z_k) + g u_k`` in non-dimensional units.

This module holds :class:`ControlAffineModel`, the interface between the drill-string models
(lumped, FEM, hybrid) and the model-based controller designs that need a control-affine
description, first of all the dual-heuristic-programming (DHP / SNAC) trainer of seed Ch. 4
(:mod:`downhole.control.dhp`).

The contract (what a model exporter must provide)
-------------------------------------------------
Seed Eqs. 4.14-4.20 and 4.25 give the discrete model in physical units

    z_{k+1} = A_d z_k + B_d u_k + h(z_k)                                   (physical)

with ``A_d`` the zero-order-hold (``expm``) discretization of the linear mechanics, ``B_d`` the
input map of the two surface inputs and ``h`` the discrete effect over one step of every force
that is not linear in the state (bit/rock law with the approximated depth of cut and its floor
omega* of Eq. 4.16, wellbore contact friction, ...). States are *deviations from the static
hanging equilibrium* (gravity pre-balanced, docs/seed-errata.md), so ``z = 0, u = 0`` is a rest
point off bottom. The non-dimensionalization of Eqs. 4.17-4.19 uses the diagonal state scale
``P = diag(state_scale)`` and (a downhole addition, see below) an input scale
``U = diag(input_scale)``:

    zbar = P^-1 z,   ubar = U^-1 u,
    zbar_{k+1} = f(zbar_k) + g ubar_k,
    f(zbar) = Abar zbar + hbar(zbar),   Abar = P^-1 A_d P,   g = P^-1 B_d U,
    hbar(zbar) = P^-1 h(P zbar).

Everything stored on a :class:`ControlAffineModel` is in these non-dimensional units:
``linear`` is ``Abar`` (n, n), ``g`` is constant (n, m) and ``nonlinear`` is ``hbar``, a callable
that maps a batch of states ``(N, n)`` to ``(N, n)`` (vectorized; compile its inner loop with
numba where it matters: the DHP trainer evaluates it on N_S samples at every one of the 40 000
steps of a 40 s horizon at dt = 1e-3). Use :meth:`ControlAffineModel.from_physical` to build one
from physical ``A_d``, ``B_d`` and a physical ``h``; it does the scaling.

The seed keeps the inputs in physical units (N and N m), which is why its Table 4.1 has
R = 1e-11; with that, the DHP iteration's contraction factor is ~1e9 (docs/seed-errata.md). An
explicit ``input_scale`` (e.g. 1e5 N and 1e4 N m) makes R of order one. ``input_scale = 1``
reproduces the seed's convention.

The Jacobian ``A_k = d zbar_{k+1} / d zbar_k`` used in the co-state recursion (Eq. 4.31) is by
default the seed's choice ``P^-1 A_d P`` = ``linear`` (``jacobian(kind="seed")``);
``kind="exact"`` adds the derivative of ``hbar`` (user-supplied ``nonlinear_jacobian`` or central
differences).

State bookkeeping: every state has a *kind* (``axial_position``, ``angular_position``,
``axial_velocity``, ``angular_velocity`` or ``other``) and a *node* index (0 = top drive / top
node, increasing down the string; -1 for states that belong to no node). The bit node is the
largest node index unless ``bit_node`` says otherwise. The reference transform of Eqs.
4.21-4.23 and the penalty layout of Eq. 4.45 are built from these tags, so an exporter must
set them. Inputs are named from the vocabulary :data:`INPUT_NAMES`.

Exporter checklist (FEM / hybrid / lumped):

1. ``A_d``, ``B_d`` physical, discrete, deviation states from hanging equilibrium, time step ``dt``.
2. ``h(z_batch)`` physical increments over one step from the nonlinear forces, vectorized over
   the batch (``(N, n) -> (N, n)``); bit law through :func:`downhole.bit.bit_forces` with
   :func:`downhole.bit.approx_depth_of_cut` (floor ``BitParams.omega_floor``). Preferably in the
   structured form ``h = forces(z) @ force_map.T`` (``force_map`` (n, n_f): the ZOH map of each
   nonlinear force, ``forces``: the n_f forces for a batch): the DHP fast path then fits n_f force
   columns instead of n state rows.
3. ``state_scale`` (Eq. 4.17: a typical maximum of |z_i|, positive), ``input_scale``.
4. ``state_names``, ``state_kinds``, ``state_nodes``, ``input_names``.
5. Optional: ``outputs(z, u) -> dict`` of physical channels (``wob``, ``tob``, ``hook_load``, ...)
   for Results of closed-loop runs on the design model; ``bit`` (the :class:`~downhole.params.BitParams`, so that closed-loop runs on the
   design model can report WOB/TOB/depth of cut), ``hanging_hook_load`` (N, to report the hook
   load), ``input_limits`` (physical, (m, 2)), ``nonlinear_rows`` (the rows where ``hbar`` can be
   non-zero: the DHP fast path fits only those), ``node_depths`` (measured depth of each node, m).

Examples
--------
A double integrator (position, velocity) with force input, dt = 0.1 s, scaled by 2 m, 1 m/s, 5 N:

>>> import numpy as np
>>> A = np.array([[1.0, 0.1], [0.0, 1.0]]); B = np.array([[0.005], [0.1]])
>>> m = ControlAffineModel.from_physical(
...     A, B, state_scale=[2.0, 1.0], input_scale=[5.0], dt=0.1,
...     state_names=["x", "v"], state_kinds=["axial_position", "axial_velocity"],
...     state_nodes=[0, 0], input_names=["slack_off_force"])
>>> m.step(np.array([0.5, 0.0]), np.array([1.0])).round(4).tolist()
[0.5125, 0.5]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from downhole.errors import DownholeInputError
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

__all__ = [
    "INPUT_NAMES",
    "INPUT_UNITS",
    "STATE_KINDS",
    "ControlAffineModel",
    "from_directional",
    "scale_from_trajectory",
]

#: Allowed state kinds.
STATE_KINDS = ("axial_position", "angular_position", "axial_velocity", "angular_velocity", "other")

#: Input names and their physical meaning (units in :data:`INPUT_UNITS`).
#: ``slack_off_force``: axial force applied at the top, positive downward, relative to the hanging
#: equilibrium (hook load = hanging hook load - slack_off_force). ``surface_torque``: top-drive
#: torque on the string. ``top_drive_axial_displacement`` / ``top_drive_angle``: prescribed top
#: displacement from the hanging position (the inputs u1, u2 of the lumped Eq. 2.1).
INPUT_NAMES = ("slack_off_force", "surface_torque", "top_drive_axial_displacement",
               "top_drive_angle")
INPUT_UNITS = {"slack_off_force": "N", "surface_torque": "N*m",
               "top_drive_axial_displacement": "m", "top_drive_angle": "rad"}

_KIND_UNITS = {"axial_position": "m", "angular_position": "rad", "axial_velocity": "m/s",
               "angular_velocity": "rad/s", "other": ""}


def _vec(name, value, n, positive=False):
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise DownholeInputError(f"{name} must have shape ({n},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DownholeInputError(f"{name} must be finite, got {arr}")
    if positive and np.any(arr <= 0):
        bad = int(np.argmax(arr <= 0))
        raise DownholeInputError(f"{name} must be positive; entry {bad} is {arr[bad]!r}")
    return arr


class ControlAffineModel:
    """Non-dimensional discrete control-affine model ``zbar+ = Abar zbar + hbar(zbar) + g ubar``.

    Immutable description (arrays are stored read-only). See the module docstring for the
    contract; most users call :meth:`from_physical`.

    Parameters
    ----------
    linear : array_like, shape (n, n)
        ``Abar = P^-1 A_d P``, the linear part of ``f`` and the seed's Jacobian (Eq. 4.19).
    g : array_like, shape (n, m)
        Constant input map ``P^-1 B_d U``.
    nonlinear : callable, optional
        ``hbar(zbar_batch) -> (N, n)`` for ``zbar_batch`` of shape ``(N, n)``: non-dimensional
        increment over one step of the nonlinear forces. ``None``: the model is linear.
    state_scale : array_like, shape (n,)
        ``P`` of Eq. 4.17 (physical units of each state per non-dimensional unit), positive.
    input_scale : array_like, shape (m,)
        ``U`` (physical units of each input per non-dimensional unit), positive.
    dt : float
        Time step, s.
    state_names, input_names : sequence of str
        Names (``input_names`` from :data:`INPUT_NAMES`, or any names for non-drilling models
        when ``strict_inputs=False``).
    state_kinds : sequence of str, optional
        One of :data:`STATE_KINDS` per state; default all ``"other"``.
    state_nodes : sequence of int, optional
        Node index per state (0 = top), -1 for none; default -1.
    bit_node : int, optional
        Node index of the bit; default the largest node index.
    nonlinear_jacobian : callable, optional
        ``d hbar / d zbar`` for a batch: ``(N, n) -> (N, n, n)``.
    nonlinear_rows : array_like of int, optional
        Rows of ``hbar`` that can be non-zero (default: all rows if ``nonlinear`` is given).
    force_map, forces : optional
        Structured form of ``hbar`` (alternative to ``nonlinear``): ``force_map`` (n, n_f) and
        ``forces(zbar_batch) -> (N, n_f)`` with ``hbar(zbar) = forces(zbar) @ force_map.T``
        (e.g. the ZOH input map of the bit force, bit torque and contact forces, non-dimensional).
        The DHP fast path then fits only the n_f force columns.
    outputs : callable, optional
        ``outputs(z, u) -> dict`` of extra physical channels (e.g. ``wob``, ``tob``,
        ``depth_of_cut``, ``hook_load``, ``surface_torque``) from a physical state trajectory
        ``z`` (T, n) and input trajectory ``u`` (T, m); used when closed-loop runs on the design
        model are turned into a :class:`~downhole.sim.result.Result`.
    input_limits : array_like, shape (m, 2), optional
        Physical lower/upper input bounds.
    bit : BitParams, optional
        Bit parameters used by ``nonlinear`` (for reporting WOB/TOB in closed-loop runs).
    hanging_hook_load : float, optional
        Hook load in the hanging equilibrium, N (for the ``hook_load`` channel).
    node_depths : array_like, optional
        Measured depth of each node, m.
    name : str
        Label (e.g. ``"fem table_5_1 24 states"``).
    metadata : dict, optional
        JSON-able extra information.
    strict_inputs : bool
        Require ``input_names`` from :data:`INPUT_NAMES` (default True).

    Raises
    ------
    DownholeInputError
        Shapes, kinds, names or scales that do not fit together.
    """

    def __init__(self, linear, g, nonlinear: Callable | None = None, *, state_scale,
                 input_scale, dt: float, state_names: Sequence[str],
                 input_names: Sequence[str], state_kinds: Sequence[str] | None = None,
                 state_nodes: Sequence[int] | None = None, bit_node: int | None = None,
                 nonlinear_jacobian: Callable | None = None, nonlinear_rows=None,
                 input_limits=None, bit=None, hanging_hook_load: float = 0.0,
                 node_depths=None, name: str = "", metadata: dict | None = None,
                 strict_inputs: bool = True, force_map=None, forces: Callable | None = None,
                 outputs: Callable | None = None):
        A = np.array(linear, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise DownholeInputError(f"linear must be a square (n, n) matrix, got shape {A.shape}")
        n = A.shape[0]
        G = np.array(g, dtype=float)
        if G.ndim == 1:
            G = G.reshape(n, 1) if G.shape[0] == n else G
        if G.ndim != 2 or G.shape[0] != n or G.shape[1] == 0:
            raise DownholeInputError(f"g must have shape ({n}, m) to match linear ({n}, {n}), "
                                     f"got {G.shape}")
        m = G.shape[1]
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(G))):
            raise DownholeInputError("linear and g must be finite")
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise DownholeInputError(f"dt must be a positive number of seconds, got {dt!r}")
        if nonlinear is not None and not callable(nonlinear):
            raise DownholeInputError(f"nonlinear must be callable or None, got {type(nonlinear)}")
        if (force_map is None) != (forces is None):
            raise DownholeInputError("force_map and forces must be given together")
        if force_map is not None:
            if nonlinear is not None:
                raise DownholeInputError("give either nonlinear or (force_map, forces), not both")
            fm = np.array(force_map, dtype=float)
            if fm.ndim != 2 or fm.shape[0] != n:
                raise DownholeInputError(f"force_map must have shape ({n}, n_f), got {fm.shape}")
            if not callable(forces):
                raise DownholeInputError("forces must be callable")
            fm.setflags(write=False)
            self.force_map = fm
            self.forces = forces

            def nonlinear(zb, _f=forces, _m=fm):
                return np.asarray(_f(zb), dtype=float) @ _m.T

            if nonlinear_rows is None:
                nonlinear_rows = np.nonzero(np.any(fm != 0.0, axis=1))[0]
        else:
            self.force_map = None
            self.forces = None
        self.outputs = outputs
        self._A = A
        self._g = G
        self._h = nonlinear
        self._hjac = nonlinear_jacobian
        self.dt = float(dt)
        self._P = _vec("state_scale", state_scale, n, positive=True)
        self._U = _vec("input_scale", input_scale, m, positive=True)
        names = tuple(str(s) for s in state_names)
        if len(names) != n:
            raise DownholeInputError(f"state_names has {len(names)} names, the model has {n} states")
        if len(set(names)) != n:
            raise DownholeInputError(f"state_names must be unique, got {names}")
        self.state_names = names
        inames = tuple(str(s) for s in input_names)
        if len(inames) != m:
            raise DownholeInputError(f"input_names has {len(inames)} names, g has {m} columns")
        if strict_inputs:
            for s in inames:
                if s not in INPUT_NAMES:
                    raise DownholeInputError(f"input name {s!r} is not one of {INPUT_NAMES} "
                                             "(pass strict_inputs=False for other models)")
        self.input_names = inames
        kinds = tuple(state_kinds) if state_kinds is not None else ("other",) * n
        if len(kinds) != n:
            raise DownholeInputError(f"state_kinds has {len(kinds)} entries, expected {n}")
        for i, k in enumerate(kinds):
            if k not in STATE_KINDS:
                raise DownholeInputError(f"state_kinds[{i}] = {k!r} is not one of {STATE_KINDS}")
        self.state_kinds = kinds
        nodes = np.asarray(state_nodes if state_nodes is not None else [-1] * n, dtype=int)
        if nodes.shape != (n,):
            raise DownholeInputError(f"state_nodes must have {n} entries, got {nodes.shape}")
        self.state_nodes = tuple(int(v) for v in nodes)
        if bit_node is None:
            bit_node = int(nodes.max()) if nodes.size and nodes.max() >= 0 else -1
        self.bit_node = int(bit_node)
        if nonlinear_rows is None:
            rows = np.arange(n) if nonlinear is not None else np.zeros(0, dtype=int)
        else:
            rows = np.unique(np.asarray(nonlinear_rows, dtype=int))
            if rows.size and (rows.min() < 0 or rows.max() >= n):
                raise DownholeInputError(f"nonlinear_rows must lie in 0..{n - 1}, got {rows}")
        self.nonlinear_rows = rows
        if input_limits is not None:
            lim = np.array(input_limits, dtype=float)
            if lim.shape != (m, 2) or np.any(lim[:, 0] >= lim[:, 1]):
                raise DownholeInputError(f"input_limits must be (m, 2) = ({m}, 2) with "
                                         f"lower < upper, got {lim.tolist()}")
            self.input_limits = lim
        else:
            self.input_limits = None
        self.bit = bit
        self.hanging_hook_load = float(hanging_hook_load)
        self.node_depths = None if node_depths is None else np.asarray(node_depths, float)
        self.name = name
        self.metadata = dict(metadata or {})
        for arr in (self._A, self._g, self._P, self._U, self.nonlinear_rows):
            arr.setflags(write=False)
        if self.input_limits is not None:
            self.input_limits.setflags(write=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_physical(cls, A_d, B_d, *, state_scale, input_scale, dt: float,
                      nonlinear_physical: Callable | None = None, **kwargs
                      ) -> ControlAffineModel:
        """Build from physical ``A_d`` (n, n), ``B_d`` (n, m) and ``h`` (Eqs. 4.17-4.19).

        Parameters
        ----------
        A_d, B_d : array_like
            Discrete linear model in physical units (deviation states from hanging).
        state_scale, input_scale : array_like
            ``P`` and ``U`` diagonals, physical units per non-dimensional unit.
        dt : float
            Time step, s.
        nonlinear_physical : callable, optional
            ``h(z_batch) -> (N, n)`` in physical units; wrapped as ``P^-1 h(P zbar)``.
            Alternatively pass ``force_map`` (physical, (n, n_f): increment per unit force) and
            ``forces`` (a callable of the *non-dimensional* batch returning physical forces);
            the map is scaled by ``P^-1`` here.
        **kwargs
            Passed to the constructor (names, kinds, nodes, limits, ...).

        Returns
        -------
        ControlAffineModel
            The non-dimensional model.

        Raises
        ------
        DownholeInputError
            Shapes that do not fit, non-positive or non-finite scales, or any check of the
            constructor.
        """
        A_d = np.asarray(A_d, dtype=float)
        B_d = np.asarray(B_d, dtype=float)
        if A_d.ndim != 2 or A_d.shape[0] != A_d.shape[1]:
            raise DownholeInputError(f"A_d must be square, got shape {A_d.shape}")
        n = A_d.shape[0]
        if B_d.ndim == 1:
            B_d = B_d.reshape(n, 1)
        if B_d.ndim != 2 or B_d.shape[0] != n:
            raise DownholeInputError(f"B_d must have shape ({n}, m), got {B_d.shape}")
        P = _vec("state_scale", state_scale, n, positive=True)
        U = _vec("input_scale", input_scale, B_d.shape[1], positive=True)
        Abar = A_d * P[None, :] / P[:, None]
        gbar = B_d * U[None, :] / P[:, None]
        hbar = None
        if "force_map" in kwargs and kwargs["force_map"] is not None:
            fm = np.asarray(kwargs["force_map"], dtype=float)
            kwargs["force_map"] = fm / P[:, None]
        if nonlinear_physical is not None:
            Pc = P.copy()

            def hbar(zbar, _h=nonlinear_physical, _P=Pc):
                return _h(zbar * _P) / _P

        return cls(Abar, gbar, hbar, state_scale=P, input_scale=U, dt=dt, **kwargs)

    # ------------------------------------------------------------------ sizes and scaling
    @property
    def n_states(self) -> int:
        return self._A.shape[0]

    @property
    def n_inputs(self) -> int:
        return self._g.shape[1]

    @property
    def linear(self) -> np.ndarray:
        """``Abar = P^-1 A_d P`` (n, n), read-only."""
        return self._A

    @property
    def g(self) -> np.ndarray:
        """Constant input map ``P^-1 B_d U`` (n, m), read-only."""
        return self._g

    @property
    def state_scale(self) -> np.ndarray:
        return self._P

    @property
    def input_scale(self) -> np.ndarray:
        return self._U

    @property
    def is_linear(self) -> bool:
        return self._h is None

    @property
    def A_d(self) -> np.ndarray:
        """Physical discrete state matrix ``P Abar P^-1``."""
        return self._A * self._P[:, None] / self._P[None, :]

    @property
    def B_d(self) -> np.ndarray:
        """Physical discrete input matrix ``P g U^-1``."""
        return self._g * self._P[:, None] / self._U[None, :]

    def to_nondim_state(self, z):
        """Non-dimensional state(s) ``zbar = P^-1 z = z / state_scale`` of ``z`` (shape (..., n),
        each entry in the unit of its kind: m, rad, m/s, rad/s)."""
        return np.asarray(z, float) / self._P

    def to_physical_state(self, zbar):
        """Physical state(s) ``z = P zbar = zbar * state_scale`` (m, rad, m/s, rad/s) of ``zbar``
        (shape (..., n))."""
        return np.asarray(zbar, float) * self._P

    def to_nondim_input(self, u):
        """Non-dimensional input(s) ``ubar = U^-1 u = u / input_scale`` of ``u`` (shape (..., m), in
        the units of :data:`INPUT_UNITS`: N, N m, m, rad)."""
        return np.asarray(u, float) / self._U

    def to_physical_input(self, ubar):
        """Physical input(s) ``u = U ubar = ubar * input_scale`` (units of :data:`INPUT_UNITS`) of
        ``ubar`` (shape (..., m))."""
        return np.asarray(ubar, float) * self._U

    # ------------------------------------------------------------------ dynamics
    def nonlinear(self, zbar) -> np.ndarray:
        """``hbar(zbar)`` for a state (n,) or batch (N, n); zeros for a linear model.

        Parameters
        ----------
        zbar : array_like, shape (n,) or (N, n)
            Non-dimensional state or batch of states.

        Returns
        -------
        ndarray, shape (n,) or (N, n)
            Non-dimensional increment of the nonlinear forces over one step.

        Raises
        ------
        DownholeInputError
            If ``zbar`` does not have ``n_states`` columns, or the model's ``nonlinear`` callable
            returns an array of another shape.
        """
        z = np.asarray(zbar, dtype=float)
        single = z.ndim == 1
        zb = z[None, :] if single else z
        if zb.ndim != 2 or zb.shape[1] != self.n_states:
            raise DownholeInputError(f"state batch must have shape (N, {self.n_states}), "
                                     f"got {z.shape}")
        if self._h is None:
            out = np.zeros_like(zb)
        else:
            out = np.asarray(self._h(zb), dtype=float)
            if out.shape != zb.shape:
                raise DownholeInputError(f"nonlinear returned shape {out.shape}, expected "
                                         f"{zb.shape}")
        return out[0] if single else out

    def f(self, zbar) -> np.ndarray:
        """Drift ``f(zbar) = Abar zbar + hbar(zbar)`` for a state (n,) or a batch (N, n).

        Parameters
        ----------
        zbar : array_like, shape (n,) or (N, n)
            Non-dimensional state or batch of states.

        Returns
        -------
        ndarray, shape (n,) or (N, n)
            Non-dimensional drift.
        """
        z = np.asarray(zbar, dtype=float)
        lin = z @ self._A.T
        if self._h is None:
            return lin
        return lin + self.nonlinear(z)

    def step(self, zbar, ubar) -> np.ndarray:
        """``zbar_{k+1} = f(zbar_k) + g ubar_k`` (single state or batch with matching inputs).

        Parameters
        ----------
        zbar : array_like, shape (n,) or (N, n)
            Non-dimensional state(s) at step k.
        ubar : array_like, shape (m,) or (N, m)
            Non-dimensional input(s) at step k.

        Returns
        -------
        ndarray, shape (n,) or (N, n)
            Non-dimensional state(s) at step k + 1.
        """
        return self.f(zbar) + np.asarray(ubar, dtype=float) @ self._g.T

    def jacobian(self, zbar=None, kind: str = "seed") -> np.ndarray:
        """Jacobian ``d zbar_{k+1} / d zbar_k``.

        ``kind="seed"``: ``P^-1 A_d P`` (constant, Eq. 4.31's approximation; ``zbar`` ignored).
        ``kind="exact"``: adds ``d hbar/d zbar`` at ``zbar`` (a state (n,) -> (n, n), or a batch
        (N, n) -> (N, n, n)) from ``nonlinear_jacobian`` or central differences.

        Parameters
        ----------
        zbar : array_like, shape (n,) or (N, n), optional
            Non-dimensional state or batch; required for ``kind="exact"``.
        kind : {"seed", "exact"}
            Which Jacobian (default ``"seed"``).

        Returns
        -------
        ndarray, shape (n, n) or (N, n, n)
            The non-dimensional Jacobian (the read-only ``linear`` matrix for ``"seed"``).

        Raises
        ------
        DownholeInputError
            An unknown ``kind``, or ``kind="exact"`` without ``zbar``.
        """
        if kind == "seed":
            return self._A
        if kind != "exact":
            raise DownholeInputError(f"jacobian kind must be 'seed' or 'exact', got {kind!r}")
        if zbar is None:
            raise DownholeInputError("jacobian(kind='exact') needs the state zbar")
        z = np.asarray(zbar, dtype=float)
        single = z.ndim == 1
        zb = z[None, :] if single else z
        if self._h is None:
            J = np.broadcast_to(self._A, (zb.shape[0],) + self._A.shape).copy()
        elif self._hjac is not None:
            J = self._A[None] + np.asarray(self._hjac(zb), dtype=float)
        else:
            n = self.n_states
            J = np.broadcast_to(self._A, (zb.shape[0], n, n)).copy()
            for j in range(n):
                h = 1e-6 * max(1.0, float(np.max(np.abs(zb[:, j]))))
                zp = zb.copy()
                zm = zb.copy()
                zp[:, j] += h
                zm[:, j] -= h
                J[:, :, j] += (self.nonlinear(zp) - self.nonlinear(zm)) / (2 * h)
        return J[0] if single else J

    # ------------------------------------------------------------------ bookkeeping
    def indices(self, kind: str, node: int | None = None) -> np.ndarray:
        """State indices of ``kind`` (optionally only at ``node``; ``node="bit"`` allowed).

        Parameters
        ----------
        kind : str
            One of :data:`STATE_KINDS`.
        node : int or "bit", optional
            Node index (0 = top), or ``"bit"`` for :attr:`bit_node`; None for all nodes.

        Returns
        -------
        ndarray of int
            Matching state indices, ascending (possibly empty).

        Raises
        ------
        DownholeInputError
            If ``kind`` is not one of :data:`STATE_KINDS`.
        """
        if kind not in STATE_KINDS:
            raise DownholeInputError(f"kind must be one of {STATE_KINDS}, got {kind!r}")
        if node == "bit":
            node = self.bit_node
        return np.array([i for i, (k, nd) in enumerate(zip(self.state_kinds, self.state_nodes))
                         if k == kind and (node is None or nd == node)], dtype=int)

    def index(self, kind: str, node) -> int:
        """The single state index of ``kind`` at ``node`` (int or ``"bit"``).

        Parameters
        ----------
        kind : str
            One of :data:`STATE_KINDS`.
        node : int or "bit"
            Node index (0 = top) or ``"bit"``.

        Returns
        -------
        int
            The state index.

        Raises
        ------
        DownholeInputError
            If ``kind`` is unknown or the model has not exactly one such state at ``node``.
        """
        idx = self.indices(kind, node)
        if idx.size != 1:
            raise DownholeInputError(f"model {self.name!r} has {idx.size} states of kind "
                                     f"{kind!r} at node {node!r}, expected exactly one")
        return int(idx[0])

    @property
    def nodes(self) -> list[int]:
        return sorted({nd for nd in self.state_nodes if nd >= 0})

    def state_units(self) -> tuple[str, ...]:
        """Physical unit of each state (from its kind)."""
        return tuple(_KIND_UNITS[k] for k in self.state_kinds)

    def describe(self) -> dict:
        """JSON-able summary (sizes, names, kinds, scales, dt) for saved controllers."""
        return {"name": self.name, "n_states": self.n_states, "n_inputs": self.n_inputs,
                "dt": self.dt, "state_names": list(self.state_names),
                "state_kinds": list(self.state_kinds), "state_nodes": list(self.state_nodes),
                "bit_node": self.bit_node, "input_names": list(self.input_names),
                "state_scale": self._P.tolist(), "input_scale": self._U.tolist(),
                "hanging_hook_load": self.hanging_hook_load,
                "input_limits": None if self.input_limits is None
                else self.input_limits.tolist(), "metadata": self.metadata}

    def __repr__(self) -> str:
        kind = "linear" if self.is_linear else "nonlinear"
        return (f"ControlAffineModel({self.name!r}, {kind}, n={self.n_states}, "
                f"m={self.n_inputs}, dt={self.dt:g})")


def scale_from_trajectory(z, floor=None) -> np.ndarray:
    """Eq. 4.17's scale: the maximum |z_i| over a physical trajectory ``z`` (T, n).

    Parameters
    ----------
    z : array_like, shape (T, n)
        Physical state trajectory (each state in the unit of its kind: m, rad, m/s, rad/s).
    floor : float or array_like of shape (n,), optional
        Lower bound of each scale, in the same units; keeps states that stay near zero from
        getting a tiny scale.

    Returns
    -------
    ndarray, shape (n,)
        Positive state scale ``P`` (physical units per non-dimensional unit).

    Raises
    ------
    DownholeInputError
        If ``z`` is not two-dimensional, or some scale is zero (a state identically zero and no
        positive ``floor``).
    """
    z = np.asarray(z, dtype=float)
    if z.ndim != 2:
        raise DownholeInputError(f"z must be a (T, n) trajectory, got shape {z.shape}")
    s = np.max(np.abs(z), axis=0)
    if floor is not None:
        s = np.maximum(s, np.broadcast_to(np.asarray(floor, float), s.shape))
    if np.any(s <= 0):
        raise DownholeInputError("some states are identically zero; pass a positive floor")
    return s


def directional_state_layout(n: int, state_scale=None):
    """State kinds and node indices of a directional model's ``[positions; velocities]`` state
    (axial and angular interleaved per node), and the default non-dimensional state scale
    (0.05 m, 30 rad, 0.02 m/s, 20 rad/s) unless ``state_scale`` is given."""
    kinds, nodes = [], []
    for blk in ("position", "velocity"):
        for i in range(n):
            kinds += [f"axial_{blk}", f"angular_{blk}"]
            nodes += [i, i]
    if state_scale is None:
        base = {"axial_position": 0.05, "angular_position": 30.0, "axial_velocity": 0.02,
                "angular_velocity": 20.0}
        state_scale = np.array([base[k] for k in kinds])
    return kinds, nodes, state_scale


def from_directional(model, dt: float = 1e-3, *, state_scale=None, input_scale=(1e5, 1e4),
                     top_drive_inertia: float = DEFAULT_TOP_DRIVE_INERTIA,
                     friction: bool = True, v_eps_design: float = 0.05) -> ControlAffineModel:
    """Non-dimensional control-affine model of Eqs. 4.17-4.19, 4.25 for the DHP design.

    ``z_{k+1} = A_d z_k + B_d u_k + h(z_k)`` with h the ZOH effect over one step of the bit law
    (approximated depth of cut with the floor omega* of Eq. 4.16) and, with ``friction``, of
    the wellbore friction (normal force from the hanging tension; regularization
    ``v_eps_design`` m/s so the design model stays smooth). States are deviations from the
    static hanging equilibrium (bit on bottom with zero WOB).

    Parameters
    ----------
    model : downhole.string.fem.DirectionalModel
        The FEM (or hybrid: its ``design_model()`` is used).
    dt : float
        Step, s.
    state_scale : array_like, optional
        ``P`` of Eq. 4.17; default: 0.05 m, 30 rad, 0.02 m/s, 20 rad/s per kind.
    input_scale : (float, float)
        Input scale (N, N m).
    top_drive_inertia : float
        Top-drive inertia on the top node, kg m^2.
    friction : bool
        Include the wellbore friction in h.
    v_eps_design : float
        Friction regularization velocity of the design model, m/s.

    Returns
    -------
    ControlAffineModel

    Raises
    ------
    DownholeInputError
        If ``model`` has no ``design_model()`` (not a DirectionalModel), or a scale of the
        wrong shape or sign.
    """
    from downhole.bit.law import approx_depth_of_cut, bit_forces
    from downhole.contact.softstring import nodal_friction_forces
    from downhole.string.fem import hanging_tension

    if not callable(getattr(model, "design_model", None)):
        raise DownholeInputError("from_directional needs a DirectionalModel (fem_model / "
                                 f"hybrid_model), got {type(model).__name__}")
    m = model.design_model()
    n = m.n_nodes
    A_d, B_d = model.linear_model(dt, top_drive_inertia)
    A, _, names, _ = model.continuous_linear_model(top_drive_inertia)
    ns = A.shape[0]
    Gam = model.nodal_force_map(dt, top_drive_inertia)
    bitp = m.bit.kernel_params()
    ib = n - 1
    # hanging tension per element (zero WOB) for the friction normal force
    tension = hanging_tension(m)
    elem = m.elem
    radius = m.radius
    mu = m.mu if friction else 0.0

    def h(zb, _G=Gam):
        N = zb.shape[0]
        F = np.zeros((N, 2 * n))
        va = zb[:, 2 * n + 2 * ib]
        vt = zb[:, 2 * n + 2 * ib + 1]
        for j in range(N):
            d = approx_depth_of_cut(va[j], vt[j], bitp)
            w, t = bit_forces(d, va[j], vt[j], bitp)
            F[j, 2 * ib] -= w
            F[j, 2 * ib + 1] -= t
        if mu > 0:
            xa = zb[:, 0:2 * n:2]
            T = tension[None, :] - m.Ka[1, None, :n - 1] * (xa[:, 1:] - xa[:, :-1])
            fa, ft = nodal_friction_forces(T, elem, radius, mu, zb[:, 2 * n:4 * n:2],
                                           zb[:, 2 * n + 1:4 * n:2], v_eps_design)
            F[:, 0:2 * n:2] += fa
            F[:, 1:2 * n:2] += ft
        return F @ _G.T

    kinds, nodes, state_scale = directional_state_layout(n, state_scale)
    rows = np.arange(ns)
    return ControlAffineModel.from_physical(
        A_d, B_d, state_scale=state_scale, input_scale=input_scale, dt=dt,
        nonlinear_physical=h, state_names=names, state_kinds=kinds, state_nodes=nodes,
        input_names=["slack_off_force", "surface_torque"], bit=m.bit,
        hanging_hook_load=m.buoyed_weight, node_depths=m.node_md, nonlinear_rows=rows,
        name=f"{model.name} ({m.n_states} states)",
        metadata={"model": model.name, "kind": model.kind})
