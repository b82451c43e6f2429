"""RK4's four forward passes per step: which stage a pass is, and what each body feels there.

MuJoCo's RK4 (``mj_RungeKutta``) runs its stages at t0, t0 + h/2, t0 + h/2, t0 + h, the stage
times computed as ``t0 + c h``; the same expressions here recognise them exactly. Stage 1 is
evaluated in full and records, per tagged body, how the later stages treat it (the MjData's RK4
record, ``FieldData.rk4``):

* ``RK4_PER_STAGE``: the pure model of each stage (a body moving freely);
* ``RK4_HOLD``: stage 1's wrench over the step, for a body the low-speed treatment stuck or
  slipped, or whose motion would reverse within ``lowspeed.RK4_HOLD_STEPS`` steps. Why: the
  time-stepping stick needs the force constant over the step to end it at rest (per stage it
  keeps 3/8 of the velocity), and RK4's stage combination does not damp a torque that jumps
  with the sign of a slow spin (docs/stability.md, "RK4");
* ``RK4_FROZEN``: the model at the stage's pose with stage 1's twist, plus stage 1's implicit
  correction, for a body moved by the linearly implicit step. Why not hold: across a slow motion
  RFT is stiff (its stages would overshoot, as the explicit step does), but along it the force
  changes with depth, and a held force lags it (a dropped 1 g sphere at 5 ms stopped 10.6 % too
  deep).

Any other pattern of passes (a user's ``mj_forward``, a new step at t0 + h) is evaluated afresh,
which is always safe.
"""

from __future__ import annotations

import numba

from mjrft.field.tables import RK4_BODY, RK4_HEAD

#: Modes of a body in the later stages of an RK4 step.
RK4_PER_STAGE, RK4_HOLD, RK4_FROZEN = 0.0, 1.0, 2.0


@numba.njit(cache=True)
def stage_held(t, h, rec):
    """True if a pass at time t [s] is stage 2, 3 or 4 of an RK4 step (timestep h [s]) whose
    stage 1 was evaluated; updates the record's head rec[:2] (time of the last evaluated pass,
    passes since)."""
    n = rec[1]
    if (n == 1.0 or n == 2.0) and t == rec[0] + 0.5 * h:
        rec[1] = n + 1.0
        return True
    if n == 3.0 and t == rec[0] + 1.0 * h:
        rec[1] = 4.0
        return True
    rec[0] = t
    rec[1] = 1.0
    return False


@numba.njit(cache=True)
def read_modes(rec, keep, frz):
    """Set keep[k] / frz[k] (int, per tagged body) from the modes stage 1 recorded."""
    for k in range(keep.shape[0]):
        mode = rec[RK4_HEAD + RK4_BODY * k]
        keep[k] = mode == RK4_HOLD
        frz[k] = mode == RK4_FROZEN


@numba.njit(cache=True)
def write_modes(rec, decision, slow, frozen, implicit):
    """Record each tagged body's mode for the later stages, and its stage-1 twist and implicit
    correction frozen (ntbody, 12), from its decision (``implicit``: lowspeed.IMPLICIT)."""
    for k in range(decision.shape[0]):
        blk = RK4_HEAD + RK4_BODY * k
        if decision[k] == implicit:
            rec[blk] = RK4_FROZEN
        else:
            rec[blk] = RK4_HOLD if slow[k] else RK4_PER_STAGE
        for c in range(12):
            rec[blk + 1 + c] = frozen[k, c]
