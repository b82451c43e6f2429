"""MuJoCo Warp worlds for the tests that hold the Warp path against the C++ engine
(tests/test_warp.py, test_warp_lowspeed.py, test_warp_soil.py). Import after
``pytest.importorskip("mujoco_warp")``."""

from __future__ import annotations

import mujoco_warp as mjw
import numpy as np


def put(mjm, mjd, qpos, qvel):
    """MuJoCo Warp's model of mjm and data of len(qpos) worlds at qpos, qvel (nworld, nq / nv),
    set in float32 from mjd's other fields."""
    m = mjw.put_model(mjm)
    d = mjw.put_data(mjm, mjd, nworld=len(qpos))
    d.qpos.assign(qpos.astype(np.float32))
    d.qvel.assign(qvel.astype(np.float32))
    return m, d


def world_kinematics(mjd, d, w):
    """Put world w's MuJoCo Warp kinematics into mjd (float32 values, held in float64)."""
    for name in ("xpos", "xmat", "xipos", "ximat", "cvel", "subtree_com", "geom_xpos"):
        dst = getattr(mjd, name)
        dst[:] = getattr(d, name).numpy()[w].reshape(dst.shape)
