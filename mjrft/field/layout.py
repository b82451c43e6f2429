"""Where MuJoCo keeps the scalars the compiled pass reads: exact struct offsets, checked at load.

The compiled pass reads a few MjModel/MjData fields live on every forward pass (a user may change
``opt.timestep`` or ``opt.integrator`` between steps). Arrays come as NumPy views, but scalars
such as ``opt.timestep`` and ``data.time`` have no view, so their addresses are computed here
from the struct declarations MuJoCo ships (``mujoco.introspect.structs``): a ``ctypes``
structure built from the declared fields in order gives each field's offset, exactly as the C
compiler lays them out. This is the only module that computes addresses inside MuJoCo's structs;
every address is checked against the binding's own values the first time it is used, with an
error that names the MuJoCo version if the declarations and the library disagree.
"""

from __future__ import annotations

import ctypes
import functools

import mujoco
import numpy as np
from mujoco.introspect import ast_nodes, structs

_SCALARS = {
    "mjtNum": ctypes.c_double,
    "double": ctypes.c_double,
    "float": ctypes.c_float,
    "mjtFloat": ctypes.c_float,
    "int": ctypes.c_int,
    "unsigned int": ctypes.c_uint,
    "mjtSize": ctypes.c_int64,
    "int64_t": ctypes.c_int64,
    "uint64_t": ctypes.c_uint64,
    "size_t": ctypes.c_size_t,
    "uintptr_t": ctypes.c_size_t,
    "mjtBool": ctypes.c_ubyte,
    "mjtByte": ctypes.c_ubyte,
    "unsigned char": ctypes.c_ubyte,
    "char": ctypes.c_char,
}


class LayoutError(RuntimeError):
    """MuJoCo's declared struct layout does not match the loaded library."""


def _ctype(decl: object) -> type:
    if isinstance(decl, ast_nodes.PointerType):
        return ctypes.c_void_p
    if isinstance(decl, ast_nodes.ArrayType):
        inner = _ctype(decl.inner_type)
        for extent in reversed(decl.extents):
            inner = inner * extent
        return inner
    if isinstance(decl, ast_nodes.AnonymousStructDecl):
        return _compose(f"anonymous_{id(decl)}", decl.fields, ctypes.Structure)
    if isinstance(decl, ast_nodes.AnonymousUnionDecl):
        return _compose(f"anonymous_{id(decl)}", decl.fields, ctypes.Union)
    if isinstance(decl, ast_nodes.ValueType):
        if decl.name in _SCALARS:
            return _SCALARS[decl.name]
        if decl.name in structs.STRUCTS:
            return struct(decl.name)
        if decl.name.startswith("mjt"):  # enums
            return ctypes.c_int
    raise LayoutError(
        f"unknown C type {decl!r} in MuJoCo {mujoco.__version__}'s struct declarations"
    )


def _compose(name: str, fields, base: type) -> type:
    return type(name, (base,), {"_fields_": [(f.name, _ctype(f.type)) for f in fields]})


@functools.cache
def struct(name: str) -> type:
    """A ctypes structure with the layout of MuJoCo's struct ``name`` (e.g. "mjModel")."""
    return _compose(name, structs.STRUCTS[name].fields, ctypes.Structure)


def offset(name: str, field: str) -> int:
    """Byte offset of ``field`` in MuJoCo's struct ``name``."""
    return getattr(struct(name), field).offset


def _fail(what: str) -> LayoutError:
    return LayoutError(
        f"{what}: MuJoCo {mujoco.__version__}'s struct declarations (mujoco.introspect) do not "
        "match the loaded library; mjrft supports the mujoco versions pinned in its pyproject"
    )


def model_addresses(model: mujoco.MjModel) -> dict[str, int]:
    """Addresses of the live MjModel scalars the pass reads: ``opt_timestep`` (float64),
    ``opt_disableflags`` and ``opt_integrator`` (int32); checked against the binding."""
    opt = model._address + offset("mjModel", "opt")
    out = {
        "opt_timestep": opt + offset("mjOption", "timestep"),
        "opt_disableflags": opt + offset("mjOption", "disableflags"),
        "opt_integrator": opt + offset("mjOption", "integrator"),
    }
    if model.opt.gravity.ctypes.data != opt + offset("mjOption", "gravity"):
        raise _fail("opt.gravity")
    if ctypes.c_void_p.from_address(model._address + offset("mjModel", "body_mass")).value != (
        model.body_mass.ctypes.data
    ):
        raise _fail("body_mass")
    checks = (
        ("opt_timestep", ctypes.c_double, model.opt.timestep),
        ("opt_disableflags", ctypes.c_int32, model.opt.disableflags),
        ("opt_integrator", ctypes.c_int32, model.opt.integrator),
    )
    for key, ctype, value in checks:
        if ctype.from_address(out[key]).value != value:
            raise _fail(key.replace("_", ".", 1))
    return out


def time_address(data: mujoco.MjData) -> int:
    """Address of the float64 ``data.time``; checked against the binding."""
    addr = data._address + offset("mjData", "time")
    if ctypes.c_void_p.from_address(data._address + offset("mjData", "xpos")).value != (
        data.xpos.ctypes.data
    ):
        raise _fail("mjData.xpos")
    if ctypes.c_double.from_address(addr).value != data.time and np.isfinite(data.time):
        raise _fail("mjData.time")
    return addr
