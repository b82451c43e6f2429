"""The ellipsoid rig at the triangle counts near 1 % force error: accuracy and cost side by side.

Run: python benchmarks/rig_target.py [--triangles 48 80 112 192] [--reference N]

For each count: the RFT force and moment errors of the ellipsoid under its rig's motion
(benchmarks/pareto.py's "ellipsoid" case: the trajectory of ``mjrft.demos.ellipsoid_pitch`` at
10 ms spacing against the same shape at about N triangles, default pareto.REF_TRIANGLES), and the
cost of an mj_step of models/ellipsoid_pitch.xml with the field at that count against a plain
mj_step of the same model, deep in the medium (t = 10 s) and tip in (t = 1 s), measured as
benchmarks/field_overhead.py does (medians of back-to-back pairs). The smallest count whose
force error is at most 1 % is the one the cost target is read at.
Writes benchmarks/results/rig_target.csv.
"""

from __future__ import annotations

import argparse

import mujoco
from field_overhead import MODELS, OUT, state_at, time_pairs
from pareto import REF_TRIANGLES, Case, _shapes, ellipsoid_rig_motion, write_csv

from mjrft import simulate
from mjrft.field import GranularField


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, nargs="+", default=[48, 80, 112, 192])
    ap.add_argument("--reference", type=int, default=REF_TRIANGLES)
    args = ap.parse_args()
    OUT.mkdir(exist_ok=True)
    case = Case("ellipsoid", _shapes()["ellipsoid"], lambda s: ellipsoid_rig_motion(0.01),
                args.reference, "ellipsoid")  # fmt: skip
    print(f"ellipsoid rig motion, reference {case.ref_n} triangles")
    plain_model = mujoco.MjModel.from_xml_path(str(MODELS / "ellipsoid_pitch.xml"))
    rows = []
    for n in args.triangles:
        acc = case.error_at(n)
        model = simulate.load_model(MODELS / "ellipsoid_pitch.xml", n_triangles=n)
        fld = GranularField(model)
        row = {"requested": n, "triangles": fld.n_elements,
               "force_error": acc["force_error"], "moment_error": acc["moment_error"]}  # fmt: skip
        for label, t in (("tip_in", 1.0), ("deep", 10.0)):
            plain, with_field, ratio, _ = time_pairs(plain_model, model, fld, state_at(model, t))
            row |= {f"{label}_plain_us": 1e6 * plain, f"{label}_field_us": 1e6 * with_field,
                    f"{label}_ratio": ratio}  # fmt: skip
        rows.append(row)
        print(
            f"  {row['triangles']:4d} triangles  force error {100 * row['force_error']:.3f} %  "
            f"moment error {100 * row['moment_error']:.3f} %  step cost vs plain: "
            f"tip in {row['tip_in_ratio']:.2f}x, deep {row['deep_ratio']:.2f}x "
            f"(plain {row['deep_plain_us']:.1f} us)"
        )
    ok = [r for r in rows if r["force_error"] <= 0.01]
    if ok:
        r = min(ok, key=lambda r: r["triangles"])
        print(f"smallest count at <= 1 %: {r['triangles']} triangles, deep {r['deep_ratio']:.2f}x")
    write_csv(OUT / "rig_target.csv", rows)


if __name__ == "__main__":
    main()
