"""benchmarks/stability.py's energy accounting, against analytic values.

The map's energy criterion is about the medium: the work of the user force that lowers
a body is taken off each step's energy change. Checked here on a body far above the medium under
gravity and a constant user force, where each integrator's energy change is known exactly.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "stability.py"


@pytest.fixture(scope="module")
def stability():
    spec = importlib.util.spec_from_file_location("mjrft_bench_stability", _PATH)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up by name
    spec.loader.exec_module(mod)
    yield mod
    sys.modules.pop(spec.name, None)


def _fly(stability, integrator, lift=2.0, steps=40):
    """A 10 g ellipsoid 1 m above the surface (a model without the engine plugin: no medium),
    pushed up by lift x its weight (world z) and sideways, no spin. Returns model, qpos, qvel,
    user force per step, the constant total force [N] and the body's mass [kg]."""
    m = mujoco.MjModel.from_xml_string(stability.scene_xml("ellipsoid", 0.01, 60))
    m.opt.timestep, m.opt.integrator = 0.005, stability.INTEGRATORS[integrator]
    d = mujoco.MjData(m)
    d.qpos[2] = 1.0
    d.qvel[:3] = [0.3, -0.2, 0.1]
    mass = float(m.body_mass[1])
    user = np.array([0.4, 0.1, lift]) * mass * 9.81
    qpos, qvel, user_f = [d.qpos.copy()], [d.qvel.copy()], [np.zeros(3)]
    for _ in range(steps):
        d.xfrc_applied[1, :3] = user
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
        user_f.append(user)
    total = user + mass * np.asarray(m.opt.gravity)
    return m, np.array(qpos), np.array(qvel), np.array(user_f), total, mass


# Round-off of energies ~0.1 J summed over 40 steps: far below the analytic terms checked.
ROUND_OFF_J = 1e-12


def test_user_work_is_taken_off_exactly_under_rk4(stability):
    """RK4 integrates a constant force exactly, so the mechanical energy changes by exactly the
    user force's work: the net gain is zero, and the raw gain is not."""
    m, qpos, qvel, user_f, _, _ = _fly(stability, "RK4")
    gain = np.diff(stability.mechanical_energy(m, 1, qpos, qvel))
    work = stability.user_work(m, 1, qpos, user_f)
    assert np.all(work > 1e-4)  # the lift does visible positive work every step
    np.testing.assert_allclose(gain - work, 0.0, atol=ROUND_OFF_J)


def test_semi_implicit_euler_loses_exactly_dt2_f2_over_2m(stability):
    """MuJoCo's Euler moves the position with the new velocity: per step the energy net of the
    user's work changes by -dt^2 |F|^2 / (2 m), F the total force (analytic)."""
    m, qpos, qvel, user_f, total, mass = _fly(stability, "Euler")
    net = np.diff(stability.mechanical_energy(m, 1, qpos, qvel))
    net -= stability.user_work(m, 1, qpos, user_f)
    expected = -(m.opt.timestep**2) * (total @ total) / (2.0 * mass)
    np.testing.assert_allclose(net, expected, rtol=1e-6, atol=ROUND_OFF_J)
