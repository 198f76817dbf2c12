"""Named parameter presets: the seed's Tables 2.1, 3.1, 5.1 (as corrected) and a plausible lumped set."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import BaseModel

from downhole.params.bit import BitParams
from downhole.params.lumped import LumpedParams
from downhole.params.strings import DirectionalWellParams, NeutralStringParams, PipeSection

__all__ = ["PRESETS", "Preset", "get_preset"]


@dataclass(frozen=True)
class Preset:
    """A named pair of string and bit parameters.

    ``kind`` tells which model family the string parameters belong to: ``"lumped"`` (Ch. 2),
    ``"neutral"`` (Ch. 3) or ``"directional"`` (Ch. 4/5).

    Attributes
    ----------
    name : str
        Preset name (a key of :data:`PRESETS`).
    kind : {"lumped", "neutral", "directional"}
        Model family.
    description : str
        One line.
    string : pydantic.BaseModel
        The string parameters (:class:`LumpedParams`, :class:`NeutralStringParams` or
        :class:`DirectionalWellParams`).
    bit : BitParams
        The bit.
    """

    name: str
    kind: str
    description: str
    string: BaseModel
    bit: BitParams


def _plausible_lumped() -> LumpedParams:
    # 2500 m of 5" drill pipe (OD 127 mm, ID 108.6 mm) over 200 m of 6 3/4" collars
    # (OD 171 mm, ID 71.4 mm), steel. Equivalent mass = collars + 1/3 pipe; stiffness of the pipe;
    # 5 % damping ratio in both fields.
    rho, e_mod, g_mod = 7850.0, 2.1e11, 8.1e10
    pipe = PipeSection(outer_diameter=0.127, inner_diameter=0.1086, young_modulus=e_mod,
                       shear_modulus=g_mod, density=rho)
    collar = PipeSection(outer_diameter=0.171, inner_diameter=0.0714, young_modulus=e_mod,
                         shear_modulus=g_mod, density=rho)
    lp, lc = 2500.0, 200.0
    mass = rho * (collar.area * lc + pipe.area * lp / 3.0)
    inertia = rho * (collar.polar_moment * lc + pipe.polar_moment * lp / 3.0)
    ka = e_mod * pipe.area / lp
    kt = g_mod * pipe.polar_moment / lp
    zeta = 0.05
    return LumpedParams(
        mass=mass, inertia=inertia, axial_stiffness=ka, torsional_stiffness=kt,
        axial_damping=2 * zeta * math.sqrt(ka * mass),
        torsional_damping=2 * zeta * math.sqrt(kt * inertia),
    )


PRESETS: dict[str, Preset] = {}


def _add(p: Preset) -> None:
    PRESETS[p.name] = p


_add(Preset(
    name="table_2_1", kind="lumped",
    description="Seed Table 2.1 (4th-order lumped model, Ch. 2), gravity pre-balanced. "
                "M = 787 t is the seed's value (implausibly heavy) and is kept for reproduction.",
    string=LumpedParams(mass=787215.0, inertia=2863.0, axial_stiffness=3.53e5,
                        axial_damping=3.44e4, torsional_stiffness=685.2,
                        torsional_damping=416.29),
    bit=BitParams(epsilon=77e6, sigma=45e6, zeta=0.64, radius=0.15, n_blades=5,
                  wear_length=3.6e-3, d_star=1.2e-3, contact_stiffness=37.5e6, mu_c=0.5, mu_s=0.8,
                  gamma=1.0, gamma_b=0.9, v_f=1.0, mu_gamma=0.7),
))
_add(Preset(
    name="plausible_lumped", kind="lumped",
    description="Physically plausible 4th-order lumped string: 2500 m of 5\" pipe over 200 m of "
                "6 3/4\" collars (M = 52 t, I = 207 kg m^2), 5 % damping, Table 2.1 bit.",
    string=_plausible_lumped(),
    bit=BitParams(epsilon=77e6, sigma=45e6, zeta=0.64, radius=0.15, n_blades=5,
                  wear_length=3.6e-3, d_star=1.2e-3),
))
_add(Preset(
    name="table_3_1", kind="neutral",
    description="Seed Table 3.1 (neutral-type distributed model, Ch. 3), corrected: J is the "
                "polar moment 1.9085e-5 m^4, G in Pa, friction mu*gamma = 0.7.",
    string=NeutralStringParams(),
    bit=BitParams(epsilon=45e6, sigma=45e6, zeta=0.8, radius=0.15, n_blades=5,
                  wear_length=1.2e-3, d_star=1.2e-3, gamma=1.0, friction_law="constant",
                  mu_gamma=0.7),
))
_add(Preset(
    name="table_5_1", kind="directional",
    description="Seed Table 5.1 (directional FEM / hybrid model, Ch. 4-5), corrected: "
                "J = 1.909e-5 m^4; top drive J_td = 500 kg m^2, PI Kp = 1e4, Ki = 2e3.",
    string=DirectionalWellParams(),
    bit=BitParams(epsilon=45e6, sigma=45e6, zeta=0.64, radius=0.22, n_blades=5,
                  wear_length=3.6e-3, d_star=1.2e-3, friction_law="constant", mu_gamma=0.7),
))


def get_preset(name: str) -> Preset:
    """Return the preset called ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS` (e.g. ``"table_2_1"``).

    Returns
    -------
    Preset

    Raises
    ------
    KeyError
        If ``name`` is unknown (the message lists the known names).
    """
    try:
        return PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset {name!r}; known presets: {', '.join(PRESETS)}") from None
