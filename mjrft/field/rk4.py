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

A free body evaluated per stage (RK4_PER_STAGE or RK4_FROZEN) keeps that only while the step
stays dissipative: at each later stage, the step completed with that stage's wrench is balanced
(:func:`step_balance`), and where it would add energy the body holds stage 1's wrench from that
stage on. Why: the force depends on the direction of motion and on which triangles are in the
medium, so it can jump between stages (an edge dipping in at the half step, a slow spin whose
direction turns), and RK4's combination of such stages is not bounded by any one of them (a
5 kg prism gained 0.4 % of its energy in one step; docs/stability.md, "Thrown bodies"). Holding
stage 1's wrench is safe: stage 1 checked it (``lowspeed.adds_no_energy``).

Any other pattern of passes (a user's ``mj_forward``, a new step at t0 + h) is evaluated afresh,
which is always safe.
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.field.lowspeed import ROUNDING, free_body_terms, has_inertia, mv
from mjrft.field.tables import RK4_BODY, RK4_HEAD, unpack

#: Modes of a body in the later stages of an RK4 step.
RK4_PER_STAGE, RK4_HOLD, RK4_FROZEN = 0.0, 1.0, 2.0
# A body's block of the record (RK4_BODY values): its mode, then stage 1's twist and implicit
# correction (12, RK4_FROZEN), then for the energy guard of the free bodies not held: stage 1's
# wrench, the weighted sum of the wrenches applied so far, the sum of the forces of stages 2-4
# so far, stage 1's twist, other wrenches and inverse world inertia (3, 3, row-major).
_W1, _ACC, _LIN, _TWIST, _OTHER, _II = 13, 19, 25, 28, 34, 40
# RK4's stage weights (1, 2, 2, 1) / 6 times 6, by pass number 1-4; and per pass n the summed
# weight of passes n..4 (a stage's wrench continued to the end of the step).
_WEIGHT = (0.0, 1.0, 2.0, 2.0, 1.0)
_REST_WEIGHT = (0.0, 6.0, 5.0, 3.0, 1.0)
_JIT = {"cache": True, "error_model": "numpy"}


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


@numba.njit(inline="always", **_JIT)
def guarded(m, s, k, blk):
    """True if tagged body k (record block blk) is a free body its RK4 step evaluates per
    stage, which the energy guard watches."""
    return s.rk4[blk] != RK4_HOLD and m.tbody_treat[k] != 0 and has_inertia(m, m.tbody_bodyid[k])


@numba.njit(**_JIT)
def begin_step(m_rec, e_rec):
    """Stage 1 of an RK4 step: record, for each free body evaluated per stage (not held), what
    the energy guard of the later stages needs (:func:`guard_stage`)."""
    m, d, s = unpack(m_rec, e_rec)
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        blk = RK4_HEAD + RK4_BODY * k
        if not guarded(m, s, k, blk):
            continue
        twist, other, _, ii, _ = free_body_terms(m, d, k, s.user[b])
        for c in range(6):
            s.rk4[blk + _W1 + c] = s.wrench[b, c]
            s.rk4[blk + _ACC + c] = s.wrench[b, c]
            s.rk4[blk + _TWIST + c] = twist[c]
            s.rk4[blk + _OTHER + c] = other[c]
        for c in range(3):
            s.rk4[blk + _LIN + c] = 0.0
        for c in range(9):
            s.rk4[blk + _II + c] = ii[c // 3, c % 3]


@numba.njit(**_JIT)
def step_balance(blk, w, n, mass, h):
    """The energy [J] / h an RK4 step adds with the wrenches applied in its passes before pass
    n (2-4) and w (6,) in pass n and after it, and the sum of the magnitudes of its terms.

    RK4 ends the step at v1 = v0 + h/6 (a1 + 2 a2 + 2 a3 + a4) and x1 = x0 + h v0 + h^2/6 (a1 +
    a2 + a3) (its stage velocities are v0 + h/2 a1, v0 + h/2 a2, v0 + h a3), so with constant
    other forces f_o the medium's forces F_j add, beyond the step without them, exactly
    ``h (F . v0 + h/(2m) |F|^2 + h/(6m) f_o . (F2 + F3 + F4))``, F = (F1 + 2 F2 + 2 F3 + F4)/6;
    the rotation (no potential) adds ``h (T . w0 + h/2 T . I^-1 T + h t_o . I^-1 T)``, with stage
    1's inertia and gyroscopic torque t_o. blk: the body's record block; world frame; mass [kg].
    """
    rest = _REST_WEIGHT[n]
    count = 5.0 - n
    wbar = np.empty(6)
    for c in range(6):
        wbar[c] = (blk[_ACC + c] + rest * w[c]) / 6.0
    ii = blk[_II : _II + 9].reshape(3, 3)
    itau = mv(ii, wbar[3:])
    p = 0.0
    size = 0.0
    for c in range(6):
        p += wbar[c] * blk[_TWIST + c]
        size += abs(wbar[c] * blk[_TWIST + c])
    for c in range(3):
        quad = 0.5 * h * (wbar[c] * wbar[c] / mass + wbar[3 + c] * itau[c])
        lin = h * blk[_OTHER + c] * (blk[_LIN + c] + count * w[c]) / (6.0 * mass)
        rot = h * blk[_OTHER + 3 + c] * itau[c]
        p += quad + lin + rot
        size += abs(quad) + abs(lin) + abs(rot)
    return p, size


@numba.njit(**_JIT)
def guard_stage(m_rec, e_rec):
    """Stages 2-4 of an RK4 step: a free body evaluated per stage (not held) keeps this stage's
    wrench if the step completed with it adds no energy (:func:`step_balance`), else it
    holds stage 1's wrench from this stage on (RK4_HOLD). Returns the number of bodies held."""
    m, _, s = unpack(m_rec, e_rec)
    n = int(s.rk4[1])
    h = m.opt_timestep[0]
    held = 0
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        blk = RK4_HEAD + RK4_BODY * k
        if not guarded(m, s, k, blk):
            continue
        record = s.rk4[blk : blk + RK4_BODY]
        w = s.wrench[b]
        p, size = step_balance(record, w, n, m.body_mass[b], h)
        if p > ROUNDING * size:
            for c in range(6):
                w[c] = record[_W1 + c]
            record[0] = RK4_HOLD
            held += 1
        for c in range(6):
            record[_ACC + c] += _WEIGHT[n] * w[c]
        for c in range(3):
            record[_LIN + c] += w[c]
    return held
