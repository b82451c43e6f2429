"""Process-wide routing of MuJoCo's passive-force callback to the installed granular fields.

MuJoCo has one global ``mjcb_passive``. Installing a Python callable there breaks every model
compilation in the process: the compiler runs a forward pass on a temporary model that has no
Python wrapper, and the binding's trampoline raises (docs/design.md section 3). So the C global
points to a small *native* guard (a numba ``cfunc``) that forwards to the binding's trampoline only
for models with an installed field; every other model, including the compiler's temporary ones,
never enters Python. The guard must be native rather than a ctypes callback: the binding escapes
Python exceptions with ``longjmp`` out of ``mj_step``, which is harmless across native frames but
corrupts the interpreter when it crosses a Python frame.

For fields of compiled media, the guard also runs the field's whole pass natively
(``mjrft.field.passive.step``) for every MjData already registered, and enters Python only for an
MjData seen for the first time (the field registers it) or when the pass reports a problem (Python
then raises, naming the body, from the status the pass left). Fields of media given by Python
callables take the trampoline on every pass.

State here is the registry of installed fields and registered MjData, mutated only by the
functions below under a lock, and restored to exactly what it found on the last uninstall
(including a user's own passive callback, which is chained: it still runs for every model).
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading
from collections.abc import Callable
from typing import Any

import llvmlite.binding as llvm
import mujoco
import numpy as np
from llvmlite import ir
from numba import cfunc, types
from numba.extending import intrinsic

from mjrft.field import passive
from mjrft.field.signals import HeldSignals
from mjrft.field.tables import u64_ptr

_MAX_MODELS = 256
_MAX_DATAS = 4096
_lock = threading.RLock()
# Word 0: number of models; then (mjModel address, field native-table address or 0) pairs.
_registry = np.zeros(1 + 2 * _MAX_MODELS, dtype=np.uint64)
# Word 0: number of MjData; then (mjData address, mjModel address, entry-table address) triples.
_datas = np.zeros(1 + 3 * _MAX_DATAS, dtype=np.uint64)
_handlers: dict[int, Callable[[Any, Any], None]] = {}
_tables: dict[int, int] = {}  # mjModel address -> native table address (0: Python only)
_data_entries: dict[int, tuple[int, int]] = {}  # mjData address -> (mjModel address, entry)
_state: dict[str, Any] = {}  # guard, trampoline address, saved user callback


def _libmujoco() -> ctypes.CDLL:
    pattern = os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")
    candidates = sorted(glob.glob(pattern)) or sorted(
        glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco*.dylib"))
    )
    if not candidates:
        raise RuntimeError(f"cannot locate the MuJoCo shared library next to {mujoco.__file__}")
    return ctypes.CDLL(candidates[0])


# Run-time inputs of the native guard: (registry address, MjData table address, the binding's
# trampoline, the pass mode). The guard reads them through the linker symbol _SLOTS_SYMBOL
# rather than as compile-time constants, so numba caches it on disk like the pass (compiling it
# took 1.7 s of every process's start).
_SLOTS_SYMBOL = "mjrft_guard_slots"
_slots = np.zeros(4, dtype=np.uint64)
llvm.add_symbol(_SLOTS_SYMBOL, _slots.ctypes.data)
_slots[0] = _registry.ctypes.data
_slots[1] = _datas.ctypes.data
_slots[3] = passive.INSTALLED


@intrinsic
def _slot(typingctx, i):
    """_slots[i], loaded from the linker symbol at run time."""
    sig = types.uint64(types.intp)

    def codegen(context, builder, signature, args):
        gv = builder.module.globals.get(_SLOTS_SYMBOL)
        if gv is None:
            gv = ir.GlobalVariable(builder.module, ir.ArrayType(ir.IntType(64), 4), _SLOTS_SYMBOL)
            gv.linkage = "external"
        return builder.load(builder.gep(gv, [ir.Constant(ir.IntType(32), 0), args[0]]), align=8)

    return sig, codegen


@intrinsic
def _address(typingctx, ptr):
    """A pointer as an integer."""
    sig = types.uint64(types.voidptr)

    def codegen(context, builder, signature, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.uint64))

    return sig, codegen


@intrinsic
def _call_passive(typingctx, function, m, d):
    """Call the C function at address `function` as a passive callback f(m, d)."""
    sig = types.void(types.uint64, types.voidptr, types.voidptr)

    def codegen(context, builder, signature, args):
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i8p])
        builder.call(builder.inttoptr(args[0], fnty.as_pointer()), [args[1], args[2]])
        return context.get_dummy_value()

    return sig, codegen


def _guard(m, d):
    """The native passive callback: the field's native pass for a registered MjData of an
    installed model, the trampoline to Python for other MjData of installed models or a pass
    that reports a problem, nothing for any other model."""
    reg = u64_ptr(_slot(0))
    key = _address(m)
    table = np.uint64(0)
    found = False
    for i in range(reg[0]):
        if reg[1 + 2 * i] == key:
            table = reg[2 + 2 * i]
            found = True
            break
    if not found:
        return
    if table != 0:
        dat = u64_ptr(_slot(1))
        dkey = _address(d)
        for j in range(dat[0]):
            if dat[1 + 3 * j] == dkey and dat[2 + 3 * j] == key:
                if passive.step(table, dat[3 + 3 * j], np.int64(_slot(3))) == passive.OK:
                    return
                break
    _call_passive(_slot(2), m, d)


def _compiled_guard():
    """The guard as a C callback, compiled or loaded from numba's cache on first use (a cfunc
    compiles when it is created: at import it would hold up every import of the field)."""
    return cfunc(types.void(types.voidptr, types.voidptr), nopython=True, cache=True)(_guard)


def _dispatch(m, d) -> None:
    """Python side of the passive callback: the field of this model, then any user callback.

    Exceptions propagate out of mj_step (the binding re-raises them there).
    """
    handler = _handlers.get(m._address)
    if handler is not None:
        handler(m, d)
    user = _state.get("user_callback")
    if user is not None:
        user(m, d)


def _c_global() -> ctypes.c_void_p:
    if "c_global" not in _state:
        _state["c_global"] = ctypes.c_void_p.in_dll(_libmujoco(), "mjcb_passive")
    return _state["c_global"]


def _trampoline() -> int:
    """Address of the binding's C trampoline to Python callables (fixed for the process)."""
    if "trampoline" not in _state:
        previous = _original["get"]()
        with HeldSignals():
            _original["set"](_dispatch)
            _state["trampoline"] = _c_global().value
            _original["set"](previous)
    return _state["trampoline"]


def _guard_address() -> int:
    """Address of the native guard, loaded from numba's cache (or compiled) on first use,
    before any global is touched."""
    if "guard" not in _state:
        # Deferred too: a KeyboardInterrupt inside numba's compilation or cache load can land in
        # its lazy imports and leave numba unable to compile anything after.
        with HeldSignals():
            _slots[2] = _trampoline()
            _state["compiled_guard"] = _compiled_guard()  # keeps the code alive
            _state["guard"] = _state["compiled_guard"].address
    return _state["guard"]


def _route() -> None:
    """Point MuJoCo's C global at the guard, or at the trampoline while a user callback is
    chained (their callback runs for every model, so every model must reach Python)."""
    user = _state.get("user_callback")
    _c_global().value = _trampoline() if user is not None else _guard_address()


def _set_mjcb_passive(callback) -> None:
    """``mujoco.set_mjcb_passive`` while a field is installed: chains the callback after the
    fields (it runs for every model) instead of silently switching the fields off."""
    if callback is not None and not callable(callback):
        raise TypeError(f"mjcb_passive must be callable or None, got {type(callback).__name__}")
    if isinstance(callback, ctypes._CFuncPtr):
        raise RuntimeError(
            "a native (ctypes) mjcb_passive cannot be chained with an installed granular field"
        )
    with _lock, HeldSignals():
        _state["user_callback"] = callback
        _route()


def _get_mjcb_passive():
    """``mujoco.get_mjcb_passive`` while a field is installed: the chained user callback."""
    return _state.get("user_callback")


_original = {"set": mujoco.set_mjcb_passive, "get": mujoco.get_mjcb_passive}


def install(
    model: mujoco.MjModel, handler: Callable[[Any, Any], None], native_table: int = 0
) -> None:
    """Route the passive callback of `model` to handler(m, d) until ``uninstall(model)``.

    native_table: address of the field's static record (``mjrft.field.tables``; 0: Python
    only). With it, registered MjData are handled natively; handler sees the others and any
    reported problem. Atomic against Ctrl-C: an interrupt during it rolls it back and is raised
    after. While any field is installed, ``mujoco.set_mjcb_passive`` chains a user callback
    after the fields and ``mujoco.get_mjcb_passive`` returns it.
    """
    key = model._address
    if key in _handlers:
        raise RuntimeError("a granular field is already installed for this MjModel")
    _guard_address()  # loads or compiles the guard while no state is changed yet
    with _lock, HeldSignals() as interrupt:
        if len(_handlers) >= _MAX_MODELS:
            raise RuntimeError(f"at most {_MAX_MODELS} models can have installed fields at once")
        if not _handlers:
            _take_global()
        _handlers[key] = handler
        _tables[key] = int(native_table)
        _sync_registry()
        if interrupt.pending:  # roll back, then the interrupt is raised on leaving
            _uninstall(key)


def _take_global() -> None:
    """The first installed field takes MuJoCo's passive callback, keeping the user's chained."""
    user = _original["get"]()
    if user is not None and not callable(user):
        raise RuntimeError("unsupported mjcb_passive already installed")
    if isinstance(user, ctypes._CFuncPtr):
        raise RuntimeError(
            "a native (ctypes) mjcb_passive is installed; mjrft cannot chain it. "
            "Remove it with mujoco.set_mjcb_passive(None) before installing a field"
        )
    _state["user_callback"] = user
    _original["set"](_dispatch)  # the binding's callable; the C global then goes to the guard
    _route()
    mujoco.set_mjcb_passive, mujoco.get_mjcb_passive = _set_mjcb_passive, _get_mjcb_passive


def _give_back_global() -> None:
    """The last field gives MuJoCo's passive callback back (the user's, if one is chained).

    Raises RuntimeError if the callback was replaced behind the fields' back (through a
    reference to ``mujoco.set_mjcb_passive`` taken before installing, or ctypes): the fields
    then stopped acting at some step without a word, and their results are not to be trusted.
    """
    replaced = _original["get"]() is not _dispatch or _c_global().value not in (
        _state.get("trampoline"),
        _state.get("guard"),
    )
    mujoco.set_mjcb_passive, mujoco.get_mjcb_passive = _original["set"], _original["get"]
    _original["set"](_state.pop("user_callback", None))
    if replaced:
        raise RuntimeError(
            "MuJoCo's passive callback was replaced while a granular field was installed (a "
            "reference to mujoco.set_mjcb_passive taken before installing, or ctypes): the field "
            "stopped acting then, so the run's granular forces are missing from that step on; "
            "set callbacks through mujoco.set_mjcb_passive while installed, which chains them"
        )


def uninstall(model: mujoco.MjModel) -> None:
    """Stop routing `model`; restore the previous passive callback when no field remains.
    Atomic against Ctrl-C; a no-op if the model has no installed field."""
    with _lock, HeldSignals():
        _uninstall(model._address)


def _uninstall(key: int) -> None:
    if _handlers.pop(key, None) is None:
        return
    _tables.pop(key, None)
    _sync_registry()
    for addr in [a for a, (mkey, _) in _data_entries.items() if mkey == key]:
        _data_entries.pop(addr)
    _sync_datas()
    if not _handlers:
        _give_back_global()


def _sync_registry() -> None:
    keys = list(_handlers)
    # Write entries before the count so a concurrent guard never reads an unset slot.
    for i, k in enumerate(keys):
        _registry[1 + 2 * i] = k
        _registry[2 + 2 * i] = _tables.get(k, 0)
    _registry[0] = len(keys)


def register_data(model: mujoco.MjModel, data_address: int, entry_address: int) -> None:
    """Let the guard run the model's native pass on this MjData (entry: its address table)."""
    with _lock:
        if data_address not in _data_entries and len(_data_entries) >= _MAX_DATAS:
            raise RuntimeError(f"at most {_MAX_DATAS} MjData can be registered at once")
        _data_entries[data_address] = (model._address, entry_address)
        _sync_datas()


def unregister_data(data_address: int) -> None:
    """Forget an MjData (it was freed, or its field was uninstalled)."""
    with _lock:
        if _data_entries.pop(data_address, None) is not None:
            _sync_datas()


def _sync_datas() -> None:
    items = list(_data_entries.items())
    _datas[0] = min(_datas[0], len(items))  # shrink first: never expose a stale triple
    for j, (daddr, (mkey, entry)) in enumerate(items):
        _datas[1 + 3 * j : 4 + 3 * j] = (daddr, mkey, entry)
    _datas[0] = len(items)


def installed_handler(model: mujoco.MjModel) -> Callable[[Any, Any], None] | None:
    """The handler installed for `model`, or None."""
    return _handlers.get(model._address)


def installed_models() -> int:
    """Number of models with an installed field (for tests and diagnostics)."""
    return len(_handlers)
