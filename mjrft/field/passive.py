"""The field's forward pass, compiled: the one implementation every path runs.

``step(model_address, entry_address, mode)`` is one pass on one MjData: the native guard in
MuJoCo's passive callback calls it (``mjrft.field.guard``), Python calls it for the explicit path
and for queries, and ``batch`` calls the same ``forward`` for every copy of a batch. Modes:

* ``INSTALLED``: inside ``mj_step``/``mj_forward``: the RK4 stage rule, then
  ``xfrc_applied`` ownership (intruding rows = user part + RFT);
* ``EXPLICIT``: the wrench of the current state, the treatment balancing ``s.user_in``; reads
  and writes nothing of the MjData (``GranularField.wrench``);
* ``BATCH``: as EXPLICIT, for one copy of a batch (no report to the field);
* ``QUERY``: the pure model only (``GranularField.element_states``).
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.field import deform, lowspeed, mechanism, ownership, rk4
from mjrft.field.evaluate import first_bad_body, pure_wrenches, twist_wrench
from mjrft.field.tables import ENTRY_SIZE, unpack

INSTALLED, EXPLICIT, BATCH, QUERY = 0, 1, 2, 3
#: Status of a pass: OK, or -1 - k where tagged body k has a non-finite position or velocity,
#: or BELOW_GROUND - k where it reaches below the deforming ground's bottom (mjrft:region zmin).
OK = 0
BELOW_GROUND = -1_000_000
_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(**_JIT)
def frozen_wrenches(m_rec, e_rec):
    """Bodies moved by the implicit step feel, in RK4's later stages, the model at the stage's
    pose with stage 1's twist plus stage 1's correction (rk4.RK4_FROZEN). Returns (#evaluated,
    #acting)."""
    m, _, s = unpack(m_rec, e_rec)
    evaluated = 0
    acting = 0
    for k in range(m.tbody_bodyid.shape[0]):
        if not s.frz[k]:
            continue
        b = m.tbody_bodyid[k]
        blk = rk4.RK4_HEAD + rk4.RK4_BODY * k
        v, omega = s.rk4[blk + 1 : blk + 4], s.rk4[blk + 4 : blk + 7]
        ne, na = twist_wrench(m_rec, e_rec, k, v, omega, s.wrench[b])
        if ne > 0:  # in play: the correction acts where the model does
            for c in range(6):
                s.wrench[b, c] += s.rk4[blk + 7 + c]
        evaluated += ne
        acting += na
    return evaluated, acting


@numba.njit(**_JIT)
def forward(m_rec, e_rec, mode):
    """One pass of the field on one MjData; returns OK or a failure status (``OK``).

    m_rec, e_rec: addresses of the field's model record and the MjData's entry record
    (``mjrft.field.tables``). The treatment balances the user part of xfrc_applied (INSTALLED)
    or s.user_in (the other modes). Writes s.wrench, s.elem_force, s.decision and, when
    installed, xfrc_applied and the RK4 record.
    """
    m, d, s = unpack(m_rec, e_rec)
    bad = first_bad_body(m_rec, e_rec)
    s.status[0] = OK if bad < 0 else -1 - bad
    if bad >= 0:  # refuse to feed a non-finite state forward (Python names the body)
        return s.status[0]
    s.cull[:] = 0
    s.keep[:] = 0
    s.frz[:] = 0
    s.slow[:] = 0
    held = False
    if mode == INSTALLED and m.opt_integrator[0] == m.int_rk4:
        held = rk4.stage_held(d.time[0], m.opt_timestep[0], s.rk4)
        if held:
            rk4.read_modes(s.rk4, s.keep, s.frz)
    if m.soil and mode != QUERY and not held and deform.due(m, d):
        below = deform.update(m_rec, e_rec)
        if below >= 0:
            s.status[0] = BELOW_GROUND - below
            return s.status[0]
    evaluated, acting = pure_wrenches(m_rec, e_rec)
    if held:
        ne, na = frozen_wrenches(m_rec, e_rec)
        evaluated += ne
        acting += na
        if m.treat:
            rk4.guard_stage(m_rec, e_rec)
    if mode != QUERY:
        if evaluated or not held:
            s.stats[0] += 1
        s.stats[1] += evaluated
        s.stats[2] += acting
    if mode == INSTALLED:
        ownership.take_user_part(m_rec, e_rec)
    if not held and mode != QUERY:  # a held stage keeps its step's decisions
        s.decision[:] = lowspeed.PURE
        s.frozen[:] = 0.0
        if m.treat:
            lowspeed.treat_all(m_rec, e_rec, s.user if mode == INSTALLED else s.user_in)
        if m.mech and mode == INSTALLED:
            mechanism.treat_mechanisms(m_rec, e_rec)
        if mode == INSTALLED:
            rk4.write_modes(s.rk4, s.decision, s.slow, s.frozen, lowspeed.IMPLICIT)
            if m.treat and m.opt_integrator[0] == m.int_rk4:
                rk4.begin_step(m_rec, e_rec)
    if mode == INSTALLED:
        ownership.write_rows(m_rec, e_rec)
    if mode == INSTALLED or mode == EXPLICIT:
        report(s.decision, s.wrench, m.tbody_bodyid, s.report_decision, s.report_wrench,
               mode == INSTALLED)  # fmt: skip
    return OK


@numba.njit(**_JIT)
def report(decision, wrench, bodyid, report_decision, report_wrench, with_wrench):
    """Copy this pass's decisions (and wrenches) to the field's shared report arrays."""
    for k in range(bodyid.shape[0]):
        report_decision[k] = decision[k]
        if with_wrench:
            for c in range(6):
                report_wrench[bodyid[k], c] = wrench[bodyid[k], c]


@numba.njit(**_JIT)
def step(m_rec, e_rec, mode):
    """One pass (``forward``) on the MjData whose entry record is at e_rec."""
    return forward(m_rec, e_rec, mode)


@numba.njit(cache=True, error_model="numpy", nogil=True)
def batch(m_rec, entries, n, mode):
    """``forward`` on n simulations of one model, one after the other (the GIL is released, so
    threads may run disjoint sets of them).

    entries: address of n consecutive entry records, one per simulation (``ENTRY_RECORD``),
    whose MjData arrays are that simulation's rows of the batch, ``user_in`` its user wrenches
    and ``wrench`` its output rows; their other FieldData arrays are one thread's work arrays.
    mode: BATCH (an argument rather than the constant, so that numba compiles ``forward`` once
    for every caller instead of once per literal mode). Returns OK, or -1 - i for the first
    simulation i whose state is not finite (then no wrench is written) or whose pass failed
    (an intruder below the deforming ground's bottom).
    """
    size = np.uint64(ENTRY_SIZE)
    for i in range(n):
        if first_bad_body(m_rec, entries + np.uint64(i) * size) >= 0:
            return -1 - i
    for i in range(n):
        if forward(m_rec, entries + np.uint64(i) * size, mode) != OK:
            return -1 - i
    return OK
