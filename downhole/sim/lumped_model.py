"""Lumped drill strings as chains: the 4th-order (Eq. 2.1) and 12th-order (Eqs. 2.26-2.31) models.

A :class:`ChainModel` is the mechanics core's lumped configuration: per field (axial, torsional)
a chain of DOFs with diagonal mass, springs and dampers between neighbours (tridiagonal K and C),
absolute dampers to ground, and a coupling of DOF 0 to the top drive (a spring/damper to the
commanded displacement, or an applied hook load/torque). The bit acts on the last DOF. Positions
are deviations from the static hanging equilibrium (gravity pre-balanced), unless the parameters
ask for the printed, unbalanced form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from downhole.errors import DownholeInputError
from downhole.params import BitParams, LumpedParams, get_preset

__all__ = ["ChainField", "ChainModel", "lumped_model"]


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
    """

    name: str
    axial: ChainField
    torsional: ChainField
    bit: BitParams
    weight: float
    params: LumpedParams = field(repr=False)

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

    def packed(self):
        """Arrays for the compiled kernel: (mass, k_link, c_link, c_abs, k_top, c_top, gravity),
        each with a leading field axis of size 2 (links padded to n)."""
        n = self.n
        out = []
        for attr in ("mass", "k_link", "c_link", "c_abs", "gravity"):
            arr = np.zeros((2, n))
            for i, f in enumerate((self.axial, self.torsional)):
                vals = np.asarray(getattr(f, attr), float)
                arr[i, : len(vals)] = vals
            out.append(arr)
        mass, k_link, c_link, c_abs, gravity = out
        k_top = np.array([self.axial.k_top, self.torsional.k_top])
        c_top = np.array([self.axial.c_top, self.torsional.c_top])
        return mass, k_link, c_link, c_abs, k_top, c_top, gravity


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
