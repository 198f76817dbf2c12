"""Parameters of the bit/rock interaction laws (Detournay: seed Eqs. 2.2-2.8, 4.9-4.12, 4.16;
Aarsnes & van de Wouw 2019: contact force independent of the depth of cut).

The law is chosen by name (``BitParams.law``); :data:`LAW_IDS` gives the integer id that the
compiled dispatch in :mod:`downhole.bit.law` branches on. :meth:`BitParams.kernel_params` builds,
by name, the one structure the compiled kernels take: :class:`BitKernelParams`, a
``typing.NamedTuple`` of floats that numba passes by value (in registers) and reads by attribute
(``p.epsilon``). Kernels hand it through to the law unopened.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

from pydantic import BaseModel, ConfigDict, Field

from downhole.params.quantity import Q

__all__ = ["LAW_IDS", "BitKernelParams", "BitParams"]

#: Integer id of each bit law in the compiled dispatch (:mod:`downhole.bit.law`).
LAW_IDS = {"detournay": 0, "aarsnes": 1}


class BitKernelParams(NamedTuple):
    """The bit law's parameters as the compiled kernels take them (SI units, all float64).

    Built only by :meth:`BitParams.kernel_params`. The fields are those of :class:`BitParams`
    except three that the compiled dispatch needs as numbers: ``wear_flat_continuous`` (1.0 for
    ``wear_flat_law="continuous"``, 0.0 for ``"printed"``), ``friction_stribeck`` (1.0 for
    ``friction_law="stribeck"``, 0.0 for ``"constant"``) and ``law`` (the id of
    :data:`LAW_IDS`); ``contact_force`` is resolved (sigma l a when ``BitParams.contact_force``
    is None) and ``n_blades`` is a float.
    """

    epsilon: float
    sigma: float
    zeta: float
    radius: float
    n_blades: float
    wear_length: float
    d_star: float
    contact_stiffness: float
    mu_c: float
    mu_s: float
    gamma: float
    gamma_b: float
    v_f: float
    mu_gamma: float
    a1: float
    b1: float
    a2: float
    b2: float
    wear_flat_continuous: float
    friction_stribeck: float
    omega_reg: float
    omega_floor: float
    law: float
    contact_force: float
    contact_depth: float


class BitParams(BaseModel):
    """PDC bit and rock parameters, SI units.

    Attributes
    ----------
    epsilon : float
        Intrinsic specific energy of the rock, Pa (seed symbol epsilon).
    sigma : float
        Maximum contact pressure at the wear flats, Pa.
    zeta : float
        Cutter face inclination number, - (0.5-0.8).
    radius : float
        Bit radius a (R_b), m.
    n_blades : int
        Number of blades n.
    wear_length : float
        Total wear-flat length l, m.
    d_star : float
        Depth of cut (all blades) above which wear-flat contact saturates, m.
    contact_stiffness : float
        K_c of the printed Ch. 2 piecewise law (only used with ``wear_flat_law="printed"``), N/m.
    mu_c, mu_s : float
        Coulomb and static friction coefficients of the Stribeck law (Eq. 2.8).
    gamma : float
        Bit geometry parameter (gamma / delta of the seed), -.
    gamma_b, v_f : float
        Stribeck decay parameters of Eq. 2.8, applied to |omega| (docs/seed-errata.md).
    mu_gamma : float
        Constant product mu*gamma used with ``friction_law="constant"`` (Tables 2.1/5.1: 0.7).
    a1, b1, a2, b2 : float
        Regularisation constants of f(v) = 1/(1+exp(a1 v + b1)) and g(omega) = tanh(a2 omega + b2).
    wear_flat_law : {"continuous", "printed"}
        ``continuous`` (default): W_f = sigma l a min(d/d*, 1) H(d) f(v). ``printed``: the seed's
        piecewise form with K_c below d* (jumps at d* with Table 2.1).
    friction_law : {"stribeck", "constant"}
        Wear-flat friction coefficient: Stribeck in |omega| (default) or the constant ``mu_gamma``.
    omega_reg : float
        Width of the ramp that switches the cutting torque off for omega <= 0, rad/s.
    omega_floor : float
        Floor omega* of the approximated depth of cut d = 2 pi v / max(omega, omega*) (Eq. 4.16), rad/s.
    law : {"detournay", "aarsnes"}
        Bit/rock law. ``detournay`` (default): the corrected seed law above. ``aarsnes``: Aarsnes &
        van de Wouw (2019), cutting as Detournay, wear-flat contact force ``contact_force``
        independent of the depth of cut once the bit is in contact, friction torque
        gamma mu a W_f g(omega) (see ``docs/bit-laws.md``).
    contact_force : float or None
        Aarsnes law only: contact force W_f of the wear flats, N. ``None``: sigma l a.
    contact_depth : float
        Aarsnes law only: depth of cut over which the contact force rises linearly from 0 to its
        full value (a regularised Heaviside step at first contact), m.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    epsilon: Q["pressure"] = Field(77e6, gt=0)
    sigma: Q["pressure"] = Field(45e6, ge=0)
    zeta: float = Field(0.64, gt=0, le=2.0)
    radius: Q["length"] = Field(0.15, gt=0)
    n_blades: int = Field(5, ge=1, le=20)
    wear_length: Q["length"] = Field(3.6e-3, ge=0)
    d_star: Q["length"] = Field(1.2e-3, gt=0)
    contact_stiffness: Q["stiffness"] = Field(37.5e6, ge=0)
    mu_c: float = Field(0.5, ge=0)
    mu_s: float = Field(0.8, ge=0)
    gamma: float = Field(1.0, gt=0)
    gamma_b: float = Field(0.9, ge=0)
    v_f: float = Field(1.0, gt=0)
    mu_gamma: float = Field(0.7, ge=0)
    a1: float = -20e4
    b1: float = -1.5
    a2: float = 70e3
    b2: float = 2.0
    wear_flat_law: Literal["continuous", "printed"] = "continuous"
    friction_law: Literal["stribeck", "constant"] = "stribeck"
    omega_reg: Q["angular_velocity"] = Field(0.01, gt=0)
    omega_floor: Q["angular_velocity"] = Field(0.5, gt=0)
    law: Literal[tuple(LAW_IDS)] = "detournay"  # type: ignore[valid-type]
    contact_force: Q["force"] | None = Field(None, ge=0)
    contact_depth: Q["length"] = Field(1e-5, gt=0)

    def kernel_params(self) -> BitKernelParams:
        """The parameters as the compiled kernels take them (:class:`BitKernelParams`)."""
        contact = (self.sigma * self.wear_length * self.radius
                   if self.contact_force is None else self.contact_force)
        return BitKernelParams(
            epsilon=float(self.epsilon), sigma=float(self.sigma), zeta=float(self.zeta),
            radius=float(self.radius), n_blades=float(self.n_blades),
            wear_length=float(self.wear_length), d_star=float(self.d_star),
            contact_stiffness=float(self.contact_stiffness), mu_c=float(self.mu_c),
            mu_s=float(self.mu_s), gamma=float(self.gamma), gamma_b=float(self.gamma_b),
            v_f=float(self.v_f), mu_gamma=float(self.mu_gamma), a1=float(self.a1),
            b1=float(self.b1), a2=float(self.a2), b2=float(self.b2),
            wear_flat_continuous=1.0 if self.wear_flat_law == "continuous" else 0.0,
            friction_stribeck=1.0 if self.friction_law == "stribeck" else 0.0,
            omega_reg=float(self.omega_reg), omega_floor=float(self.omega_floor),
            law=float(LAW_IDS[self.law]), contact_force=float(contact),
            contact_depth=float(self.contact_depth))
