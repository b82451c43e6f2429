"""Who owns ``xfrc_applied``: the user's part of each intruding body's row survives the field.

``xfrc_applied`` is user input that persists across steps (a controller, the interactive viewer's
perturbation). The installed field writes the intruding bodies' rows every forward pass, so per
MjData it remembers the user's part of each such row and what it wrote there (``FieldData.user``,
``FieldData.written``). A component that no longer holds what the field wrote was assigned by the
user, and that value becomes the user's part of that component; the other components keep their
user part. Then row = user + RFT. Per component, not per row: writing one component
(``d.xfrc_applied[b, 0] = push``) is an assignment of that component only, and must not turn the
RFT force left in the row's other components into a user force. A component assigned exactly the
value the field wrote there reads as unassigned, which changes nothing: the user part and the total
stay what they were. So user forces are never lost or counted twice, for any number of forward
passes per step, and leaving ``installed()`` restores the user's values.

A copy of a tracked MjData (``copy.copy``, ``mj_copyData``) carries rows the field wrote. To
recognise it, each pass also records (written, user) in the MjData's ring of its last
``XFRC_HISTORY`` writes; an MjData seen for the first time takes the user part of a matching
write of any MjData of the field (:func:`adopt`), or else its whole rows as the user's.
"""

from __future__ import annotations

import numba
import numpy as np

from mjrft.field.tables import unpack

#: How many past writes of xfrc_applied rows each MjData remembers, to recognise its copies.
XFRC_HISTORY = 4096


@numba.njit(cache=True)
def take_user_part(m_rec, e_rec):
    """Components of tagged rows that differ from what was written were assigned by the user:
    they become the user part (s.user) of that component."""
    m, d, s = unpack(m_rec, e_rec)
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        for c in range(6):
            if d.xfrc_applied[b, c] != s.written[b, c]:
                s.user[b, c] = d.xfrc_applied[b, c]


@numba.njit(cache=True)
def write_rows(m_rec, e_rec):
    """xfrc_applied = user + RFT on every tagged row (kept rows keep what stage 1 wrote), and
    remember what was written (s.written and the ring)."""
    m, d, s = unpack(m_rec, e_rec)
    ring_size = s.ring.shape[0] - 1
    slot = int(s.ring[0, 0, 0, 0]) % ring_size  # ring[0] holds the write counter
    for k in range(m.tbody_bodyid.shape[0]):
        b = m.tbody_bodyid[k]
        for c in range(6):
            total = d.xfrc_applied[b, c] if s.keep[k] else s.user[b, c] + s.wrench[b, c]
            d.xfrc_applied[b, c] = total
            s.written[b, c] = total
            s.ring[1 + slot, 0, k, c] = total
            s.ring[1 + slot, 1, k, c] = s.user[b, c]
    s.ring[0, 0, 0, 0] += 1.0


def adopt(current: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """User part (ntbody, 6) of the tagged rows ``current`` of an MjData seen for the first time.

    A copy of a tracked MjData carries rows the field wrote (user + RFT); rings hold the last
    writes of the field's MjData and the user part behind each. Rows matching none are all the
    user's.
    """
    for ring in rings:
        n = min(int(ring[0, 0, 0, 0]), ring.shape[0] - 1)
        if n:
            hits = np.flatnonzero(np.all(ring[1 : n + 1, 0] == current, axis=(1, 2)))
            if hits.size:
                return ring[1 + hits[-1], 1].copy()
    return current.copy()


def take(data, st, rows: np.ndarray, others: list) -> None:
    """First installed pass on an MjData: its tagged rows (body ids ``rows``) are the user's or,
    for a copy of a tracked MjData, the user part behind the write they carry (:func:`adopt`
    over the rings of the ``others``' states)."""
    current = np.array(data.xfrc_applied[rows])
    st.arrays.user[rows] = adopt(current, [o.arrays.ring for o in others if o is not st])
    st.arrays.written[rows] = current
    st.arrays.rk4[:] = 0.0
    st.owned = True


def user_part(data, st, rows: np.ndarray) -> np.ndarray:
    """(nbody, 6) xfrc_applied without the field's contribution: components that still hold
    what the field wrote show the user part, components assigned since show what was assigned."""
    out = np.array(data.xfrc_applied)
    if st is not None and st.owned:
        current = out[rows]
        out[rows] = np.where(current != st.arrays.written[rows], current, st.arrays.user[rows])
    return out
