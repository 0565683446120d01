"""Screenshot a finished .rrd in the Rerun web viewer with headless chromium.

Recipe (stack-notes section 2): serve the file with the venv's ``rerun`` CLI
(``rerun --serve-web x.rrd --web-viewer-port P --port Q``), start headless chromium with
``--remote-debugging-port``, navigate over the DevTools protocol (``websocket-client``), wait
20-25 s of real time for the software-rendered viewer, then ``Page.captureScreenshot``.
chromium's own ``--screenshot`` captures only "Loading Application Bundle..." and is not used.

Also holds :func:`write_synthetic_rrd`, a deterministic demo recording (seeded) that drives the
real :class:`~gcs_monitor.sinks.rerun_sink.RerunSink` with synthetic Frames, set/channel status
and alarms; tests and the docs image use it until a real demo run replaces it.

Usage::

    python -m gcs_monitor.tools.screenshot run.rrd docs/img/dashboard.png [--wait 25]
    python -m gcs_monitor.tools.screenshot --synthetic demo.rrd docs/img/dashboard.png
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import json
import logging
import math
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

import numpy as np

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


# --------------------------------------------------------------------------- synthetic demo
def write_synthetic_rrd(
    path: Path,
    *,
    vehicle: int = 1,
    duration_s: float = 30.0,
    seed: int = 0,
    fault_t_s: float = 12.0,
) -> dict[str, Any]:
    """Drive a real RerunSink with a deterministic synthetic flight and write ``path``.

    A 25 m/s circle (radius 300 m, 20 deg bank), triplex AoA with a +2 deg bias on vane 2 from
    ``fault_t_s``, and a +0.5 m/s^2 accelerometer-x bias on IMU 0 from ``fault_t_s + 3 s`` that
    a first-order "reconstruction" follows. RMS, weights and alarms come from simple stand-ins
    (a moving RMS against the median, inverse-RMS weights) so every dashboard view has data; it is
    a demo of the display, not of the FDI algorithms.

    Returns counters: frames, events and the sink's publish statistics.
    """
    from dashboards.blueprints import default_blueprint
    from gcs_monitor.core.types import ChannelId
    from gcs_monitor.fdi.events import (
        AlarmEvent,
        AlarmKind,
        AlarmState,
        ChannelStatus,
        FaultType,
        SetStatus,
    )
    from gcs_monitor.fdi.records import Estimate, StepOutput
    from gcs_monitor.sinks.rerun_sink import RerunSink
    from gcs_monitor.telemetry.frame import Frame, ImuSample

    rng = np.random.default_rng(seed)
    dt_s = 0.01
    n = round(duration_s / dt_s)
    speed_mps, radius_m, bank_rad = 25.0, 300.0, math.radians(20.0)
    lat0, lon0, alt0 = math.radians(47.0), math.radians(8.0), 500.0
    earth_r = 6_367_000.0
    aoa_bias_rad, acc_bias_mps2 = math.radians(2.0), 0.5
    rms_window = 50
    aoa_th_rad, acc_th_mps2 = math.radians(0.8), 0.2
    resid_hist = np.zeros((rms_window, 3))
    acc_fault_hat = 0.0
    raised_aoa = raised_acc = False
    n_events = 0
    with RerunSink(vehicle, rrd_path=path, recording_id=f"synthetic-{vehicle}-{seed}",
                   blueprint=default_blueprint(vehicle)) as sink:
        for k in range(n):
            t_s = k * dt_s
            t_us = round(t_s * 1e6)
            psi = speed_mps / radius_m * t_s
            north, east = radius_m * math.sin(psi), radius_m * (1 - math.cos(psi))
            aoa_true = 0.06 + 0.01 * math.sin(0.7 * t_s)
            aoa = aoa_true + rng.normal(0.0, math.radians(0.15), 3)
            if t_s >= fault_t_s:
                aoa[2] += aoa_bias_rad
            acc = np.array([0.3, 0.0, -9.81 / math.cos(bank_rad)]) + rng.normal(0, 0.05, 3)
            acc_fault = acc_bias_mps2 if t_s >= fault_t_s + 3.0 else 0.0
            acc[0] += acc_fault
            gyro = np.array([0.0, 0.02, speed_mps / radius_m]) + rng.normal(0, 0.002, 3)
            frame = Frame(
                t_us=t_us,
                imu=[ImuSample(t_us, 0, acc, gyro)],
                euler_rad=np.array([bank_rad, aoa_true, psi]),
                lat_rad=lat0 + north / earth_r,
                lon_rad=lon0 + east / (earth_r * math.cos(lat0)),
                alt_msl_m=alt0 + 5.0 * math.sin(0.2 * t_s),
                aoa_rad=aoa,
            )
            cas = 25.0 + 0.3 * math.sin(0.5 * t_s) + rng.normal(0.0, 0.1, 3)
            frame.cas_mps = cas
            cas_med = float(np.median(cas))
            cas_set = SetStatus(
                name="cas",
                t_us=t_us,
                measured=tuple(cas),
                reference=cas_med,
                fused=cas_med,
                weights=(1 / 3, 1 / 3, 1 / 3),
                rms=(0.1, 0.1, 0.1),
                threshold=1.0,
                faulty=(False, False, False),
                configuration="triplex",
            )
            fused_med = float(np.median(aoa))
            resid_hist[k % rms_window] = aoa - fused_med
            rms = np.sqrt(np.mean(resid_hist**2, axis=0))
            w = 1.0 / np.maximum(rms, 1e-4)
            w /= w.sum()
            faulty = tuple(bool(r > aoa_th_rad) for r in rms)
            aoa_set = SetStatus(
                name="aoa",
                t_us=t_us,
                measured=tuple(aoa),
                reference=fused_med,
                fused=float(w @ aoa),
                weights=tuple(w),
                rms=tuple(rms),
                threshold=aoa_th_rad,
                faulty=faulty,
                configuration="triplex" if not any(faulty) else "duplex",
            )
            acc_fault_hat += dt_s / 0.8 * (acc_fault - acc_fault_hat)  # 0.8 s first-order lag
            ch_acc = [ChannelId("acc", 0, ax) for ax in "xyz"]
            chans = [
                ChannelStatus(
                    ch,
                    t_us,
                    value=acc_fault_hat if ch.axis == "x" else 0.0,
                    rms=abs(acc_fault_hat) if ch.axis == "x" else 0.02,
                    threshold=acc_th_mps2,
                    faulty=False,
                    estimator="imu_ts",
                )
                for ch in ch_acc
            ]
            est = Estimate(
                name="imu_ts",
                t_us=t_us,
                states={
                    "vel_ned_mps": np.array(
                        [speed_mps * math.cos(psi), speed_mps * math.sin(psi), 0.0]
                    )
                },
                faults={ch_acc[0]: acc_fault_hat},
                virtual={
                    ch: float(acc[i] - (acc_fault_hat if i == 0 else 0.0))
                    for i, ch in enumerate(ch_acc)
                },
            )
            events: list[AlarmEvent] = []
            if faulty[2] and not raised_aoa:
                raised_aoa = True
                events.append(
                    AlarmEvent(
                        t_us,
                        ChannelId("aoa", 2),
                        AlarmState.RAISED,
                        AlarmKind.SENSOR_FAULT,
                        FaultType.BIAS,
                        float(aoa[2] - fused_med),
                        float(rms[2]),
                        aoa_th_rad,
                        "voting",
                        "vane 2 disagrees",
                        vehicle,
                    )
                )
            if acc_fault_hat > acc_th_mps2 and not raised_acc:
                raised_acc = True
                events.append(
                    AlarmEvent(
                        t_us,
                        ch_acc[0],
                        AlarmState.RAISED,
                        AlarmKind.SENSOR_FAULT,
                        FaultType.BIAS,
                        acc_fault_hat,
                        acc_fault_hat,
                        acc_th_mps2,
                        "imu_ts",
                        "accelerometer x bias",
                        vehicle,
                    )
                )
            n_events += len(events)
            sink.log_true_faults(t_us, {ch_acc[0]: acc_fault})
            sink.publish(frame, StepOutput(events=events, estimates=[est], sets=[aoa_set, cas_set],
                                           channels=chans))
            if k % 100 == 0:
                sink.update_health({"alarms_active": int(raised_aoa) + int(raised_acc)})
        stats = {
            "frames": n,
            "events": n_events,
            "publish": sink.n_publish,
            "rows_sent": sink.n_rows_sent,
        }
    return stats


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", type=Path)
    ap.add_argument("png", type=Path)
    ap.add_argument("--wait", type=float, default=25.0, help="seconds to let the viewer render")
    ap.add_argument("--synthetic", action="store_true", help="first write a synthetic demo rrd")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO)
    if args.synthetic:
        write_synthetic_rrd(args.rrd)
    screenshot_rrd(args.rrd, args.png, wait_s=args.wait)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
