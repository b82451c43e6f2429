"""The two public tables of Agarwal et al.'s 3D-RFT against 2D RFT in the plane.

Run: python benchmarks/agarwal_tables.py

The KKKobefeng/3D-RFT table (``mjrft.core.agarwal``) and the Isaac Lab fork's, which differs
in C2[16] and C3[15] (docs/models.md): for each, the force of a horizontal plate pushed straight
down (minus the table's sum) and, on 4,000 random in-plane elements (normal and velocity in the
x-z plane, leading, 1 cm deep), the RMS difference from Li et al.'s generic 2D RFT
(``Material.generic``) relative to the RMS of the latter, each table's scale matched to Li's at
the plate pushed down. Evaluated with the slow reference of tests/agarwal_reference.py, so
that the table can be swapped.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import mjrft
from mjrft import Material
from mjrft.core import agarwal
from mjrft.core.material import AGARWAL_PLATE_DOWN

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import agarwal_reference

#: The fork's two entries that differ: (table, index, value).
FORK = (("C2", 16, 0.18519), ("C3", 15, -0.20770))


def in_plane_elements(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    th, ph = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 2 * np.pi, n)
    normal = np.stack([np.cos(th), np.zeros(n), np.sin(th)], 1)
    vel = 0.01 * np.stack([np.cos(ph), np.zeros(n), np.sin(ph)], 1)
    keep = np.einsum("ij,ij->i", normal, vel) > 1e-4  # leading
    normal, vel = normal[keep], vel[keep]
    pos = np.zeros_like(normal)
    pos[:, 2] = -0.01
    return pos, normal, np.full(len(normal), 1e-4), vel


def main() -> None:
    pos, normal, area, vel = in_plane_elements(4000)
    li = Material.generic(1e6)
    f_li = mjrft.element_forces(pos, normal, area, vel, li)
    rms_li = np.sqrt((f_li**2).sum(1).mean())
    xi = li.with_model("agarwal3d").agarwal[agarwal.XI_N]  # matched for the KKKobefeng table
    published = {name: getattr(agarwal, name) for name in ("C1", "C2", "C3")}
    fork = {name: list(c) for name, c in published.items()}
    for name, i, value in FORK:
        fork[name][i] = value
    try:
        for label, table in (("KKKobefeng/3D-RFT", published), ("Isaac Lab fork", fork)):
            for name, c in table.items():
                setattr(agarwal, name, tuple(c))  # the reference reads the module's table
            plate = -sum(sum(c) for c in table.values())
            xi_t = xi * AGARWAL_PLATE_DOWN / plate  # this table's plate pushed down = Li's
            f = np.array([agarwal_reference.element_force(*e, xi_t, 10.0)
                          for e in zip(pos, normal, area, vel, strict=True)])  # fmt: skip
            err = np.sqrt(((f - f_li) ** 2).sum(1).mean()) / rms_li
            print(f"{label:18s} plate pushed down {plate:.5f}; in-plane RMS difference from "
                  f"Li's 2D RFT {100 * err:.1f} %")  # fmt: skip
    finally:
        for name, c in published.items():
            setattr(agarwal, name, c)


if __name__ == "__main__":
    main()
