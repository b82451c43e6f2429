"""``run.json``: what produced a run's files (versions, machine, options, model hash, outcome).

Written beside the CSV when a run starts (status "running") and rewritten, atomically, when it
ends, so a folder of results always says which code, model and options made it.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import sys
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

from mjrft.app.report import atomic_path

#: Distributions whose versions are recorded.
_PACKAGES = ("mjrft", "mujoco", "numpy", "matplotlib", "rerun-sdk", "trimesh")


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def versions() -> dict[str, str | None]:
    """Installed versions of the packages a run depends on (None where not installed)."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in _PACKAGES:
        try:
            out[name] = importlib_metadata.version(name)
        except importlib_metadata.PackageNotFoundError:
            out[name] = None
    return out


def machine() -> dict[str, Any]:
    """The machine: OS, architecture, CPU model (from /proc/cpuinfo where there is one), cores."""
    cpu = platform.processor() or None
    try:
        with open("/proc/cpuinfo") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    return {
        "system": platform.system(),
        "release": platform.release(),
        "machine": platform.machine(),
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
    }


def model_files(xml: Path) -> dict[str, str | None]:
    """SHA-256 of the MJCF file and of the files it names (meshes, height fields, textures,
    includes; resolved as MuJoCo does, against the file's folder and <compiler> asset folders);
    None for a named file that cannot be read."""
    out: dict[str, str | None] = {str(xml): file_sha256(xml)}
    try:
        root = ElementTree.parse(xml).getroot()
    except (ElementTree.ParseError, OSError):
        return out
    folders = {"mesh": "meshdir", "hfield": "meshdir", "texture": "texturedir"}
    compiler = root.find("compiler")
    for element in root.iter():
        name = element.get("file")
        if name is None or element.tag not in (*folders, "include", "model"):
            continue
        base = xml.parent
        if compiler is not None and element.tag in folders:
            sub = compiler.get(folders[element.tag]) or compiler.get("assetdir")
            base = base / sub if sub else base
        target = base / name
        out[str(target)] = file_sha256(target) if target.is_file() else None
    return out


def write(path: str | os.PathLike, record: dict[str, Any]) -> Path:
    """Write `record` as indented JSON, atomically (a reader never sees half a file)."""
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            json.dump(record, fh, indent=2, default=str)
            fh.write("\n")
    return Path(path)


def command_line() -> list[str]:
    """The command that is running, as typed."""
    return [Path(sys.argv[0]).name, *sys.argv[1:]]
