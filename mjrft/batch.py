"""Many copies of one granular scene stepped together on MuJoCo's threaded batch.

``mujoco.batch.Batch`` steps many simulations of one model on a thread pool and refuses Python
callbacks, so here the granular forces enter the way the design card describes for batches:
through ``xfrc_applied`` between steps. Each substep: one native call computes the RFT wrenches of
every copy from the bound position- and velocity-stage fields (``mjrft._native.batch_wrench``),
``xfrc_applied = user + RFT`` is written, and the batch steps with ``stage=mjSTAGE_VEL``, which
leaves those fields current at the new state (a persistent batch then continues from them, so
this costs no extra forward pass).
This is the explicit path of ``mjrft.field`` for every copy (the force is evaluated at the state
at the start of the substep and held over it), and gives the same trajectories as that path on
single MjData (tests/test_batch.py).
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco.batch import Batch

from mjrft import _native
from mjrft.field import GranularField


class BatchedField:
    """A GranularField applied to ``nsim`` simulations of its model on ``nthread`` threads.

    Args:
      field: the field (its model is the batch's model; Fourier-form materials only).
      nsim: number of simulations (copies); they may differ in state and controls.
      nthread: threads for MuJoCo's batch (default: all cores).
    Attributes:
      batch: the underlying ``mujoco.batch.Batch``: set initial states and controls through it
        (``batch.qpos``, ``batch.ctrl``, ``batch.reset(key=...)``).
      user_xfrc: (nsim, nbody, 6) your own applied forces [N, N m], world frame, at each body's
        CoM; the RFT wrench is added to it every substep (``xfrc_applied`` itself is rewritten).
      wrench: (nsim, nbody, 6) RFT wrenches of the last substep.
    """

    _DERIVED = ("xpos", "xmat", "xipos", "ximat", "cvel", "subtree_com", "geom_xpos")

    def __init__(self, field: GranularField, nsim: int, nthread: int | None = None) -> None:
        if field._table is None:
            raise ValueError(
                f"material {field.material.name!r} is given by Python callables; batched "
                "stepping needs a Fourier-form material (a preset, a table, or zeta)"
            )
        if nsim < 1:
            raise ValueError(f"nsim must be >= 1, got {nsim}")
        self.field = field
        self.model = field.model
        kw = {} if nthread is None else {"nthread": nthread}
        self.batch = Batch(self.model, nsim=nsim, persistent=True, **kw)
        self._arrays = {name: self.batch.bind(name) for name in self._DERIVED}
        self._xfrc = self.batch.bind("xfrc_applied")
        self.user_xfrc = np.zeros_like(self._xfrc)
        self.wrench = np.zeros_like(self._xfrc)

    @property
    def nsim(self) -> int:
        """Number of simulations."""
        return self.batch.nsim

    def reset(self, keyframe: int | np.ndarray = -1) -> None:
        """Reset every simulation (to a keyframe, one each, or -1: model defaults)."""
        self.batch.reset(keyframe=keyframe)

    def forward(self) -> None:
        """Make the derived fields current after you write states (qpos, qvel, act) directly."""
        self.batch.forward(stage=mujoco.mjtStage.mjSTAGE_VEL.value)

    def step(self, nstep: int = 1) -> None:
        """Advance every simulation by nstep substeps with granular forces acting in each.

        The derived fields must describe the current states: they do after ``reset``, ``step``
        and ``forward``; call ``forward`` after writing states yourself.
        """
        vel = mujoco.mjtStage.mjSTAGE_VEL.value
        for _ in range(nstep):
            a = self._arrays
            status = _native.batch_wrench(
                self.field._table.ctypes.data, a["xpos"], a["xmat"], a["xipos"], a["ximat"],
                a["cvel"], a["subtree_com"], a["geom_xpos"], self.user_xfrc, self.wrench,
            )  # fmt: skip
            if status != _native.OK:
                sim = -1 - status
                raise FloatingPointError(
                    f"simulation {sim} of the batch has a non-finite intruding-body state at "
                    f"time {float(self.batch.bind('time')[sim]):.6g} s; the granular field "
                    "refuses to feed NaN forward"
                )
            np.add(self.user_xfrc, self.wrench, out=self._xfrc)
            self.batch.step(stage=vel)


def single_step_reference(
    field: GranularField, data: mujoco.MjData, user: np.ndarray | None = None
) -> None:
    """The single-MjData explicit path a BatchedField substep reproduces (for tests/benchmarks).

    mj_forward; xfrc_applied = user + field.wrench(data); mj_step.
    """
    mujoco.mj_forward(field.model, data)
    u = np.zeros((field.model.nbody, 6)) if user is None else user
    data.xfrc_applied[:] = u + field.wrench(data, user_xfrc=u)
    mujoco.mj_step(field.model, data)
