"""Parameters of the lumped axial-torsional drill-string models (seed Eq. 2.1 and 2.26-2.31)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from downhole.params.quantity import Q

__all__ = ["LumpedParams", "TwelfthOrderSplit"]

G_ACC = 9.81


class TwelfthOrderSplit(BaseModel):
    """How the 12th-order (3-mass) model splits the 4th-order mass, inertia and compliance.

    Defaults are the split of docs/seed-errata.md, which matches the 4th-order model within 2-4 %
    below half the first natural frequency: mass shares 0.02/0.08/0.90 and compliance shares
    (servo : spring 1 : spring 2) = 0.02 : 0.58 : 0.40 of 1/K_a (and 1/K_t).

    Parameters
    ----------
    mass_shares : (float, float, float)
        Shares of the mass and inertia of the three bodies, top first (positive, sum 1).
    compliance_shares : (float, float, float)
        Shares of the compliance 1/K of the servo and the two springs (positive, sum 1).
    servo_damping_ratio : float
        Damping ratio of the top (servo) stage (dimensionless, default 0.7).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    mass_shares: tuple[float, float, float] = (0.02, 0.08, 0.90)
    compliance_shares: tuple[float, float, float] = (0.02, 0.58, 0.40)
    servo_damping_ratio: float = Field(0.7, ge=0)

    def model_post_init(self, __context) -> None:
        """Pydantic hook after field validation (``__context`` unused): a ``ValueError``, reported
        as a validation error, unless ``mass_shares`` and ``compliance_shares`` are three
        positive numbers summing to 1."""
        for name in ("mass_shares", "compliance_shares"):
            vals = getattr(self, name)
            if any(v <= 0 for v in vals) or abs(sum(vals) - 1.0) > 1e-9:
                raise ValueError(f"{name} must be three positive numbers summing to 1, got {vals}")


class LumpedParams(BaseModel):
    """4th-order lumped drill string (seed Eq. 2.1), SI units.

    Attributes
    ----------
    mass : float
        Equivalent axial mass M, kg.
    inertia : float
        Equivalent torsional inertia I, kg m^2.
    axial_stiffness, axial_damping : float
        K_a (N/m) and C_a (N s/m). C_a acts on the absolute bit velocity, as in Eq. 2.1.
    torsional_stiffness, torsional_damping : float
        K_t (N m/rad) and C_t (N m s/rad), C_t on the absolute bit angular velocity.
    gravity_prebalance : bool
        True (default): the string starts hanging in static equilibrium with zero WOB, i.e.
        u1 = V0 t - M g / K_a (docs/seed-errata.md). False: the printed Eq. 2.1 with M g unbalanced.
    g : float
        Gravitational acceleration, m/s^2.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    mass: Q["mass"] = Field(..., gt=0)
    inertia: Q["inertia"] = Field(..., gt=0)
    axial_stiffness: Q["stiffness"] = Field(..., gt=0)
    axial_damping: Q["damping"] = Field(..., ge=0)
    torsional_stiffness: Q["torsional_stiffness"] = Field(..., gt=0)
    torsional_damping: Q["torsional_damping"] = Field(..., ge=0)
    gravity_prebalance: bool = True
    g: Q["acceleration"] = Field(G_ACC, ge=0)
    twelfth_order: TwelfthOrderSplit = TwelfthOrderSplit()

    @property
    def weight(self) -> float:
        """String weight M g carried by the hook when hanging, N."""
        return self.mass * self.g
