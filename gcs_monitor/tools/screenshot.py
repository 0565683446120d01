"""Screenshot a finished .rrd in the Rerun web viewer with headless chromium.

Recipe (stack-notes section 2): serve the file with the venv's ``rerun`` CLI
(``rerun --serve-web x.rrd --web-viewer-port P --port Q``), start headless chromium with
``--remote-debugging-port``, navigate over the DevTools protocol (``websocket-client``), wait
20-25 s of real time for the software-rendered viewer, then ``Page.captureScreenshot``.
chromium's own ``--screenshot`` captures only "Loading Application Bundle..." and is not used.

Usage::

    python -m gcs_monitor.tools.screenshot run.rrd out.png [--wait 25]

``docs/img/dashboard.png`` comes from the dashboard test, which screenshots a synthetic recording
(``tests/helpers/synthetic_rrd.py``): ``GCS_UPDATE_SCREENSHOT=1 pytest -m browser``.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import json
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
)
WINDOW_PX = (1600, 1000)
STARTUP_TIMEOUT_S = 30.0
SETTLE_POLL_S = 5.0
SETTLE_REL = 0.01
SETTLE_MAX_S = 90.0


def free_port() -> int:
    """A TCP port that was free on 127.0.0.1 a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rerun_cli() -> str:
    """The ``rerun`` executable shipped with rerun-sdk (the venv's, preferably)."""
    here = Path(sys.executable).parent / "rerun"
    if here.exists():
        return str(here)
    found = shutil.which("rerun")
    if found is None:
        raise FileNotFoundError("rerun CLI not found (pip install rerun-sdk)")
    return found


def _wait_port(port: int, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.5):
            return
        time.sleep(0.1)
    raise TimeoutError(f"nothing listening on 127.0.0.1:{port} after {timeout_s} s")


def _http_json(url: str, timeout_s: float = 2.0) -> Any:
    with urllib.request.urlopen(url, timeout=timeout_s) as r:  # noqa: S310 (localhost only)
        return json.loads(r.read().decode())


@contextlib.contextmanager
def _process(cmd: list[str], **kw: Any) -> Iterator[subprocess.Popen[bytes]]:
    """Start a process in its own process group and always terminate (then kill) that group.

    The ``rerun`` entry point is a Python wrapper that runs the native viewer as a child; ending
    only the wrapper would leave the viewer serving (and spinning a core) after we return.
    """
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True, **kw)

    def signal_group(sig: int) -> None:
        try:
            os.killpg(p.pid, sig)
        except ProcessLookupError:
            pass

    try:
        yield p
    finally:
        signal_group(signal.SIGTERM)
        try:
            p.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            signal_group(signal.SIGKILL)
            p.wait(timeout=5.0)
        signal_group(signal.SIGKILL)  # children that outlived the wrapper


class _DevTools:
    """Minimal Chrome DevTools Protocol client over one websocket."""

    def __init__(self, ws_url: str) -> None:
        import websocket  # websocket-client (dev extra)

        self._ws = websocket.create_connection(ws_url, timeout=60, suppress_origin=True)
        self._id = 0

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self._id += 1
        my_id = self._id
        self._ws.send(json.dumps({"id": my_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self._ws.recv())
            if msg.get("id") == my_id:
                if "error" in msg:
                    raise RuntimeError(f"DevTools {method}: {msg['error']}")
                return dict(msg.get("result", {}))

    def close(self) -> None:
        self._ws.close()


def viewer_url(web_port: int, grpc_port: int) -> str:
    """Web-viewer URL that loads the recording proxied by ``rerun --serve-web``."""
    rec = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
    return f"http://127.0.0.1:{web_port}/?url={rec}"


def screenshot_rrd(
    rrd: Path,
    png: Path,
    *,
    wait_s: float = 25.0,
    chromium: str = CHROMIUM,
    window_px: tuple[int, int] = WINDOW_PX,
    optimize: bool = True,
) -> Path:
    """Render ``rrd`` in the Rerun web viewer (headless chromium) and save a PNG screenshot.

    Parameters
    ----------
    rrd : a finished recording (its embedded default blueprint decides the layout)
    png : output file (parents created)
    wait_s : real time to let the software-rendered viewer load and draw (20-25 s on 2 cores)
    chromium : browser executable (Debian ``chromium``)
    window_px : viewport width, height in pixels
    optimize : serve a ``rerun rrd optimize`` copy (the sink writes many small chunks, e.g.
        2600 -> 92 for a 30 s demo; the software-rendered web viewer ingests the original so
        slowly that only the first seconds show after 25 s)

    Returns
    -------
    the PNG path. Also logs the page title.
    """
    rrd = Path(rrd).resolve()
    png = Path(png)
    if not rrd.exists():
        raise FileNotFoundError(rrd)
    if not Path(chromium).exists():
        raise FileNotFoundError(f"{chromium} missing: apt-get install -y chromium")
    web_port, grpc_port, dbg_port = free_port(), free_port(), free_port()
    env = dict(os.environ, RERUN_ANALYTICS="0")  # never phone home from tests
    serve = [
        rerun_cli(),
        "--serve-web",
        str(rrd),
        "--web-viewer-port",
        str(web_port),
        "--port",
        str(grpc_port),
    ]
    with tempfile.TemporaryDirectory(prefix="gcs-shot-") as tmp:
        profile = str(Path(tmp) / "profile")
        if optimize:
            compact = Path(tmp) / "optimized.rrd"
            subprocess.run(
                [rerun_cli(), "rrd", "optimize", str(rrd), "-o", str(compact)],
                check=True,
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                timeout=120,
            )
            serve[2] = str(compact)
        shot = _capture(
            serve, env, profile, web_port, grpc_port, dbg_port, chromium, window_px, wait_s
        )
    png.parent.mkdir(parents=True, exist_ok=True)
    png.write_bytes(base64.b64decode(shot["data"]))
    return png


def _capture(
    serve: list[str],
    env: dict[str, str],
    profile: str,
    web_port: int,
    grpc_port: int,
    dbg_port: int,
    chromium: str,
    window_px: tuple[int, int],
    wait_s: float,
) -> dict[str, Any]:
    with _process(serve, env=env):
        _wait_port(web_port, STARTUP_TIMEOUT_S)
        _wait_port(grpc_port, STARTUP_TIMEOUT_S)
        browser = [
            chromium,
            *CHROMIUM_FLAGS,
            f"--remote-debugging-port={dbg_port}",
            f"--user-data-dir={profile}",
            f"--window-size={window_px[0]},{window_px[1]}",
            "about:blank",
        ]
        with _process(browser):
            ws_url = _page_ws_url(dbg_port)
            dt = _DevTools(ws_url)
            try:
                dt.call("Page.enable")
                dt.call(
                    "Emulation.setDeviceMetricsOverride",
                    width=window_px[0],
                    height=window_px[1],
                    deviceScaleFactor=1,
                    mobile=False,
                )
                dt.call("Page.navigate", url=viewer_url(web_port, grpc_port))
                time.sleep(wait_s)
                title = dt.call("Runtime.evaluate", expression="document.title")
                log.info("viewer page title: %s", title.get("result", {}).get("value"))
                shot = _settled_screenshot(dt)
            finally:
                dt.close()
    return shot


def screenshot_page(html: Path, png: Path, *, width_px: int = 1200,
                    height_px: int = 2600, timeout_s: float = 120.0) -> Path:
    """Screenshot a static, self-contained HTML page (a fault report) with headless chromium's
    own ``--screenshot`` (enough for a page without scripts, unlike the Rerun viewer)."""
    png = Path(png).resolve()
    png.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as profile:
        cmd = [CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
               f"--window-size={width_px},{height_px}", f"--screenshot={png}",
               Path(html).resolve().as_uri()]
        subprocess.run(cmd, check=True, timeout=timeout_s, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
    if not png.exists():
        raise RuntimeError(f"chromium wrote no screenshot of {html}")
    return png


def _settled_screenshot(dt: _DevTools) -> dict[str, Any]:
    """Capture until the picture stops changing (the viewer is still ingesting on a loaded box).

    The compressed PNG size grows as plot lines and table rows appear, so two captures
    ``SETTLE_POLL_S`` apart whose sizes differ by < ``SETTLE_REL`` mean the view has settled.
    Gives up after ``SETTLE_MAX_S`` and returns the last capture.
    """
    shot = dt.call("Page.captureScreenshot", format="png")
    deadline = time.monotonic() + SETTLE_MAX_S
    while time.monotonic() < deadline:
        time.sleep(SETTLE_POLL_S)
        nxt = dt.call("Page.captureScreenshot", format="png")
        a, b = len(shot["data"]), len(nxt["data"])
        shot = nxt
        if abs(b - a) <= SETTLE_REL * max(a, b):
            break
        log.info("viewer still drawing (png %d -> %d bytes)", a, b)
    return shot


def _page_ws_url(dbg_port: int) -> str:
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError, ValueError):
            for t in _http_json(f"http://127.0.0.1:{dbg_port}/json/list"):
                if t.get("type") == "page" and "webSocketDebuggerUrl" in t:
                    return str(t["webSocketDebuggerUrl"])
        time.sleep(0.2)
    raise TimeoutError(f"chromium DevTools did not come up on port {dbg_port}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--wait", type=float, default=25.0, help="seconds to let the viewer render")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO)
    screenshot_rrd(args.rrd, args.png, wait_s=args.wait)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
