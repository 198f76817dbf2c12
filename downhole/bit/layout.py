"""Named slots of the packed bit-parameter array (:data:`downhole.params.bit.BIT_ARRAY_LAYOUT`).

Only the bit laws (:mod:`downhole.bit.detournay`, :mod:`downhole.bit.aarsnes`) and their dispatch
(:mod:`downhole.bit.law`) read the array; every kernel hands it through unopened. The indices are
derived from the layout tuple by name, so reordering the layout cannot silently shift a slot.
"""

from __future__ import annotations

from downhole.params.bit import BIT_ARRAY_LAYOUT

__all__ = ["SLOT"]

#: Slot of each named parameter in the packed array.
SLOT = {name: i for i, name in enumerate(BIT_ARRAY_LAYOUT)}

EPS = SLOT["epsilon"]
SIG = SLOT["sigma"]
ZETA = SLOT["zeta"]
A = SLOT["radius"]
NBL = SLOT["n_blades"]
L = SLOT["wear_length"]
DSTAR = SLOT["d_star"]
KC = SLOT["contact_stiffness"]
MUC = SLOT["mu_c"]
MUS = SLOT["mu_s"]
GAM = SLOT["gamma"]
GAMB = SLOT["gamma_b"]
VF = SLOT["v_f"]
MUGAM = SLOT["mu_gamma"]
A1 = SLOT["a1"]
B1 = SLOT["b1"]
A2 = SLOT["a2"]
B2 = SLOT["b2"]
CONT = SLOT["wear_flat_continuous"]
STRIB = SLOT["friction_stribeck"]
OMREG = SLOT["omega_reg"]
OMFLOOR = SLOT["omega_floor"]
LAW = SLOT["law"]
FCONT = SLOT["contact_force"]
DCONT = SLOT["contact_depth"]
