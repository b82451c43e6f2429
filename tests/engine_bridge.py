"""The C++ engine's structs for tests: ``Tables`` and ``State`` views of a numba field's arrays.

The engine declares every array once (``engine/fields.h``); this module parses those lists and
builds the same structs as ctypes Structures, so a test can run a C++ stage on exactly the
arrays the compiled numba pass uses (``GranularField._tables.arrays``, a ``DataState``'s
``arrays``) and compare the two. mjModel and mjData go in as their addresses
(``model._address``).
"""

from __future__ import annotations

import ctypes
import os
import re
import subprocess
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / "engine"
BUILD = ROOT / "build" / "engine"
_TYPES = {"f64": (ctypes.c_double, np.float64), "i64": (ctypes.c_int64, np.int64)}


def _macro(name: str) -> str:
    text = (ENGINE / "fields.h").read_text()
    start = text.index(f"#define {name}(X)")
    body = []
    for line in text[start:].splitlines()[1:]:
        body.append(line)
        if not line.rstrip().endswith("\\"):
            break
    return "\n".join(body)


def table_sizes() -> list[str]:
    return re.findall(r"X\((\w+)\)", _macro("MJRFT_TABLE_SIZES"))


def table_scalars() -> list[tuple[str, str]]:
    return re.findall(r"X\((f64|i64), (\w+),", _macro("MJRFT_TABLE_SCALARS"))


def table_arrays() -> list[tuple[str, str]]:
    return re.findall(r"X\((f64|i64), (\w+),", _macro("MJRFT_TABLE_ARRAYS"))


def state_arrays() -> list[tuple[str, str]]:
    """(type, name) of the State's arrays: the persistent ones, then the work arrays."""
    return [
        *re.findall(r"X\((f64|i64), (\w+),", _macro("MJRFT_STATE_PERSISTENT")),
        *re.findall(r"X\((f64|i64), (\w+),", _macro("MJRFT_STATE_WORK")),
    ]


class Tables(ctypes.Structure):
    _fields_ = (
        [(n, ctypes.c_int64) for n in table_sizes()]
        + [(n, _TYPES[t][0]) for t, n in table_scalars()]
        + [(n, ctypes.c_void_p) for _, n in table_arrays()]
    )


class State(ctypes.Structure):
    _fields_ = [(n, ctypes.c_void_p) for _, n in state_arrays()]


def library(sanitize: bool = False) -> ctypes.CDLL:
    """Build (CMake, incremental) and load the engine library."""
    import mujoco

    build = BUILD.with_name("engine-asan") if sanitize else BUILD
    mj = os.path.dirname(mujoco.__file__)
    if not (build / "build.ninja").exists():
        subprocess.run(
            ["cmake", "-S", str(ENGINE), "-B", str(build), "-G", "Ninja", f"-DMUJOCO_DIR={mj}",
             f"-DMJRFT_SANITIZE={'ON' if sanitize else 'OFF'}"],
            check=True, capture_output=True,
        )  # fmt: skip
    subprocess.run(["cmake", "--build", str(build)], check=True, capture_output=True)
    return ctypes.CDLL(str(build / "libmjrft_granular.so"))


class Bridge:
    """ctypes Tables and State for one numba field and one of its MjData.

    tables: a ``Tables`` over ``field._tables.arrays`` (no copy). state: a ``State`` over copies
    of the MjData's ``FieldData`` arrays and soil block (``arrays``, by name), so the C++ stage
    runs beside the numba one on the same inputs without sharing outputs.
    """

    def __init__(self, field, data, copy: bool = True) -> None:
        fm = field._tables.arrays
        self.keep: list[np.ndarray] = []
        t = Tables()
        sizes = {
            "nelem": len(fm.elem_area), "ntgeom": len(fm.tgeom_geomid),
            "ntbody": len(fm.tbody_bodyid), "surface_nrow": fm.surface_grid.shape[0],
            "surface_ncol": fm.surface_grid.shape[1], "ncoef": len(fm.coef),
            "nvert": fm.elem_vert.shape[0], "nsoil": fm.nsoil,
        }  # fmt: skip
        for name in table_sizes():
            setattr(t, name, int(sizes[name]))
        for _, name in table_scalars():
            setattr(t, name, getattr(fm, name))
        for kind, name in table_arrays():
            a = np.ascontiguousarray(getattr(fm, name), dtype=_TYPES[kind][1])
            self.keep.append(a)
            setattr(t, name, a.ctypes.data)
        self.tables = t
        st = field._states.of(data)
        fd = st.arrays
        self.arrays: dict[str, np.ndarray] = {}
        s = State()
        for kind, name in state_arrays():
            if name == "xfrc_last":  # the engine's own record; the numba pass has none
                src = np.full_like(fd.user, np.nan)
            else:
                src = st.userdata if name == "soil" else getattr(fd, name)
            a = np.array(src, dtype=_TYPES[kind][1], order="C", copy=True) if copy else src
            self.arrays[name] = a
            setattr(s, name, a.ctypes.data)
        self.state = s
        self.field_state = st

    def pointers(self, model, data) -> tuple:
        """(mjModel*, mjData*, Tables*, State*) for a ctypes call."""
        return (
            ctypes.c_void_p(model._address), ctypes.c_void_p(data._address),
            ctypes.byref(self.tables), ctypes.byref(self.state),
        )  # fmt: skip
