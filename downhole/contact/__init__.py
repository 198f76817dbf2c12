"""Wellbore contact: soft-string normal force and regularized, implicitly applied friction."""

from downhole.contact.softstring import (
                                         ELEM_LAYOUT,
                                         contact_elements,
                                         element_normal_half,
                                         friction_damper,
                                         friction_forces,
                                         nodal_friction_forces,
                                         normal_force_per_length,
                                         normal_weight,
                                         soft_string_normal_force,
)

__all__ = [
                                         "ELEM_LAYOUT",
                                         "contact_elements",
                                         "element_normal_half",
                                         "friction_damper",
                                         "friction_forces",
                                         "nodal_friction_forces",
                                         "normal_force_per_length",
                                         "normal_weight",
                                         "soft_string_normal_force",
]
