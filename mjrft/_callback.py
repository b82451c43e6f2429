"""Process-wide routing of MuJoCo's passive-force callback to the installed granular fields.

MuJoCo has one global ``mjcb_passive``. Installing a Python callable there breaks every model
compilation in the process: the compiler runs a forward pass on a temporary model that has no
Python wrapper, and the binding's trampoline raises (DESIGN.md section 3). So the C global points
to a small *native* guard (a numba ``cfunc``) that forwards to the binding's trampoline only for
models with an installed field; every other model, including the compiler's temporary ones, never
enters Python. The guard must be native rather than a ctypes callback: the binding escapes Python
exceptions with ``longjmp`` out of ``mj_step``, which is harmless across native frames but corrupts
the interpreter when it crosses a Python frame.

State here is one registry of installed fields, mutated only by ``install``/``uninstall`` under a
lock, and restored to exactly what it found (including a user's own passive callback, which is
chained: it still runs for every model).
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

_MAX_MODELS = 256
_lock = threading.RLock()
# Slot 0: number of registered models; slots 1..n: their mjModel addresses. Read by the guard.
_registry = np.zeros(_MAX_MODELS + 1, dtype=np.uint64)
_handlers: dict[int, Callable[[Any, Any], None]] = {}
_state: dict[str, Any] = {}  # guard, trampoline address, saved user callback


def _libmujoco() -> ctypes.CDLL:
    pattern = os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")
    candidates = sorted(glob.glob(pattern)) or sorted(
        glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco*.dylib"))
    )
    if not candidates:
        raise RuntimeError(f"cannot locate the MuJoCo shared library next to {mujoco.__file__}")
    return ctypes.CDLL(candidates[0])


def _build_guard(trampoline_address: int):
    """Compile the native guard that calls the trampoline only for registered models."""
    from numba import cfunc, types
    from numba.extending import intrinsic

    @intrinsic
    def _u64_ptr(typingctx, addr):
        sig = types.CPointer(types.uint64)(types.uint64)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

        return sig, codegen

    @intrinsic
    def _address(typingctx, ptr):
        sig = types.uint64(types.voidptr)

        def codegen(context, builder, signature, args):
            return builder.ptrtoint(args[0], context.get_value_type(types.uint64))

        return sig, codegen

    proto = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)
    trampoline = proto(trampoline_address)
    registry_address = np.uint64(_registry.ctypes.data)

    @cfunc(types.void(types.voidptr, types.voidptr), nopython=True)
    def guard(m, d):
        reg = _u64_ptr(registry_address)
        key = _address(m)
        for i in range(1, reg[0] + 1):
            if reg[i] == key:
                trampoline(m, d)
                return

    return guard


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


def install(model: mujoco.MjModel, handler: Callable[[Any, Any], None]) -> None:
    """Route the passive callback of `model` to handler(m, d) until ``uninstall(model)``."""
    with _lock:
        key = model._address
        if key in _handlers:
            raise RuntimeError("a granular field is already installed for this MjModel")
        if len(_handlers) >= _MAX_MODELS:
            raise RuntimeError(f"at most {_MAX_MODELS} models can have installed fields at once")
        if not _handlers:
            user = mujoco.get_mjcb_passive()
            if user is not None and not callable(user):
                raise RuntimeError("unsupported mjcb_passive already installed")
            if isinstance(user, ctypes._CFuncPtr):
                raise RuntimeError(
                    "a native (ctypes) mjcb_passive is installed; mjrft cannot chain it. "
                    "Remove it with mujoco.set_mjcb_passive(None) before installing a field"
                )
            _state["user_callback"] = user
            # Registers _dispatch with the binding and puts its trampoline in the C global...
            mujoco.set_mjcb_passive(_dispatch)
            if user is None:
                # ...which the native guard then replaces, keeping _dispatch as the binding's
                # callable. With a user callback present every model must still reach Python
                # (their callback runs for all models), so the trampoline stays; compilation
                # was already unavailable to them while their callback is installed.
                glob_ptr = _c_global()
                tramp = glob_ptr.value
                if "guard" not in _state or _state["trampoline"] != tramp:
                    _state["guard"] = _build_guard(tramp)
                    _state["trampoline"] = tramp
                glob_ptr.value = _state["guard"].address
        _handlers[key] = handler
        _sync_registry()


def uninstall(model: mujoco.MjModel) -> None:
    """Stop routing `model`; restore the previous passive callback when no field remains."""
    with _lock:
        if _handlers.pop(model._address, None) is None:
            return
        _sync_registry()
        if not _handlers:
            # Restores both the binding's callable and the C global (trampoline or null).
            mujoco.set_mjcb_passive(_state.pop("user_callback", None))


def _sync_registry() -> None:
    keys = list(_handlers)
    # Write entries before the count so a concurrent guard never reads an unset slot.
    _registry[1 : len(keys) + 1] = keys
    _registry[0] = len(keys)


def installed_models() -> int:
    """Number of models with an installed field (for tests and diagnostics)."""
    return len(_handlers)
