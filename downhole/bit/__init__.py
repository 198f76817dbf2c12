"""Bit/rock interaction: one compiled bit-law interface (:mod:`downhole.bit.law`) with the
corrected Detournay law and the Aarsnes & van de Wouw law behind it, and one depth-of-cut memory
(:mod:`downhole.bit.rock_surface`) beside the approximated depth of cut."""

from downhole.bit.law import (
    LAWS,
    BitLaw,
    approx_depth_of_cut,
    approx_depth_rate,
    bit_force_slopes,
    bit_forces,
    bit_forces_and_slopes,
    bit_forces_and_slopes_py,
    bit_forces_py,
    bit_forces_vec,
    bit_wob,
    law_id,
    solve_bit_node,
)
from downhole.bit.rock_surface import (
    RockSurfaceSpec,
    rock_advance,
    rock_advance_to,
    rock_depth,
    rock_depth_at,
    rock_init,
)

__all__ = [
    "LAWS",
    "BitLaw",
    "RockSurfaceSpec",
    "approx_depth_of_cut",
    "approx_depth_rate",
    "bit_force_slopes",
    "bit_forces",
    "bit_forces_and_slopes",
    "bit_forces_and_slopes_py",
    "bit_forces_py",
    "bit_forces_vec",
    "bit_wob",
    "law_id",
    "rock_advance",
    "rock_advance_to",
    "rock_depth",
    "rock_depth_at",
    "rock_init",
    "solve_bit_node",
]
