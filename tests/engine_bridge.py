"""The engine's ``Tables`` struct (engine/tables.h) as a ctypes Structure, for tests that call one
stage of the engine through its C test entry points (engine/testing_*.cc).

The layout is the library's own (``mjrft.core.engine.layout``: the names and types of
engine/fields.h, in order), so it is declared once.
"""

from __future__ import annotations

import ctypes

from mjrft.core import engine

_CTYPES = {"f64": ctypes.c_double, "i64": ctypes.c_int64}


def _tables_type() -> type[ctypes.Structure]:
    lay = engine.layout()
    fields = (
        [(name, ctypes.c_int64) for name in lay.sizes]
        + [(name, _CTYPES[kind]) for kind, name in lay.scalars]
        + [(name, ctypes.c_void_p) for _, name in lay.arrays]
    )
    return type("Tables", (ctypes.Structure,), {"_fields_": fields})


Tables = _tables_type()


def tables_of(tables: dict) -> ctypes.Structure:
    """A ``Tables`` over a field's engine tables (``GranularField._tables``: sizes and scalars
    by name, arrays as C-contiguous NumPy arrays, kept alive by the caller)."""
    lay, t = engine.layout(), Tables()
    for name in lay.sizes:
        setattr(t, name, int(tables[name]))
    for _, name in lay.scalars:
        setattr(t, name, tables[name])
    for _, name in lay.arrays:
        setattr(t, name, tables[name].ctypes.data)
    return t
