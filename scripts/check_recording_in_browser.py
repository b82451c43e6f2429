"""Check a recording in a real browser: rerun's web viewer in headless Chromium shows the stress
colours of the intruders.

What it does:

1. Takes ``--rrd FILE``, or records 5 s of models/ellipsoid_pitch.xml at the defaults of
   ``mjrft run --rrd`` (the ellipsoid is in the medium from 0.02 s on).
2. Reads the file: the viewer opens at its last frame, so every intruder must carry stress
   colours there (some triangles not grey), or there is nothing to check.
3. Writes a copy without the intruders' ``rft_mesh`` entities (``rerun rrd filter``).
4. Serves each file with rerun's web viewer on 127.0.0.1 (``mjrft.app.view.WebViewerServer``)
   and opens it in headless Chromium with software WebGL2 (SwiftShader), driven through the
   DevTools protocol; waits until the WebAssembly viewer has loaded the whole recording (the page
   stops changing) and takes a screenshot. The full one is saved (``--screenshot``).
5. The intruders' pixels are those that differ between the two screenshots (same layout, camera
   and time; only the meshes are missing in the second). It checks that there are enough of them
   and that they are not uniform grey: a share of them is clearly coloured (chroma, max - min of
   R, G, B, at least ``MIN_CHROMA``) and they take several distinct hues.

Not a CI test: it needs Chromium (Debian: ``apt-get install chromium``) and takes about a minute
on a 2-core machine. Prints what it checked; exits 1 if a check fails, 2 if it could
not run.

    python scripts/check_recording_in_browser.py [--rrd FILE] [--screenshot PNG]
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mjrft.app import view  # noqa: E402

#: Browser window size [px].
WINDOW = (1600, 1000)
#: Flags for headless Chromium without a GPU: SwiftShader provides WebGL2 in software.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--remote-debugging-port=0",
    f"--window-size={WINDOW[0]},{WINDOW[1]}",
]
#: Loading: the page counts as loaded once two screenshots this many seconds apart are equal,
#: no sooner than MIN_LOAD_S after opening it, and at most LOAD_TIMEOUT_S.
SETTLE_S = 3.0
MIN_LOAD_S = 8.0
LOAD_TIMEOUT_S = 180.0
#: A pixel belongs to an intruder if the screenshots with and without its mesh differ there by
#: more than this (sum of |dR| + |dG| + |dB|, 0-765).
MASK_THRESHOLD = 45
#: Rows of the window that can show the scene, as fractions of its height (below the top bar,
#: above the time panel).
SCENE_ROWS = (0.05, 0.94)
#: Checks on the intruders' pixels: at least MIN_PIXELS of them; at least MIN_COLOURED_SHARE of
#: them with chroma >= MIN_CHROMA (grey, even tinted by the translucent surface, stays below
#: 40); the coloured ones spread over at least MIN_HUES of 12 hue bins (30 deg each) with 1% of
#: them or more.
MIN_PIXELS = 500
MIN_CHROMA = 50
MIN_COLOURED_SHARE = 0.25
MIN_HUES = 2


def record_default(folder: Path) -> Path:
    """5 s of models/ellipsoid_pitch.xml recorded at the recorder's defaults (those of
    ``mjrft run --rrd``); the .rrd path."""
    from mjrft import simulate, viz

    rrd = folder / "ellipsoid_pitch.rrd"
    print("making a recording: 5 s of models/ellipsoid_pitch.xml, the defaults of mjrft run --rrd")
    viz.record(simulate.load_model(ROOT / "models" / "ellipsoid_pitch.xml"), 5.0, rrd)
    return rrd


def intruders_at_last_frame(rrd: Path) -> list[tuple[str, float, int, int]]:
    """Per intruder mesh entity: (entity, sim_time of its last colours, coloured triangles,
    triangles) at the last frame it was logged."""
    from rerun.chunk import RrdReader

    from mjrft import viz

    grey = int(viz.stress_colors(np.zeros(1), 1.0)[0])
    entities = sorted(
        {c.entity_path for c in RrdReader(str(rrd)).stream() if c.entity_path.endswith("rft_mesh")}
    )
    out = []
    for entity in entities:
        rows = [
            r for r in viz.read_entity(rrd, entity) if "step" in r and r["Mesh3D:vertex_colors"]
        ]
        if not rows:
            out.append((entity, float("nan"), 0, 0))
            continue
        last = rows[-1]
        colors = np.asarray(last["Mesh3D:vertex_colors"], dtype=np.uint32)[::3]
        out.append((entity, last["sim_time"], int(np.sum(colors != grey)), len(colors)))
    return out


def last_time(rrd: Path) -> float:
    """The last sim_time in the file [s] (where the viewer opens)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    t = 0.0
    for chunk in RrdReader(str(rrd)).stream():
        batch = chunk.to_record_batch()
        if "sim_time" in batch.schema.names and batch.num_rows:
            ns = batch.column("sim_time").cast(pa.int64()).to_numpy()
            t = max(t, float(ns.max()) * 1e-9)
    return t


def without_meshes(rrd: Path, entities: list[str], dest: Path) -> Path:
    """A copy of the recording (and its blueprint) without these entities."""
    cmd = [view.rerun_executable(), "rrd", "filter", "-o", str(dest)]
    for e in entities:
        cmd += ["--drop-entity", e]
    subprocess.run([*cmd, str(rrd)], check=True, capture_output=True)
    return dest


class Chromium:
    """Headless Chromium with a fresh profile, driven through the DevTools protocol."""

    def __init__(self, executable: str, profile: Path) -> None:
        self.proc = subprocess.Popen(
            [executable, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,  # its helper processes go with it
        )
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + 30
        while not (port_file.exists() and port_file.read_text().strip()):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("Chromium did not start its DevTools endpoint")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
        page = next(t for t in targets if t["type"] == "page")
        from websockets.sync.client import connect

        self._connection = connect(page["webSocketDebuggerUrl"], max_size=None)
        self.ws = self._connection.__enter__()
        self._id = 0
        self.call("Page.enable")
        self.call(
            "Emulation.setDeviceMetricsOverride",
            width=WINDOW[0],
            height=WINDOW[1],
            deviceScaleFactor=1,
            mobile=False,
        )

    def call(self, method: str, **params: object) -> dict:
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=60))
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def screenshot(self) -> np.ndarray:
        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def close(self) -> None:
        try:
            self._connection.__exit__(None, None, None)
        finally:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()


def render(rrd: Path, executable: str, scratch: Path) -> tuple[np.ndarray, float]:
    """Screenshot of rerun's web viewer showing ``rrd`` once loaded; (RGB image, load time)."""
    profile = Path(tempfile.mkdtemp(prefix="chromium-", dir=scratch))
    with view.WebViewerServer(rrd, 0, 0) as server:
        browser = Chromium(executable, profile)
        try:
            t0 = time.monotonic()
            browser.call("Page.navigate", url=server.url)
            last = None
            while True:
                time.sleep(SETTLE_S)
                img = browser.screenshot()
                elapsed = time.monotonic() - t0
                if last is not None and np.array_equal(img, last) and elapsed >= MIN_LOAD_S:
                    return img, elapsed - SETTLE_S
                if elapsed > LOAD_TIMEOUT_S:
                    raise RuntimeError(f"the viewer kept changing for {LOAD_TIMEOUT_S:g} s")
                last = img
        finally:
            browser.close()


def hue_bins(rgb: np.ndarray) -> np.ndarray:
    """Hue of each (n, 3) RGB pixel in 30-degree bins 0..11."""
    r, g, b = (rgb[:, i].astype(np.float64) for i in range(3))
    hue = np.degrees(np.arctan2(np.sqrt(3.0) * (g - b), 2.0 * r - g - b)) % 360.0
    return (hue // 30).astype(np.int64)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rrd", type=Path, help="the recording (default: record 5 s of the ellipsoid)")
    p.add_argument(
        "--screenshot",
        type=Path,
        default=Path("recording_viewer.png"),
        help="where to save the viewer's screenshot (default: ./recording_viewer.png)",
    )
    p.add_argument(
        "--mask",
        type=Path,
        default=None,
        help="also save the screenshot with the pixels taken as the intruders' in magenta",
    )
    p.add_argument(
        "--chromium",
        default=shutil.which("chromium") or "/usr/bin/chromium",
        help="the Chromium executable (default: chromium on PATH)",
    )
    args = p.parse_args(argv)
    if not Path(args.chromium).exists():
        print(f"no Chromium at {args.chromium} (Debian: apt-get install chromium)")
        return 2
    with tempfile.TemporaryDirectory(prefix="mjrft-browser-check-") as tmp:
        scratch = Path(tmp)
        rrd = args.rrd or record_default(scratch)
        t_end = last_time(rrd)
        meshes = intruders_at_last_frame(rrd)
        if not meshes:
            print(f"FAIL: {rrd} has no intruder meshes (world/bodies/<body>/rft_mesh)")
            return 1
        print(f"recording: {rrd} ({rrd.stat().st_size / 1e6:.1f} MB), last frame t = {t_end:g} s")
        in_medium = True
        for entity, t, coloured, n in meshes:
            print(f"  {entity}: colours last logged at t = {t:g} s, {coloured} of {n} triangles "
                  "coloured (stress > 0)")  # fmt: skip
            in_medium &= coloured > 0
        if not in_medium:
            print("FAIL: not every intruder is in the medium at the last frame (nothing to see)")
            return 1
        nomesh = without_meshes(rrd, [e for e, *_ in meshes], scratch / "without_meshes.rrd")
        full, t_full = render(rrd, args.chromium, scratch)
        print(f"viewer loaded the recording in {t_full:.0f} s (headless Chromium, SwiftShader)")
        bare, t_bare = render(nomesh, args.chromium, scratch)
        print(f"viewer loaded the copy without the meshes in {t_bare:.0f} s")
        args.screenshot.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(full).save(args.screenshot, optimize=True)
        print(f"screenshot: {args.screenshot} ({full.shape[1]} x {full.shape[0]} px)")

    mask = np.abs(full.astype(np.int64) - bare.astype(np.int64)).sum(axis=2) > MASK_THRESHOLD
    # The top bar and the time panel (whose data-density strip differs too) are not the scene.
    mask[: int(SCENE_ROWS[0] * mask.shape[0])] = False
    mask[int(SCENE_ROWS[1] * mask.shape[0]) :] = False
    if args.mask is not None:
        shown = full.copy()
        shown[mask] = (255, 0, 255)
        Image.fromarray(shown).save(args.mask)
        print(f"mask: {args.mask}")
    pixels = full[mask]
    chroma = pixels.max(axis=1).astype(np.int64) - pixels.min(axis=1)
    coloured = pixels[chroma >= MIN_CHROMA]
    share = len(coloured) / max(1, len(pixels))
    counts = np.bincount(hue_bins(coloured), minlength=12) if len(coloured) else np.zeros(12)
    hues = int(np.sum(counts >= max(1, 0.01 * len(coloured))))
    ys, xs = np.nonzero(mask)
    where = f"x {xs.min()}-{xs.max()}, y {ys.min()}-{ys.max()}" if len(xs) else "none"
    print(f"intruder pixels (differ without the meshes): {len(pixels)} ({where})")
    print(
        f"  coloured (chroma >= {MIN_CHROMA}): {share:.0%}; hue bins used: {hues} of 12; "
        f"median chroma {np.median(chroma) if len(chroma) else 0:.0f}"
    )
    checks = [
        (len(pixels) >= MIN_PIXELS, f"at least {MIN_PIXELS} intruder pixels"),
        (share >= MIN_COLOURED_SHARE, f"at least {MIN_COLOURED_SHARE:.0%} of them coloured"),
        (hues >= MIN_HUES, f"their colours spread over at least {MIN_HUES} hues"),
    ]
    for ok, what in checks:
        print(f"{'ok  ' if ok else 'FAIL'} {what}")
    return 0 if all(ok for ok, _ in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
