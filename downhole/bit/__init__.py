"""Bit/rock interaction: the Detournay law and the two depths of cut (delayed, approximated)."""

from downhole.bit.detournay import (approx_depth_of_cut, bit_force_slopes, bit_forces,
                                    bit_forces_py, bit_forces_vec)
from downhole.bit.rock_surface import RockSurfaceSpec, rock_advance, rock_depth, rock_init

__all__ = ["bit_forces", "bit_forces_py", "bit_forces_vec", "approx_depth_of_cut",
           "bit_force_slopes", "RockSurfaceSpec", "rock_init", "rock_depth", "rock_advance"]
