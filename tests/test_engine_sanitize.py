"""The engine under AddressSanitizer and UndefinedBehaviorSanitizer.

Builds the engine with ``-DMJRFT_SANITIZE=ON`` and steps a scene of every stage (free bodies
under each integrator, a mechanism standing and walking, a height field, the deforming ground,
the sensor plugin and the sinking check, queries from Python) in a child process that preloads
the sanitizer runtime; any report fails it. Slow (a second build of the engine): run by
``.ci/run`` as its own step, or with ``MJRFT_SANITIZE=1 python -m pytest
tests/test_engine_sanitize.py``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(
    os.environ.get("MJRFT_SANITIZE") != "1",
    reason="a sanitizer build of the engine: set MJRFT_SANITIZE=1 (.ci/run does)",
)

SCENES = r"""
import numpy as np, mujoco, mjrft
from mjrft.app.simulate import resolve_model

def run(model, steps, qvel=None):
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    if qvel is not None:
        data.qvel[:] = qvel
    for _ in range(steps):
        mujoco.mj_step(model, data)
    field = mjrft.GranularField(model)
    field.wrench(data)
    field.element_states(data)
    assert np.all(np.isfinite(data.qpos))

for integrator in ("Euler", "RK4", "implicitfast"):
    for name in ("sphere_drop", "ellipsoid_pitch"):
        model = mjrft.load_model(resolve_model(name), n_triangles=200)
        model.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + integrator.upper())
        run(model, 150)
for name in ("hexapod_sand", "dune_drop", "wheel_rig", "plate_rig", "root_circumnutation"):
    run(mjrft.load_model(resolve_model(name)), 150)
run(mjrft.load_model(resolve_model("wheel_rig"), deform_cell=0.005), 200)
run(mjrft.load_model(resolve_model("wheel_rig"), deform_cell=0.005, deform_travel=0.5), 200)
# the sensor plugin (12 sensors) and the sinking check (untagged thighs and trunk)
import warnings
from mjrft.envs import go2_sand
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    go2 = mjrft.load_model(go2_sand.build_spec())
    data = mujoco.MjData(go2)
    mujoco.mj_resetDataKeyframe(go2, data, 0)
    for _ in range(150):
        data.ctrl[:] = go2_sand.trot_ctrl(data.time)
        mujoco.mj_step(go2, data)
    assert np.all(np.isfinite(data.sensordata)) and data.sensordata.any()
# the walking hexapod on a 2 mm deforming grid (cones of 1,000s of breakpoints)
from mjrft.envs import hexapod_sand
env = hexapod_sand.make(seed=0, deform_cell=0.002)
env.reset()
for k in range(15):
    env.step(np.full(env.action_spec().shape, np.sin(0.5 * k)))
from mjrft.core import engine
print("sanitized scenes ok with", engine.library_path())
"""


def _asan_runtime() -> str:
    out = subprocess.run(
        ["gcc", "-print-file-name=libasan.so"], check=True, capture_output=True, text=True
    )
    return out.stdout.strip()


def test_the_engine_runs_clean_under_asan_and_ubsan(tmp_path):
    import mujoco

    build = ROOT / "build" / "engine-asan"
    mj = Path(mujoco.__file__).parent
    subprocess.run(
        ["cmake", "-S", str(ROOT / "engine"), "-B", str(build), "-DMJRFT_SANITIZE=ON",
         "-DCMAKE_BUILD_TYPE=RelWithDebInfo", f"-DMUJOCO_DIR={mj}"],
        check=True, capture_output=True,
    )  # fmt: skip
    subprocess.run(["cmake", "--build", str(build), "-j2"], check=True, capture_output=True)
    env = dict(
        os.environ,
        LD_PRELOAD=_asan_runtime(),
        MJRFT_ENGINE_LIBRARY=str(build / "libmjrft_granular.so"),
        # CPython's own allocations are not instrumented; leaks at exit are Python's.
        ASAN_OPTIONS="detect_leaks=0:abort_on_error=1",
        UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1",
    )
    out = subprocess.run(
        [sys.executable, "-c", SCENES], env=env, capture_output=True, text=True, timeout=900
    )
    assert out.returncode == 0 and "sanitized scenes ok" in out.stdout, out.stderr[-4000:]
    assert str(build / "libmjrft_granular.so") in out.stdout  # the sanitized build ran them
    assert "runtime error" not in out.stderr
