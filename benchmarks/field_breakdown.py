"""Where the field's time goes in one state of the ellipsoid rig, and what bounds its ratio.

Run: python benchmarks/field_breakdown.py [--triangles N] [--time T]
models/ellipsoid_pitch.xml with the ellipsoid at N triangles (default 2000), stepped with the
field to t = T (default 10 s: deep in the medium). Medians over repeats, all in one process:

  plain      a plain mj_step of the model (field off), called from Python
  field      an mj_step with the installed field, called from Python
  native     mjrft.field.passive.step alone (the field's whole pass), in a numba loop
  wrench     mjrft.core.kernel.body_wrench over the ellipsoid alone, in a numba loop
  one_point  the same with the quadrature's bounds zeroed (elem_reach and the patches' spread):
             the one-point rule on the same elements, nothing tested or clipped
  acting     mjrft.core.kernel.forces over the acting triangles only, from precomputed world-frame
             positions, normals and velocities: the evaluation every pipeline pays at this
             precision, whatever its bookkeeping (a lower bound on the field's cost)
  wrench_2t  body_wrench with the ellipsoid's chunks dealt to two OpenMP threads (numba
             parallel) and the partial wrenches summed: both cores inside one step

Each is printed in us and as a multiple of a plain step (a field costing x adds x to the ratio
field / plain). The 2-thread variant is checked equal to one thread (element forces bit-equal,
wrench to round-off) before it is timed. Writes benchmarks/results/field_breakdown.csv.
"""

from __future__ import annotations

import argparse
import csv
import time

import mujoco
import numba
import numpy as np
from field_overhead import MODELS, OUT, state_at, time_pairs

from mjrft import simulate
from mjrft.core import kernel as _kernel
from mjrft.core import quadrature
from mjrft.field import GranularField, passive

REPEATS = 9
CALLS = 2000
# Relative size of the round-off between one and two threads' wrench sums (the order of the
# additions differs; the element forces are bit-equal).
SUM_ROUNDOFF = 1e-12


@numba.njit(error_model="numpy")
def _loop_native(reps, field_addr, data_addr, mode):
    s = 0
    for _ in range(reps):
        s += passive.step(field_addr, data_addr, mode)
    return s


@numba.njit(error_model="numpy")
def _loop_wrench(reps, args, wrench, elem_force):
    s = 0
    for _ in range(reps):
        s += _kernel.body_wrench(*args, wrench, elem_force, np.empty((0, _kernel.ROW)))
    return s


@numba.njit(error_model="numpy")
def _loop_forces(reps, pos, normal, area, vel, co, ay, zeta, surface_z, out):
    s = 0
    for _ in range(reps):
        s += _kernel.forces(pos, normal, area, vel, co, ay, zeta, surface_z, out)
    return s


@numba.njit(parallel=True, error_model="numpy")
def wrench_two_threads(args, start, stop, wrench, elem_force):
    """body_wrench over start..stop with chunks dealt alternately to two threads."""
    parts = 2
    partial = np.zeros((parts, 6))
    count = np.zeros(parts, np.int64)
    n_chunks = (stop - start + _kernel.CHUNK - 1) // _kernel.CHUNK
    for p in numba.prange(parts):
        for c in range(p, n_chunks, parts):
            a = start + c * _kernel.CHUNK
            b = min(stop, a + _kernel.CHUNK)
            count[p] += _kernel.body_wrench(
                args[0],
                args[1],
                args[2],
                args[3],
                args[4],
                a,
                b,
                *args[7:],
                partial[p],
                elem_force,
                np.empty((0, _kernel.ROW)),
            )
    for p in range(parts):
        for c in range(6):
            wrench[c] += partial[p, c]
    return count.sum()


@numba.njit(error_model="numpy")
def _loop_two(reps, args, wrench, elem_force):
    s = 0
    for _ in range(reps):
        s += wrench_two_threads(args, args[5], args[6], wrench, elem_force)
    return s


def _median_us(fn, *args) -> float:
    fn(10, *args)  # compile / warm
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn(CALLS, *args)
        times.append((time.perf_counter() - t0) / CALLS)
    return 1e6 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=2000)
    ap.add_argument("--time", type=float, default=10.0, help="state: seconds into the run")
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    model = simulate.load_model(MODELS / "ellipsoid_pitch.xml")
    fld = GranularField(model, n_triangles=args.triangles)
    d0 = state_at(model, fld, args.time)
    plain, field, _ = time_pairs(model, d0, fld)
    plain_us, field_us = 1e6 * plain, 1e6 * field

    d = mujoco.MjData(model)
    d.qpos[:], d.qvel[:], d.act[:], d.ctrl[:], d.time = d0.qpos, d0.qvel, d0.act, d0.ctrl, d0.time
    mujoco.mj_forward(model, d)
    fm = fld._tables.arrays  # the field's static tables (mjrft.field.tables.FieldModel)
    if len(fm.tgeom_geomid) != 1:
        raise SystemExit(f"expected one intruding geom in the rig, found {len(fm.tgeom_geomid)}")
    b, root = int(fm.tbody_bodyid[0]), int(fm.tbody_rootid[0])
    start, stop = int(fm.tgeom_elemadr[0]), int(fm.tgeom_elemadr[0] + fm.tgeom_elemnum[0])
    wargs = (
        fm.elem_pos, fm.elem_normal, fm.elem_area, fm.elem_reach, fm.elem_patch, start, stop,
        fm.coef, fm.alpha_y, fm.zeta, fm.surface_prm, fm.surface_grid, False, np.zeros((2, 3)),
        np.zeros(1), d.xmat[b].reshape(3, 3).copy(),
        d.xpos[b].copy(),
        d.cvel[b, :3].copy(), d.cvel[b, 3:].copy(), d.subtree_com[root].copy(),
        d.xipos[b].copy(),
    )  # fmt: skip
    n_el = len(fm.elem_area)
    w1, e1 = np.zeros(6), np.zeros((n_el, 3))
    acting = _kernel.body_wrench(*wargs, w1, e1, np.empty((0, _kernel.ROW)))
    w2, e2 = np.zeros(6), np.zeros((n_el, 3))
    acting2 = wrench_two_threads(wargs, start, stop, w2, e2)
    if acting2 != acting or not np.array_equal(e1, e2):
        raise SystemExit("two threads disagree with one on the element forces")
    if np.abs(w2 - w1).max() > SUM_ROUNDOFF * np.abs(w1).max():
        raise SystemExit(f"two threads' wrench differs beyond round-off: {w2 - w1}")

    # The acting triangles in the world frame (mjrft.field.element_states: the same model).
    st = next(s for s in fld.element_states(d) if s.body == b)
    act = np.any(st.force != 0.0, axis=1)
    pos, nrm = np.ascontiguousarray(st.pos[act]), np.ascontiguousarray(st.normal[act])
    area, vel = np.ascontiguousarray(st.area[act]), np.ascontiguousarray(st.vel[act])
    out = np.zeros((len(area), 3))
    _kernel.forces(pos, nrm, area, vel, fm.coef, fm.alpha_y, fm.zeta, fm.surface_z, out)
    if not np.allclose(out, st.force[act], rtol=1e-12, atol=0.0):
        raise SystemExit("the acting-only evaluation disagrees with the field's element forces")

    rows = {"plain": plain_us, "field": field_us}
    with fld.installed():
        mujoco.mj_step(model, d)  # registers d: its state (entry record) exists from here
        rows["native"] = _median_us(
            _loop_native, np.uint64(fld._tables.address), np.uint64(fld._state(d).address),
            passive.INSTALLED,
        )  # fmt: skip
    rows["wrench"] = _median_us(_loop_wrench, wargs, np.zeros(6), e1)
    patch = fm.elem_patch.copy()
    patch[:, quadrature.PATCH_SPREAD] = 0.0
    one_point = (*wargs[:3], np.zeros_like(fm.elem_reach), patch, *wargs[5:])
    rows["one_point"] = _median_us(_loop_wrench, one_point, np.zeros(6), np.zeros((n_el, 3)))
    rows["acting"] = _median_us(
        _loop_forces, pos, nrm, area, vel, fm.coef, fm.alpha_y, fm.zeta, fm.surface_z, out
    )
    rows["wrench_2t"] = _median_us(_loop_two, wargs, np.zeros(6), e2)

    print(
        f"ellipsoid_pitch.xml at t = {args.time} s: {stop - start} triangles, {acting} acting; "
        f"numba threading layer {numba.threading_layer()}"
    )
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
    print(f"  two threads vs one on body_wrench: {rows['wrench'] / rows['wrench_2t']:.2f}x")
    with open(OUT / "field_breakdown.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)


if __name__ == "__main__":
    main()
