"""Constants of the 3D RFT element law shared by its NumPy and C++ (engine/law.h) evaluations.

Treers, Cao & Stuart, RA-L 6(2) 2021 (docs/design.md section 2): the frame switch for nearly
horizontal plates and the fitted scaling functions f1, f23 of the velocity decomposition.
"""

from __future__ import annotations

import numpy as np

#: |n_z| at or above this marks a nearly horizontal plate (docs/design.md 2.2): its frame comes
#: from v.
HORIZONTAL_PLATE_NZ = 1.0 - 1.0e-3

#: An element leads iff n . v > LEADING_SLACK |v| (unit n; docs/design.md 2.1). A face parallel
#: to the motion, its normal and velocity taken through a rotation and a twist, has n . v of
#: a few float64 epsilons times |v| rather than 0 (a cylinder's end cap rotated onto an axle:
#: n . v / |v| about 1 eps), which a strict n . v > 0 would count as leading half the time;
#: 16 eps covers that rounding and is far below any real incidence (sin 3.6e-15 rad).
LEADING_SLACK = 16.0 * float(np.finfo(np.float64).eps)

# Fitted scaling functions of the 3D decomposition (Treers et al. 2021, docs/design.md 2.7); both
# map [0, 1] -> [0, 1] with f(0) = 0 and f(1) = 1.
F1_GAIN, F1_SLOPE, F1_SHIFT, F1_NORM = (
    0.440850096954369,
    3.62263982880971,
    1.60910808139526,
    0.832324700111401,
)
F23_GAIN, F23_SLOPE, F23_SHIFT, F23_NORM = (
    1.99392673405210,
    1.61146827229181,
    0.973746396532650,
    5.81083560370960,
)


def f1(vt: np.ndarray) -> np.ndarray:
    """Out-of-plane scaling f1 of |v1| (component of the unit velocity along e1), in [0, 1]."""
    return F1_GAIN * (np.tanh(F1_SLOPE * vt - F1_SHIFT) + np.tanh(F1_SHIFT)) / F1_NORM


def f23(vn: np.ndarray) -> np.ndarray:
    """In-plane scaling f23 of |v23| (unit velocity in the plate's vertical plane), in [0, 1]."""
    return F23_GAIN * (np.arctanh(F23_SLOPE * vn - F23_SHIFT) + np.arctanh(F23_SHIFT)) / F23_NORM
