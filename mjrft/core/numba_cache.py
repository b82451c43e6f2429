"""Keep numba's on-disk cache of mjrft's compiled functions consistent with their sources.

numba (``cache=True``) invalidates a cached function when the file defining it changes, but not
when a function it calls, defined in another file, changes: the cached caller keeps running the
old callee. mjrft's compiled pass calls across modules (``mjrft.field.passive`` calls
``lowspeed``, ``ownership``, ``evaluate`` and ``mjrft.core.kernel``), so after editing any of
them the cache would be stale. ``refresh`` hashes the sources of every module with compiled
functions and, when the hash differs from the one recorded beside the cache, deletes mjrft's
cache files so that everything recompiles once. Installed copies never change, so this only
matters in a working tree; where the package folder is not writable nothing is done (numba then
caches elsewhere, keyed by the installed files).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]
#: Folders (relative to the package) whose modules define compiled functions.
_COMPILED = ("core", "field")
#: Modules without compiled functions whose constants compiled code reads (numba freezes
#: module-level constants into the machine code). Every module that mentions numba counts too;
#: the rest (geometry, materials, the NumPy evaluation) only call compiled code.
_CONSTANTS = ("law.py", "quadrature.py")
_STAMP = _PACKAGE / "__pycache__" / "numba-sources.sha256"


def _digest() -> str:
    h = hashlib.sha256()
    for folder in _COMPILED:
        for path in sorted((_PACKAGE / folder).glob("*.py")):
            source = path.read_bytes()
            if b"numba" in source or path.name in _CONSTANTS:
                h.update(path.name.encode())
                h.update(source)
    return h.hexdigest()


def refresh() -> bool:
    """Delete mjrft's numba cache files if the compiled modules' sources changed since they were
    written; returns True if it deleted them."""
    try:
        digest = _digest()
        if _STAMP.exists() and _STAMP.read_text() == digest:
            return False
        for folder in _COMPILED:
            for cached in (_PACKAGE / folder / "__pycache__").glob("*.nb[ic]"):
                cached.unlink()
        _STAMP.parent.mkdir(exist_ok=True)
        _STAMP.write_text(digest)
        return True
    except OSError:  # a read-only installation: numba keys its cache by the installed files
        return False
