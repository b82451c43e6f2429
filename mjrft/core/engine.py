"""The C++ engine library (``engine/`` in the repository), as the core layer reaches it.

One shared library holds the whole engine: the MuJoCo plugin ``mjrft.granular`` (registered when
the library is loaded; ``mjrft.field.plugin``) and the C entry points the RFT-only API calls
(element forces, prescribed trajectories, surfaces). Python reaches it through ctypes: one
library serves every Python version, and the core layer needs no mujoco import for it.
"""

from __future__ import annotations

import ctypes
import os
import threading
from dataclasses import dataclass
from pathlib import Path

_STEM = "libmjrft_granular"
_lock = threading.Lock()
_lib: ctypes.CDLL | None = None


class EngineError(RuntimeError):
    """The engine library is missing, was built for another MuJoCo, or a model lacks it."""


def library_path() -> Path:
    """Path of the engine library: ``MJRFT_ENGINE_LIBRARY`` if set, else the one ``pip install``
    put beside mjrft's modules."""
    import mjrft

    env = os.environ.get("MJRFT_ENGINE_LIBRARY")
    if env:
        return Path(env)
    for folder in mjrft.__path__:
        for suffix in (".so", ".dylib", ".dll"):
            path = Path(folder) / (_STEM + suffix)
            if path.exists():
                return path
    raise EngineError(
        f"the mjrft engine library ({_STEM}.so) is not installed in {list(mjrft.__path__)}: "
        "mjrft was not built; install it from its source with `pip install .` (or "
        "`pip install -e .`), which builds the C++ engine with CMake"
    )


def library() -> ctypes.CDLL:
    """The engine library, loaded once (loading it registers the MuJoCo plugin)."""
    global _lib
    with _lock:
        if _lib is None:
            path = library_path()
            try:
                lib = ctypes.CDLL(str(path))
            except OSError as e:
                raise EngineError(
                    f"cannot load the mjrft engine {path}: {e}. It links one MuJoCo release "
                    "exactly (the mujoco pinned in mjrft's pyproject.toml): reinstall mjrft "
                    "(`pip install .`) against the installed mujoco"
                ) from e
            _declare(lib)
            _lib = lib
        return _lib


def _declare(lib: ctypes.CDLL) -> None:
    p, i, s = ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p
    lib.mjrft_layout.restype = s
    lib.mjrft_mujoco_version.restype = i
    lib.mjrft_instance.argtypes = [p]
    lib.mjrft_instance.restype = i
    lib.mjrft_forward.argtypes = [p, p, i, i]
    lib.mjrft_forward.restype = ctypes.c_longlong
    lib.mjrft_state_array.argtypes = [p, p, i, s]
    lib.mjrft_state_array.restype = p
    lib.mjrft_state_size.argtypes = [p, p, i, s]
    lib.mjrft_state_size.restype = ctypes.c_longlong


@dataclass(frozen=True)
class Layout:
    """The engine's table and state layout (engine/fields.h): names in order, with types."""

    format: int
    sizes: tuple[str, ...]
    scalars: tuple[tuple[str, str], ...]  # (type, name): type "f64" or "i64"
    arrays: tuple[tuple[str, str], ...]
    state: tuple[tuple[str, str], ...]


def layout() -> Layout:
    """The layout the loaded engine reads."""
    text = library().mjrft_layout().decode()
    lines = dict(line.split(" ", 1) for line in text.strip().splitlines())
    pairs = lambda key: tuple(tuple(w.split(":")) for w in lines[key].split())  # noqa: E731
    return Layout(
        int(lines["format"]), tuple(lines["sizes"].split()), pairs("scalars"), pairs("arrays"),
        pairs("state"),
    )  # fmt: skip
