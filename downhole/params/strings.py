"""Parameters of the distributed drill strings of Chapters 3 (Table 3.1) and 5 (Table 5.1)."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from downhole.params.quantity import Q
from downhole.params.rig import DEFAULT_TOP_DRIVE_INERTIA

__all__ = ["DirectionalWellParams", "NeutralStringParams", "PipeSection"]


class PipeSection(BaseModel):
    """A uniform tubular: geometry and material, SI units.

    Parameters
    ----------
    outer_diameter : float
        Outer diameter, m (> 0).
    inner_diameter : float
        Inner diameter, m (>= 0, smaller than the outer diameter).
    young_modulus : float
        Young's modulus E, Pa (default 2.11e11).
    shear_modulus : float
        Shear modulus G, Pa (default 7.93e10).
    density : float
        Density rho of the material, kg/m^3 (default 7850).
    weight_factor : float
        Adjusted weight / plain-end weight (>= 1; default 1, plain pipe): tool joints and upsets
        add mass and displaced volume per length, ``linear_mass = weight_factor * rho * A``,
        but not stiffness (EA, GJ are the body's). From a catalogue entry
        (:func:`downhole.string.catalogue.catalogue_section`: 1.31 for 5" 19.50 lb/ft S-135
        with NC50 joints).

    Values may be given as quantity strings (``"5 in"``); they are stored in SI.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    outer_diameter: Q["length"] = Field(..., gt=0)
    inner_diameter: Q["length"] = Field(..., ge=0)
    young_modulus: Q["pressure"] = Field(2.11e11, gt=0)
    shear_modulus: Q["pressure"] = Field(7.93e10, gt=0)
    density: Q["density"] = Field(7850.0, gt=0)
    weight_factor: float = Field(1.0, ge=1.0, le=3.0)

    def model_post_init(self, __context) -> None:
        """Pydantic hook after field validation (``__context`` unused): a ``ValueError``, reported
        as a validation error, if the inner diameter is not smaller than the outer one."""
        if self.inner_diameter >= self.outer_diameter:
            raise ValueError(
                f"inner_diameter ({self.inner_diameter} m) must be smaller than "
                f"outer_diameter ({self.outer_diameter} m)")

    @property
    def area(self) -> float:
        """Cross-section area, m^2."""
        return math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2)

    @property
    def polar_moment(self) -> float:
        """Polar second moment of area J, m^4."""
        return math.pi / 32 * (self.outer_diameter**4 - self.inner_diameter**4)

    @property
    def linear_mass(self) -> float:
        """Mass per length, kg/m: ``weight_factor * rho * A`` (tool joints included)."""
        return self.weight_factor * self.density * self.area

    @property
    def linear_inertia(self) -> float:
        """Rotary inertia per length, kg m: ``weight_factor * rho * J`` (the tool joints' share
        taken in proportion to their mass, an approximation documented in docs/torque-drag.md)."""
        return self.weight_factor * self.density * self.polar_moment

    @property
    def axial_wave_speed(self) -> float:
        """c_a = sqrt(E A / linear_mass) = sqrt(E/rho) for plain pipe, m/s."""
        return math.sqrt(self.young_modulus / (self.weight_factor * self.density))

    @property
    def torsional_wave_speed(self) -> float:
        """c_t = sqrt(G J / linear_inertia) = sqrt(G/rho) for plain pipe, m/s."""
        return math.sqrt(self.shear_modulus / (self.weight_factor * self.density))

    @property
    def axial_impedance(self) -> float:
        """Z_a = A sqrt(rho E) (rho times the weight factor), N s/m."""
        return self.area * math.sqrt(self.weight_factor * self.density * self.young_modulus)

    @property
    def torsional_impedance(self) -> float:
        """Z_t = J sqrt(rho G) (rho times the weight factor), N m s/rad."""
        return self.polar_moment * math.sqrt(self.weight_factor * self.density
                                             * self.shear_modulus)


class NeutralStringParams(BaseModel):
    """Chapter 3 vertical string (Table 3.1, corrected): one uniform pipe from surface to bit.

    Table 3.1 prints G in N s/m and J in kg m^2; J is the polar moment of area in m^4
    (1.9085e-5 from the diameters). Table 3.1 omits the friction coefficient; mu = 0.7 works.

    Parameters
    ----------
    length : float
        String length L, m.
    pipe : PipeSection
        The pipe.
    alpha_axial : float
        Axial top damper alpha_A to the commanded velocity (Eq. 3.5), N s/m.
    alpha_torsional : float
        Torsional top damper alpha_T, N m s/rad.
    string_mass : float
        String mass M_S, kg.
    bit_mass : float
        Bit (bottom-hole) mass M_B, kg.
    bit_inertia : float
        Bit (bottom-hole) moment of inertia, kg m^2.
    g : float
        Gravity, m/s^2.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    length: Q["length"] = Field(1000.0, gt=0)
    pipe: PipeSection = PipeSection(outer_diameter=0.12, inner_diameter=0.06)
    alpha_axial: Q["damping"] = Field(6e5, gt=0)
    alpha_torsional: Q["torsional_damping"] = Field(8e2, gt=0)
    string_mass: Q["mass"] = Field(6.7e4, gt=0)
    bit_mass: Q["mass"] = Field(3e4, gt=0)
    bit_inertia: Q["inertia"] = Field(67.5, gt=0)
    g: Q["acceleration"] = Field(9.81, ge=0)


class DirectionalWellParams(BaseModel):
    """Chapter 5 directional well and string (Table 5.1, corrected).

    AB vertical, BC straight (here: continuing vertical, as the seed's figure), CD circular arc of
    radius R_C and angle theta_CD. Table 5.1's J = 1.72e-5 m^4 is replaced by the polar moment of
    the given diameters (1.909e-5 m^4); the seed leaves the top-drive inertia and PI gains out:
    J_td = 500 kg m^2, Kp = 1e4 N m s/rad, Ki = 2e3 N m/rad reproduce its stick-slip.

    Parameters
    ----------
    pipe : PipeSection
        The pipe (E = 210 GPa, G = 80.8 GPa by default).
    length_ab, length_bc : float
        Lengths of the sections AB and BC, m.
    arc_radius_cd : float
        Radius R_C of the arc CD, m.
    arc_angle_cd : float
        Angle theta_CD of the arc CD, rad.
    rayleigh_alpha, rayleigh_beta : float
        Rayleigh damping C = alpha M + beta K: alpha in 1/s, beta in s.
    wellbore_stiffness : float
        Wellbore contact stiffness of Table 5.1, N/m (kept with the table; the soft-string
        contact model does not use it).
    wellbore_friction : float
        Wellbore friction coefficient mu (dimensionless).
    wellbore_radius : float
        Wellbore radius of Table 5.1, m (kept with the table; the soft-string contact model
        does not use it).
    top_drive_inertia : float
        Top-drive inertia J_td, kg m^2.
    top_drive_kp : float
        Top-drive PI proportional gain, N m s/rad.
    top_drive_ki : float
        Top-drive PI integral gain, N m/rad.
    g : float
        Gravity, m/s^2.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    pipe: PipeSection = PipeSection(outer_diameter=0.12, inner_diameter=0.06,
                                    young_modulus=210e9, shear_modulus=80.8e9)
    length_ab: Q["length"] = Field(2000.0, gt=0)
    length_bc: Q["length"] = Field(1000.0, gt=0)
    arc_radius_cd: Q["length"] = Field(4000.0, gt=0)
    arc_angle_cd: Q["angle"] = Field(math.radians(30.0), gt=0)
    rayleigh_alpha: float = Field(0.05, ge=0)
    rayleigh_beta: float = Field(0.03, ge=0)
    wellbore_stiffness: Q["stiffness"] = Field(1e8, ge=0)
    wellbore_friction: float = Field(0.5, ge=0)
    wellbore_radius: Q["length"] = Field(0.24, gt=0)
    top_drive_inertia: Q["inertia"] = Field(DEFAULT_TOP_DRIVE_INERTIA, gt=0)
    top_drive_kp: Q["torsional_damping"] = Field(1e4, ge=0)
    top_drive_ki: Q["torsional_stiffness"] = Field(2e3, ge=0)
    g: Q["acceleration"] = Field(9.81, ge=0)
