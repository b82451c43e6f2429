"""Python functions a study names: ``module:function`` (imported from the Python path) or
``path/to/file.py:function`` (relative to the study file)."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mjrft.sweep.errors import StudyError


def resolve(spec: str, base: Path, where: str) -> str:
    """`spec` with a file's path made absolute against `base` (so workers find it wherever they
    start), after checking the form and that the file exists."""
    module, sep, attr = spec.rpartition(":")
    if not sep or not module or not attr.isidentifier():
        raise StudyError(f"{where}: {spec!r} is not MODULE:FUNCTION or path/to/file.py:FUNCTION")
    if not module.endswith(".py"):
        return spec
    path = Path(module) if Path(module).is_absolute() else base / module
    if not path.is_file():
        raise StudyError(f"{where}: {spec!r}: no file {str(path)!r}")
    return f"{path.resolve()}:{attr}"


def load(spec: str, where: str) -> Callable[..., Any]:
    """The function a resolved `spec` names."""
    module, _, attr = spec.rpartition(":")
    try:
        if module.endswith(".py"):
            name = f"mjrft_study_{Path(module).stem}"
            if name not in sys.modules or getattr(sys.modules[name], "__file__", None) != module:
                loader = importlib.util.spec_from_file_location(name, module)
                mod = importlib.util.module_from_spec(loader)
                sys.modules[name] = mod  # dataclasses and pickling look modules up by name
                loader.loader.exec_module(mod)
            mod = sys.modules[name]
        else:
            mod = importlib.import_module(module)
    except StudyError:
        raise
    except Exception as exc:
        raise StudyError(
            f"{where}: cannot import {module!r}: {type(exc).__name__}: {exc}"
        ) from None
    fn = getattr(mod, attr, None)
    if not callable(fn):
        raise StudyError(f"{where}: {module!r} has no callable {attr!r}")
    return fn
