"""The 3D-RFT of Agarwal, Goldman & Kamrin: the second force model, its constants and parameters.

S. Agarwal, D. I. Goldman, K. Kamrin, "Mechanistic framework for reduced-order models in soft
materials: Application to three-dimensional granular intrusion", PNAS 120 (2023), e2214017120
(arXiv 2205.14920). A leading surface element at depth d with outward unit normal n, moving
along the unit direction v (world frame, z up), feels the force per area

    f = xi_n d (alpha_n + min(mu_surf |alpha_n| / |alpha_t|, 1) alpha_t),

where, in the element's local frame (z up; r the horizontal direction of v, or of n when v is
vertical, or world x when both are; theta = z x r) and with the angles

    beta  = the normal's angle from vertical, signed as the source below does,
    gamma = the motion's angle below the horizontal (+ downwards),
    psi   = the normal's horizontal azimuth from r (atan, in (-pi/2, pi/2)),
    x1 = sin gamma,  x2 = cos beta,  x3 = cos psi cos gamma sin beta + sin gamma cos beta,

the generic coefficient is alpha = (f1 sin beta cos psi + f2 cos gamma) r
+ f1 sin beta sin psi theta - (f1 cos beta + f2 sin gamma + f3) z, with f1, f2, f3 cubic
polynomials in (x1, x2, x3) (20 terms each, ``C1``, ``C2``, ``C3``). alpha_n is its part along
the inward normal -n, of magnitude |alpha . n|; alpha_t the rest, turned to oppose the motion;
mu_surf caps the tangential part at mu_surf |alpha_n| (intruder-medium friction). The medium's
scale is xi_n = rho_c g (894 mu_int^3 - 386 mu_int^2 + 89 mu_int) [N/m^3] from its bulk density
rho_c [kg/m^3] and internal friction mu_int.

The coefficient table and the sign conventions are those of the public implementation
KKKobefeng/3D-RFT (``RFT3D.m``); mjrft's tests check the model against a plainly written
reference and against what follows from its form (``tests/test_agarwal.py``). The table could
not be checked against the paper's supplement here; a table in an Isaac Lab fork is reported
to differ in two entries (C2[17], C3[16] in this ordering).

Dissipative by construction: alpha_n . v = -|alpha . n| (n . v) < 0 for a leading element,
and alpha_t . v <= 0 after the turn. The C++ engine evaluates it (engine/law.cc, the kernel's
second model) from the parameter vector built here (``parameters``).
"""

from __future__ import annotations

import numpy as np

#: Monomial order of f1, f2, f3: 1, x1, x2, x3, x1^2, x2^2, x3^2, x1 x2, x2 x3, x3 x1, x1^3,
#: x2^3, x3^3, x1 x2^2, x2 x1^2, x2 x3^2, x3 x2^2, x3 x1^2, x1 x3^2, x1 x2 x3.
C1 = (0.00212, -0.02320, -0.20890, -0.43083, -0.00259, 0.48872, -0.00415, 0.07204, -0.02750,
      -0.08772, 0.01992, -0.45961, 0.40799, -0.10107, -0.06576, 0.05664, -0.09269, 0.01892,
      0.01033, 0.15120)  # fmt: skip
C2 = (-0.06796, -0.10941, 0.04725, -0.06914, -0.05835, -0.65880, -0.11985, -0.25739, -0.26834,
      0.02692, -0.00736, 0.63758, 0.08997, 0.21069, 0.04748, 0.20406, 0.18589, 0.04934,
      0.13527, -0.33207)  # fmt: skip
C3 = (-0.02634, -0.03436, 0.45256, 0.00835, 0.02553, -1.31290, -0.05532, 0.06790, -0.16404,
      0.02287, 0.02927, 0.95406, -0.00131, -0.11028, 0.01487, -0.02730, 0.10911, -0.04097,
      0.07881, -0.27519)  # fmt: skip
NTERMS = 20
#: Layout of the model's parameter vector (the kernel's coefficients for this model): xi_n
#: [N/m^3], mu_surf, then C1, C2, C3.
XI_N, MU_SURF, COEF0 = 0, 1, 2
SIZE = COEF0 + 3 * NTERMS
#: Gravity in xi_n's formula [m/s^2] (the source's value).
GRAVITY = 9.81
#: A unit vector's horizontal part shorter than this counts as none (vertical motion or normal):
#: the local frame then comes from the other vector, or world x (the source's threshold).
HORIZONTAL_EPS = 1e-10


def xi_n(rho_c: float, mu_int: float, gravity: float = GRAVITY) -> float:
    """The medium's scale [N/m^3] from bulk density rho_c [kg/m^3] and internal friction."""
    return rho_c * gravity * (894.0 * mu_int**3 - 386.0 * mu_int**2 + 89.0 * mu_int)


def parameters(xi: float, mu_surf: float) -> np.ndarray:
    """(SIZE,) parameter vector of the engine's model (layout: XI_N, MU_SURF, COEF0) for scale
    xi [N/m^3] (``xi_n``) and intruder-medium friction mu_surf."""
    out = np.empty(SIZE)
    out[XI_N] = xi
    out[MU_SURF] = mu_surf
    out[COEF0:] = np.concatenate([C1, C2, C3])
    return out
