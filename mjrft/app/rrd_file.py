"""Recordings cut short (a full disk, SIGKILL, a crash): find and keep their complete messages.

An ``.rrd`` file of rerun 0.41 is a 12-byte header (``RRF2``, the writer's version, options),
then messages, each a 16-byte header (kind, payload length: two little-endian u64) and its
payload, then an end message (kind 0) whose payload is the file's manifest, and a 32-byte
trailer (the manifest's offset and length, a checksum, ``RRF2FOOT``, a 4-byte version). A
writer stopped mid-file leaves no end message and no trailer, and often a last message cut in
two; rerun's reader then refuses the whole file ("Message payload ... exceeds file size").
Without the manifest the reader falls back to scanning the messages in order, so the file's
complete messages, alone, read back: that prefix is what ``salvage`` writes. Pure file
handling: imports nothing of rerun.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

#: Magic bytes at the start of an .rrd file and in its trailer.
MAGIC = b"RRF2"
TRAILER_MAGIC = b"RRF2FOOT"
#: Bytes of the file header, of a message header and of the trailer.
HEADER_BYTES, MESSAGE_HEADER_BYTES, TRAILER_BYTES = 12, 16, 32
#: Message kind of the end-of-stream message (its payload: the manifest).
END_KIND = 0


@dataclass(frozen=True)
class Scan:
    """What an .rrd file holds.

    Attributes: size (bytes of the file); complete (bytes of the header and the complete data
    messages, in order); messages (number of complete data messages); finished (the file ends
    with its end message and trailer, as rerun leaves it when the recording is closed).
    """

    size: int
    complete: int
    messages: int
    finished: bool


def scan(path: str | os.PathLike) -> Scan:
    """Walk the messages of the .rrd file at `path` (reading only their 16-byte headers).

    Raises ValueError if the file does not start as an .rrd file of this framing.
    """
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(HEADER_BYTES)
        if len(head) < HEADER_BYTES or head[:4] != MAGIC:
            raise ValueError(
                f"{str(path)!r} is not a rerun recording: an .rrd file starts with {MAGIC!r} "
                f"(this one with {head[:4]!r})"
            )
        offset, messages, finished = HEADER_BYTES, 0, False
        while offset + MESSAGE_HEADER_BYTES <= size:
            fh.seek(offset)
            kind, length = struct.unpack("<QQ", fh.read(MESSAGE_HEADER_BYTES))
            end = offset + MESSAGE_HEADER_BYTES + length
            if end > size:
                break  # the last message was cut
            if kind == END_KIND:
                fh.seek(size - TRAILER_BYTES)
                finished = end + TRAILER_BYTES == size and fh.read(TRAILER_BYTES)[20:28] == (
                    TRAILER_MAGIC
                )
                break
            offset, messages = end, messages + 1
    return Scan(size, offset, messages, finished)


def salvage(path: str | os.PathLike, out: str | os.PathLike) -> Scan:
    """Write the header and the complete data messages of the .rrd file at `path` to `out`.

    Returns the scan of `path`. The copy has no manifest; rerun reads it by scanning (every
    complete message, so every row logged before the file was cut, up to the writer's last
    flush). Raises ValueError if `path` is not an .rrd file or holds no complete message, or if
    `out` is `path`.
    """
    path, out = Path(path), Path(out)
    if out.resolve() == path.resolve():
        raise ValueError(f"salvage {str(path)!r}: the copy must go to another file")
    s = scan(path)
    if s.messages == 0:
        raise ValueError(f"{str(path)!r} holds no complete message: nothing to salvage")
    with open(path, "rb") as src, open(out, "wb") as dst:
        remaining = s.complete
        while remaining:
            block = src.read(min(remaining, 1 << 20))
            dst.write(block)
            remaining -= len(block)
    return s


def salvaged_name(path: str | os.PathLike) -> Path:
    """Where ``mjrft view-recording`` puts the salvaged copy of `path`: '<stem>.salvaged.rrd'."""
    path = Path(path)
    return path.with_name(f"{path.stem}.salvaged{path.suffix or '.rrd'}")
