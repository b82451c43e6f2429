"""``mjrft view-recording``: open a rerun recording (``.rrd``) in rerun's native or web viewer.

The native viewer needs a display and a GPU context; on a server without them, rerun's web
viewer is served instead, bound to 127.0.0.1 only, and opened in a browser on this machine or on
another one through an SSH tunnel (docs/recording.md, "Viewing a recording"). Either viewer is
rerun's own executable from the ``rerun-sdk`` package (``rerun_cli/rerun``), started in a process
group of its own and stopped with that whole group on Ctrl-C, SIGTERM or SIGHUP: the ``rerun``
command on PATH is a Python wrapper, and stopping only the wrapper would leave the server holding
its ports.

Importing this module does not import rerun (the CLI builds its parser from it).
"""

from __future__ import annotations

import argparse
import ctypes
import getpass
import importlib.util
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
from pathlib import Path

#: rerun's default ports: the web viewer's HTTP port and the gRPC port the data comes from.
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876
#: The web viewer listens on this address only (rerun's own default is every interface).
BIND = "127.0.0.1"
#: Seconds to wait for the server to listen, and for its process group to stop after SIGTERM.
START_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 5.0
#: A native viewer that exits with an error this soon after starting is taken as unable to run
#: here (no display or no GPU context: "Failed to get render context"); the web viewer follows.
NATIVE_FAILURE_WINDOW_S = 15.0
#: The server keeps the whole recording in memory for the viewers that connect: at least this
#: many times the file's size (rerun's default limit is 1 GiB; over it the oldest data is lost).
SERVER_MEMORY_PER_FILE_SIZE = 3


def rerun_executable() -> str:
    """Path of rerun's executable: ``$RERUN_CLI_PATH``, the one in the installed ``rerun_cli``
    package, else ``rerun`` on PATH. Raises ValueError if there is none."""
    if os.environ.get("RERUN_CLI_PATH"):
        return os.environ["RERUN_CLI_PATH"]
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        name = "rerun.exe" if sys.platform.startswith("win") else "rerun"
        candidate = Path(spec.origin).with_name(name)
        if candidate.exists():
            return str(candidate)
    found = shutil.which("rerun") or shutil.which("rerun", path=str(Path(sys.executable).parent))
    if found:
        return found
    raise ValueError("rerun's viewer is not installed: pip install rerun-sdk")


def has_display() -> bool:
    """Whether a native window can be opened here (always on macOS and Windows; on Linux and
    other Unix systems, when DISPLAY or WAYLAND_DISPLAY is set)."""
    if sys.platform == "darwin" or sys.platform.startswith("win"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def viewer_url(web_port: int, grpc_port: int, host: str = BIND) -> str:
    """The page to open: the web viewer at ``host:web_port`` reading the server's gRPC proxy."""
    source = f"rerun+http://{host}:{grpc_port}/proxy"
    return f"http://{host}:{web_port}/?url={urllib.parse.quote(source, safe='')}"


def ssh_tunnel(web_port: int, grpc_port: int) -> str:
    """The command that forwards both ports from another machine to this one."""
    return (
        f"ssh -N -L {web_port}:{BIND}:{web_port} -L {grpc_port}:{BIND}:{grpc_port} "
        f"{getpass.getuser()}@{socket.gethostname()}"
    )


def port_is_free(port: int) -> bool:
    """Whether a TCP port can be bound on 127.0.0.1."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((BIND, port))
        except OSError:
            return False
    return True


def free_port() -> int:
    """A TCP port that is free on 127.0.0.1 now (the OS's choice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((BIND, 0))
        return int(s.getsockname()[1])


def _choose_port(requested: int | None, default: int, what: str) -> int:
    if requested is None:  # rerun's default port, or any free one if it is taken
        return default if port_is_free(default) else free_port()
    if requested == 0:
        return free_port()
    if not port_is_free(requested):
        raise ValueError(f"{what} port {requested} is in use on {BIND}")
    return requested


def _listening(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(0.5)
        return s.connect_ex((BIND, port)) == 0


def _own_group_and_death_signal() -> None:
    """In the child before exec: a session (process group) of its own, and on Linux SIGTERM
    when the parent dies, so that even a killed ``mjrft`` does not leave the server running
    (Linux sends it when the thread that started the child ends: start it from one that lives
    as long as the viewer should)."""
    os.setsid()
    if _PRCTL is not None:
        _PRCTL(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


# Looked up before any fork: the child only calls it.
_PRCTL = None
if sys.platform.startswith("linux"):
    try:
        _PRCTL = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        _PRCTL = None


def _start(cmd: list[str], log) -> subprocess.Popen:
    env = dict(os.environ)
    env.setdefault("RUST_LOG", "warn")  # rerun's INFO lines repeat what mjrft prints
    if os.name == "posix":
        return subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=log,
            env=env,
            preexec_fn=_own_group_and_death_signal,
        )
    return subprocess.Popen(  # Windows: a new process group, stopped with CTRL_BREAK
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=log,
        stderr=log,
        env=env,
        creationflags=subprocess.CREATE_NEW_PROCESS_GROUP,
    )


def stop_group(proc: subprocess.Popen, timeout: float = STOP_TIMEOUT_S) -> None:
    """Stop a process started by this module and everything in its process group: SIGTERM,
    then SIGKILL after ``timeout`` seconds. Does nothing once the process has ended and been
    reaped (its id may then belong to another process)."""
    if proc.poll() is not None:
        return
    if os.name != "posix":
        proc.send_signal(signal.CTRL_BREAK_EVENT)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)  # the group's id is the child's pid (setsid)
    except ProcessLookupError:
        pass
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        pass
    try:
        # What is left of the group (a wrapper's child): its id is not reused while it exists.
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()


def _tail(log) -> str:
    log.flush()
    log.seek(0)
    lines = log.read().decode(errors="replace").strip().splitlines()
    return "\n".join(lines[-15:])


class WebViewerServer:
    """rerun's web viewer serving one recording on 127.0.0.1 (a context manager).

    Args:
      path: the ``.rrd`` file. web_port: HTTP port of the viewer page; grpc_port: port the page
        reads the data from. None: rerun's default (9090, 9876) or a free port if it is taken;
        0: a free port. A port given and in use raises ValueError.
      timeout: seconds to wait for both ports to listen.

    Attributes: ``url`` (the page to open), ``web_port``, ``grpc_port``, ``process``.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        web_port: int | None = None,
        grpc_port: int | None = None,
        *,
        timeout: float = START_TIMEOUT_S,
    ) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise ValueError(f"no recording {str(self.path)!r}")
        self.web_port = _choose_port(web_port, DEFAULT_WEB_PORT, "web viewer")
        self.grpc_port = _choose_port(grpc_port, DEFAULT_GRPC_PORT, "gRPC")
        if self.web_port == self.grpc_port:
            raise ValueError(f"the web viewer and gRPC ports must differ, got {self.web_port}")
        self.url = viewer_url(self.web_port, self.grpc_port)
        size_mb = self.path.stat().st_size / 1e6
        memory_mb = max(1074, int(SERVER_MEMORY_PER_FILE_SIZE * size_mb) + 1)
        cmd = [
            rerun_executable(),
            "--serve-web",
            "--bind",
            BIND,
            "--web-viewer-port",
            str(self.web_port),
            "--port",
            str(self.grpc_port),
            "--server-memory-limit",
            f"{memory_mb}MB",
            str(self.path),
        ]
        self.log = tempfile.TemporaryFile()
        self.process = _start(cmd, self.log)
        try:
            self._wait_listening(timeout)
        except BaseException:
            self.stop()
            raise

    def _wait_listening(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not (_listening(self.web_port) and _listening(self.grpc_port)):
            code = self.process.poll()
            if code is not None:
                raise RuntimeError(
                    f"rerun's web viewer server exited with status {code}:\n{_tail(self.log)}"
                )
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"rerun's web viewer server did not listen on ports {self.web_port} and "
                    f"{self.grpc_port} within {timeout:g} s:\n{_tail(self.log)}"
                )
            time.sleep(0.05)

    def output(self) -> str:
        """The server's last lines of output (warnings and errors)."""
        return _tail(self.log)

    def stop(self) -> None:
        """Stop the server and its process group (idempotent); the ports are free after."""
        stop_group(self.process)

    def __enter__(self) -> WebViewerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
        self.log.close()


class _Stop(Exception):
    """SIGTERM or SIGHUP, turned into an exception so that the viewer is stopped on the way."""


def _stop_on_signals():
    def raise_stop(signum, frame):
        raise _Stop(signal.Signals(signum).name)

    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            previous[sig] = signal.signal(sig, raise_stop)
    return previous


def serve(path: Path, web_port: int | None, grpc_port: int | None, out=sys.stdout) -> int:
    """Serve the web viewer until Ctrl-C, SIGTERM or SIGHUP, then stop it; exit status."""
    previous = _stop_on_signals()
    server = None
    try:
        server = WebViewerServer(path, web_port, grpc_port)
        print(
            f"mjrft view-recording: serving {path} with rerun's web viewer on {BIND} "
            "(Ctrl-C stops it)\n"
            f"  open in a browser on this machine:\n    {server.url}\n"
            "  from another machine, forward both ports first, then open the same URL "
            f"there:\n    {ssh_tunnel(server.web_port, server.grpc_port)}",
            file=out,
            flush=True,
        )
        code = server.process.wait()
        print(
            f"mjrft view-recording: rerun's server exited with status {code}:\n{server.output()}",
            file=sys.stderr,
        )
        return code or 1
    except RuntimeError as exc:  # the server did not start
        print(f"mjrft view-recording: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, _Stop):
        if server is not None:
            server.stop()
            print(
                f"mjrft view-recording: stopped; ports {server.web_port} and {server.grpc_port} "
                "are free",
                file=out,
                flush=True,
            )
        return 0
    finally:
        if server is not None:
            server.__exit__(None, None, None)
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def open_native(path: Path) -> int | None:
    """Run the native viewer on ``path`` until it is closed; its exit status, or None if it
    failed at once (no display or GPU context: the caller serves the web viewer instead)."""
    previous = _stop_on_signals()
    started = time.monotonic()
    try:
        proc = _start([rerun_executable(), str(path)], None)  # its messages go to the terminal
        try:
            code = proc.wait()
        except (KeyboardInterrupt, _Stop):
            stop_group(proc)
            return 0
        if code != 0 and time.monotonic() - started < NATIVE_FAILURE_WINDOW_S:
            return None
        return code
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def main(args: argparse.Namespace) -> int:
    """``mjrft view-recording``: native viewer where possible, else (or with --web) the web one."""
    path = Path(args.file)
    if not path.is_file():
        raise ValueError(f"no recording {str(path)!r}")
    path = readable_copy(path)
    if not args.web:
        if not has_display():
            print(
                "mjrft view-recording: no display (DISPLAY and WAYLAND_DISPLAY are unset): "
                "serving the web viewer instead",
                file=sys.stderr,
            )
        else:
            code = open_native(path)
            if code is not None:
                return code
            print(
                "mjrft view-recording: the native viewer could not start here (no GPU "
                "context?): serving the web viewer instead",
                file=sys.stderr,
            )
    return serve(path, args.port, args.grpc_port)


def readable_copy(path: Path, err=None) -> Path:
    """`path` if rerun can read it as it is; for a recording cut short (no end message: a full
    disk, a killed run, or a run still writing it), a salvaged copy of its complete messages
    (``mjrft.app.rrd_file``) next to it, or in the temporary directory if that is not writable.
    """
    from mjrft.app import rrd_file

    found = rrd_file.scan(path)
    if found.finished:
        return path
    out = rrd_file.salvaged_name(path)
    if not os.access(out.parent, os.W_OK):
        out = Path(tempfile.gettempdir()) / out.name
    rrd_file.salvage(path, out)
    print(
        f"mjrft view-recording: {path} was not closed (a full disk, a killed run, or a run still "
        f"writing it): opening a copy of its {found.messages} complete messages "
        f"({found.complete / 1e6:.1f} of {found.size / 1e6:.1f} MB), {out}",
        file=err or sys.stderr,
    )
    return out


def _port(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number, got {text!r}") from None
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number 0-65535, got {v}")
    return v


def add_parser(sub) -> argparse.ArgumentParser:
    """Add the ``view-recording`` subcommand to the CLI's subparsers."""
    v = sub.add_parser(
        "view-recording",
        help="open a rerun recording (.rrd) in rerun's viewer, natively or in a browser",
        description=(
            "Open FILE (a recording from `mjrft run --rrd` or `mjrft demo`) in rerun's native "
            "viewer. With --web, or when there is no display (or the native viewer cannot "
            f"start), serve rerun's web viewer on {BIND} only and print the URL to open and the "
            "SSH tunnel to use from another machine; Ctrl-C stops the server and frees its "
            "ports. See docs/recording.md."
        ),
    )
    v.add_argument("file", metavar="FILE", help="the .rrd recording")
    v.add_argument(
        "--web",
        action="store_true",
        help="serve rerun's web viewer (bound to 127.0.0.1) instead of opening a native window",
    )
    v.add_argument(
        "--port",
        type=_port,
        default=None,
        metavar="P",
        help=f"HTTP port of the web viewer page (default: {DEFAULT_WEB_PORT}, or a free port "
        "if it is taken; 0: a free port)",
    )
    v.add_argument(
        "--grpc-port",
        type=_port,
        default=None,
        metavar="G",
        help=f"port the web viewer reads the recording from (default: {DEFAULT_GRPC_PORT}, or "
        "a free port if it is taken; 0: a free port)",
    )
    v.set_defaults(func=main)
    return v
