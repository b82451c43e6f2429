"""Media given by Python callables, evaluated inside the compiled pass.

The compiled pass evaluates Fourier-form media with the compiled kernel. A medium given by
callables (``Material.from_callables``) can only be evaluated in Python, so for such a field the
pass calls ``geom_wrench`` below in numba's object mode, where the kernel places the
quadrature points (``mjrft.core.kernel.body_wrench``'s rows) and the NumPy evaluation of the
same law gives their forces (``mjrft.core.rft.quadrature_forces``). Everything else (culling,
the quadrature, the low-speed treatment, the RK4 rule, ``xfrc_applied`` ownership) stays the
one compiled implementation.
Object mode needs the GIL: such fields always enter the pass from Python (the passive-callback
guard routes them through MuJoCo's Python trampoline), and batches refuse them.
"""

from __future__ import annotations

import itertools
import threading
import weakref

import numpy as np

from mjrft.core import kernel
from mjrft.core.material import Material
from mjrft.core.rft import quadrature_forces

_lock = threading.Lock()
_keys = itertools.count(1)
# key -> (material, the kernel's element and medium arguments)
_registry: dict[int, tuple] = {}


def register(owner: object, material: Material, tables: tuple):
    """Key under which the pass finds this medium; forgotten when ``owner`` is collected.

    tables: the kernel's element and medium arguments, (cent, norm, area, reach, patch) and
    (co, ay, zeta, surface_prm, surface_grid, use_region, region, soil) of
    ``mjrft.core.kernel.body_wrench`` (co, ay and zeta unused: the callables give the forces).
    """
    with _lock:
        key = next(_keys)
        _registry[key] = (material, tables)
    weakref.finalize(owner, _registry.pop, key, None)
    return key


def geom_wrench(key, start, stop, rot, pos, omega, v_ref, p_ref, com, wrench, elem_force):
    """Add the RFT wrench on elements start..stop to wrench (6,); write their forces.

    rot (3, 3) body -> world, pos (3,) body origin [m], omega (3,) [rad/s], v_ref (3,) [m/s]
    the velocity of the world point p_ref (3,) [m], com (3,): torque point [m]; world frame.
    Elements outside the region feel nothing. Returns the number of elements that felt a force.
    """
    material, tables = _registry[key]
    sl = slice(int(start), int(stop))
    m = sl.stop - sl.start
    r = np.zeros((m, kernel.ROW))  # the geom's block alone: rows sized to it, not the field
    kernel.body_wrench(
        *(a[sl] for a in tables[:5]), 0, m, *tables[5:], rot, pos, omega, v_ref, p_ref, com,
        np.zeros(6), elem_force[sl], r,
    )  # fmt: skip
    f = quadrature_forces(r, material)
    elem_force[sl] = f
    wrench[:3] += f.sum(axis=0)
    wrench[3:] += np.cross(r[:, :3] - com, f).sum(axis=0)
    return int(np.count_nonzero(np.any(f != 0.0, axis=1)))
