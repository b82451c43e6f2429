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

from mjrft.field import lowspeed, ownership, rk4
from mjrft.field.evaluate import first_bad_body, pure_wrenches, twist_wrench
from mjrft.field.tables import MjDataArrays, unpack_entry, unpack_model

INSTALLED, EXPLICIT, BATCH, QUERY = 0, 1, 2, 3
#: Status of a pass: OK, or -1 - k where tagged body k has a non-finite position or velocity.
OK = 0
_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(**_JIT)
def frozen_wrenches(m, d, s):
    """Bodies moved by the implicit step feel, in RK4's later stages, the model at the stage's
    pose with stage 1's twist plus stage 1's correction (rk4.RK4_FROZEN). Returns (#evaluated,
    #acting)."""
    evaluated = 0
    acting = 0
    for k in range(m.tbody_bodyid.shape[0]):
        if not s.frz[k]:
            continue
        b = m.tbody_bodyid[k]
        blk = rk4.RK4_HEAD + rk4.RK4_BODY * k
        ne, na = twist_wrench(m, d, s, k, s.rk4[blk + 1 : blk + 4], s.rk4[blk + 4 : blk + 7],
                              s.wrench[b])  # fmt: skip
        if ne > 0:  # in play: the correction acts where the model does
            for c in range(6):
                s.wrench[b, c] += s.rk4[blk + 7 + c]
        evaluated += ne
        acting += na
    return evaluated, acting


@numba.njit(**_JIT)
def forward(m, d, s, user, mode):
    """One pass of the field on one MjData; returns OK or -1 - (bad tagged body).

    user (nbody, 6): the other applied wrenches the treatment balances (s.user once the
    installed path has taken the user part). Writes s.wrench, s.elem_force, s.decision and, when
    installed, xfrc_applied and the RK4 record.
    """
    bad = first_bad_body(m, d)
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
    evaluated, acting = pure_wrenches(m, d, s)
    if held:
        ne, na = frozen_wrenches(m, d, s)
        evaluated += ne
        acting += na
    if mode != QUERY:
        if evaluated or not held:
            s.stats[0] += 1
        s.stats[1] += evaluated
        s.stats[2] += acting
    if mode == INSTALLED:
        ownership.take_user_part(m, d, s)
    if not held and mode != QUERY:  # a held stage keeps its step's decisions
        s.decision[:] = lowspeed.PURE
        s.frozen[:] = 0.0
        if m.treat:
            lowspeed.treat_all(m, d, s, user)
        if mode == INSTALLED:
            rk4.write_modes(s.rk4, s.decision, s.slow, s.frozen, lowspeed.IMPLICIT)
    if mode == INSTALLED:
        ownership.write_rows(m, d, s)
    if mode == INSTALLED or mode == EXPLICIT:
        report(m, s, mode == INSTALLED)
    return OK


@numba.njit(**_JIT)
def report(m, s, wrench):
    """Copy this pass's decisions (and wrenches) to the field's shared report arrays."""
    for k in range(m.tbody_bodyid.shape[0]):
        s.report_decision[k] = s.decision[k]
        if wrench:
            b = m.tbody_bodyid[k]
            for c in range(6):
                s.report_wrench[b, c] = s.wrench[b, c]


@numba.njit(**_JIT)
def step(model_address, entry_address, mode):
    """One pass (``forward``) on the MjData whose entry record is at entry_address."""
    m = unpack_model(model_address)
    d, s = unpack_entry(m, entry_address)
    user = s.user if mode == INSTALLED else s.user_in
    return forward(m, d, s, user, mode)


@numba.njit(cache=True, error_model="numpy", nogil=True)
def batch(model_address, entry_address, xpos, xmat, xipos, ximat, cvel, subtree_com, geom_xpos,
          user_xfrc, out):  # fmt: skip
    """RFT wrenches of many simulations of one model: ``forward`` in BATCH mode on each copy.

    xpos (S, nbody, 3), xmat (S, nbody, 9), xipos (S, nbody, 3), ximat (S, nbody, 9),
    cvel (S, nbody, 6), subtree_com (S, nbody, 3), geom_xpos (S, ngeom, 3): bound MjData
    fields, world frame. user_xfrc (S, nbody, 6): the user's applied wrenches. out (S, nbody,
    6): each body's RFT force and torque at its CoM. entry_address: this thread's FieldData
    (its work arrays and counters; the GIL is released, so threads run disjoint copies). Returns
    OK, or -1 - s for the first simulation s whose state is not finite.
    """
    m = unpack_model(model_address)
    _, s = unpack_entry(m, entry_address)
    time = np.zeros(1)  # unused in BATCH mode
    out[:] = 0.0
    for sim in range(xpos.shape[0]):
        d = MjDataArrays(
            xpos[sim], xmat[sim].reshape((-1, 3, 3)), xipos[sim], ximat[sim].reshape((-1, 3, 3)),
            cvel[sim], subtree_com[sim], geom_xpos[sim], time, out[sim],
        )  # fmt: skip
        if first_bad_body(m, d) >= 0:
            return -1 - sim
    for sim in range(xpos.shape[0]):
        d = MjDataArrays(
            xpos[sim], xmat[sim].reshape((-1, 3, 3)), xipos[sim], ximat[sim].reshape((-1, 3, 3)),
            cvel[sim], subtree_com[sim], geom_xpos[sim], time, out[sim],
        )  # fmt: skip
        forward(m, d, s, user_xfrc[sim], BATCH)
        for k in range(m.tbody_bodyid.shape[0]):
            b = m.tbody_bodyid[k]
            for c in range(6):
                out[sim, b, c] = s.wrench[b, c]
    return OK
