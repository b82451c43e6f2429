"""Media given by Python callables, evaluated inside the compiled pass.

The compiled pass evaluates Fourier-form media with the compiled kernel. A medium given by
callables (``Material.from_callables``) can only be evaluated in Python, so for such a field the
pass calls ``geom_wrench`` below in numba's object mode, where it runs the NumPy evaluation of
the same law (``mjrft.core.rft.unit_normal_forces``). Everything else (culling, the low-speed
treatment, the RK4 rule, ``xfrc_applied`` ownership) stays the one compiled implementation.
Object mode needs the GIL: such fields always enter the pass from Python (the passive-callback
guard routes them through MuJoCo's Python trampoline), and batches refuse them.
"""

from __future__ import annotations

import itertools
import threading
import weakref

import numpy as np

from mjrft.core.material import Material
from mjrft.core.rft import unit_normal_forces

_lock = threading.Lock()
_keys = itertools.count(1)
# key -> (material, elem_pos, elem_normal, elem_area, surface_z, region or None)
_registry: dict[int, tuple] = {}


def register(owner: object, material: Material, elements: tuple, surface_z: float, region):
    """Key under which the pass finds this medium; forgotten when ``owner`` is collected.

    elements: (elem_pos (n, 3), elem_normal (n, 3), elem_area (n,)) in the body frame.
    """
    with _lock:
        key = next(_keys)
        _registry[key] = (material, *elements, float(surface_z), region)
    weakref.finalize(owner, _registry.pop, key, None)
    return key


def geom_wrench(key, start, stop, rot, pos, omega, v_ref, p_ref, com, wrench, elem_force):
    """Add the RFT wrench on elements start..stop to wrench (6,); write their forces.

    rot (3, 3) body -> world, pos (3,) body origin [m], omega (3,) [rad/s], v_ref (3,) [m/s]
    the velocity of the world point p_ref (3,) [m], com (3,): torque point [m]; world frame.
    Elements outside the region feel nothing. Returns the number of elements that felt a force.
    """
    material, cent, normal, area, surface_z, region = _registry[key]
    sl = slice(int(start), int(stop))
    p = cent[sl] @ rot.T + pos
    n = normal[sl] @ rot.T
    v = v_ref + np.cross(omega, p - p_ref)
    f = unit_normal_forces(p, n, area[sl], v, material, surface_z)
    if region is not None:
        f[~np.all((p >= region[0]) & (p <= region[1]), axis=1)] = 0.0
    elem_force[sl] = f
    wrench[:3] += f.sum(axis=0)
    wrench[3:] += np.cross(p - com, f).sum(axis=0)
    return int(np.count_nonzero(np.any(f != 0.0, axis=1)))
