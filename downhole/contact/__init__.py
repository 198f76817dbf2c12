"""Wellbore contact: soft-string normal force and regularized, implicitly applied friction."""

from downhole.contact.softstring import (friction_damper, friction_forces,
                                         normal_force_per_length, soft_string_normal_force)

__all__ = ["normal_force_per_length", "friction_damper", "friction_forces",
           "soft_string_normal_force"]
