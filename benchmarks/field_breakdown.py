"""Where the field's time goes in one state of the ellipsoid rig, and what bounds its ratio.

Run: python benchmarks/field_breakdown.py [--triangles N] [--time T]
models/ellipsoid_pitch.xml with the ellipsoid at N triangles (default 2000), loaded with the
engine plugin and stepped to t = T (default 10 s: deep in the medium). Medians over repeats,
all in one process; the engine's parts are called through its C entry points (ctypes, about
1 us per call, included):

  plain      a plain mj_step of the model compiled without the plugin, called from Python
  field      an mj_step of the plugin's model (the engine's pass inside it), from Python
  native     the engine's whole pass alone (``mjrft_forward`` in the mode mj_step runs it)
  wrench     the kernel's body wrench over the ellipsoid alone (``mjrft_body_wrench``)
  one_point  the same with the quadrature's bounds zeroed (elem_reach and the patches' spread):
             the one-point rule on the same elements, nothing tested or clipped
  acting     the kernel's forces over the acting triangles only (``mjrft_forces``), from
             precomputed world-frame positions, normals and velocities: the evaluation every
             pipeline pays at this precision, whatever its bookkeeping (a lower bound on the
             field's cost)

Each is printed in us and as a multiple of a plain step (a field costing x adds x to the ratio
field / plain). The kernel's parts are checked against the engine's own pass (the body's wrench
and element forces) before they are timed. Writes benchmarks/results/field_breakdown.csv.
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import time
from pathlib import Path

import mujoco
import numpy as np

from mjrft import simulate
from mjrft.core import engine, quadrature
from mjrft.field import GranularField, plugin

MODELS = Path(__file__).resolve().parents[1] / "models"
OUT = Path(__file__).resolve().parent / "results"
REPEATS = 9
CALLS = 2000
STEPS = 2000
#: The mode of ``mjrft_forward`` that mj_step runs (engine/forward.h, kInstalled).
INSTALLED = 0
#: The kernel called on its own sums the same terms in the same order as the engine's pass, but
#: the pass holds the treatment's wrench too: agreement of the pure model's parts to round-off.
PASS_ROUNDOFF = 1e-12


def _median_us(call, *args) -> float:
    """Median microseconds per call(*args) over REPEATS runs of CALLS calls."""
    for _ in range(10):
        call(*args)
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        for _ in range(CALLS):
            call(*args)
        times.append((time.perf_counter() - t0) / CALLS)
    return 1e6 * float(np.median(times))


def _clone(model: mujoco.MjModel, d0: mujoco.MjData) -> mujoco.MjData:
    d = mujoco.MjData(model)
    d.qpos[:], d.qvel[:], d.act[:], d.ctrl[:], d.time = d0.qpos, d0.qvel, d0.act, d0.ctrl, d0.time
    return d


def _step_us(model: mujoco.MjModel, d0: mujoco.MjData) -> float:
    """Microseconds per mj_step over STEPS steps from d0's state."""
    d = _clone(model, d0)
    mujoco.mj_step(model, d)
    t0 = time.perf_counter()
    for _ in range(STEPS):
        mujoco.mj_step(model, d)
    return 1e6 * (time.perf_counter() - t0) / STEPS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=2000)
    ap.add_argument("--time", type=float, default=10.0, help="state: seconds into the run")
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    path = MODELS / "ellipsoid_pitch.xml"
    model = simulate.load_model(path, n_triangles=args.triangles)
    bare = mujoco.MjModel.from_xml_path(str(path))  # the same model without the plugin
    fld = GranularField(model)
    d0 = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d0, 0)
    while d0.time < args.time:
        mujoco.mj_step(model, d0)
    # Plain and field steps alternate, so that a slow spell of this shared machine lands on both.
    plain, field = [], []
    for _ in range(REPEATS):
        plain.append(_step_us(bare, d0))
        field.append(_step_us(model, d0))
    rows = {"plain": float(np.median(plain)), "field": float(np.median(field))}

    d = _clone(model, d0)
    mujoco.mj_forward(model, d)
    t = fld._tables  # the engine's tables by name (mjrft.field.model.engine_tables)
    if len(t["tgeom_geomid"]) != 1:
        raise SystemExit(f"expected one intruding geom in the rig, found {len(t['tgeom_geomid'])}")
    be = fld.bodies[0]
    b, root = be.body, int(t["tbody_rootid"][0])
    start, n = int(t["tgeom_elemadr"][0]), int(t["tgeom_elemnum"][0])
    block = slice(start, start + n)
    elements = [np.ascontiguousarray(t[k][block]) for k in
                ("elem_pos", "elem_normal", "elem_area", "elem_reach", "elem_patch")]  # fmt: skip
    medium = (t["coef"], t["alpha_y"], t["zeta"], t["surface_prm"],
              np.reshape(t["surface_grid"], (t["surface_nrow"], t["surface_ncol"])))  # fmt: skip
    motion = [np.ascontiguousarray(a) for a in (
        d.xmat[b].reshape(3, 3), d.xpos[b], d.cvel[b, :3], d.cvel[b, 3:], d.subtree_com[root],
        d.xipos[b])]  # fmt: skip
    region = np.reshape(t["region"], (2, 3)) if t["use_region"] else None
    _, elem_force, acting = engine.body_wrench(*elements, *medium, region, None, *motion)
    (st,) = [s for s in fld.element_states(d) if s.body == b]
    want = np.zeros((n, 3))
    want[st.index] = st.force
    scale = np.abs(want).max()
    if np.abs(elem_force - want).max() > PASS_ROUNDOFF * scale:
        raise SystemExit("the kernel alone disagrees with the engine's pass on element forces")

    # The acting triangles in the world frame (element_states: the same model's inputs).
    act = np.any(st.force != 0.0, axis=1)
    pos, nrm = np.ascontiguousarray(st.pos[act]), np.ascontiguousarray(st.normal[act])
    area, vel = np.ascontiguousarray(st.area[act]), np.ascontiguousarray(st.vel[act])
    out, _ = engine.forces(pos, nrm, area, vel, t["coef"], t["alpha_y"], t["zeta"], t["surface_z"])
    if not np.allclose(out, st.force[act], rtol=PASS_ROUNDOFF, atol=0.0):
        raise SystemExit("the acting-only evaluation disagrees with the engine's element forces")

    # The timed calls go to the C entry points with their arguments checked above.
    lib = plugin.library()
    ptr = lambda a: a.ctypes.data  # noqa: E731
    instance = plugin.instance(model)
    m_ptr, d_ptr = ctypes.c_void_p(model._address), ctypes.c_void_p(d._address)
    rows["native"] = _median_us(lib.mjrft_forward, m_ptr, d_ptr, instance, INSTALLED)
    co, prm, grid = (np.ascontiguousarray(medium[i], dtype=np.float64) for i in (0, 3, 4))
    ay, zeta = float(t["alpha_y"]), float(t["zeta"])
    box = np.zeros((2, 3)) if region is None else np.ascontiguousarray(region)
    no_soil, w = np.zeros(1), np.zeros(6)

    def wrench_args(reach, patch):
        return (
            ptr(elements[0]), ptr(elements[1]), ptr(elements[2]), ptr(reach), ptr(patch), 0, n,
            ptr(co), len(co), ay, zeta, ptr(prm), ptr(grid), int(region is not None), ptr(box),
            ptr(no_soil), *(ptr(a) for a in motion), ptr(w), ptr(elem_force), None,
        )  # fmt: skip

    rows["wrench"] = _median_us(lib.mjrft_body_wrench, *wrench_args(elements[3], elements[4]))
    flat_patch = elements[4].copy()
    flat_patch[:, quadrature.PATCH_SPREAD] = 0.0
    no_reach = np.zeros_like(elements[3])
    rows["one_point"] = _median_us(lib.mjrft_body_wrench, *wrench_args(no_reach, flat_patch))
    rows["acting"] = _median_us(
        lib.mjrft_forces, ptr(pos), ptr(nrm), ptr(area), ptr(vel), len(area), ptr(co), len(co),
        ay, zeta, float(t["surface_z"]), ptr(out),
    )  # fmt: skip

    print(f"ellipsoid_pitch.xml at t = {args.time} s: {n} triangles, {acting} acting")
    plain_us = rows["plain"]
    table = []
    for name, us in rows.items():
        per = us / plain_us
        print(f"  {name:10s} {us:7.1f} us  {per:5.2f} x plain step")
        table.append({"part": name, "us": us, "per_plain_step": per})
    bound = 1 + rows["acting"] / plain_us
    print(
        f"  acting-only evaluation: {1e3 * rows['acting'] / max(acting, 1):.1f} ns per acting "
        f"triangle; a field costing at least that gives a ratio >= {bound:.2f}"
    )
    with open(OUT / "field_breakdown.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(table[0]))
        writer.writeheader()
        writer.writerows(table)


if __name__ == "__main__":
    main()
