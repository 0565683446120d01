"""Rerun sink: every Rerun call of the monitor lives behind :class:`RerunSink`.

One explicit ``rr.RecordingStream`` per vehicle (never the global one), application id
:data:`APPLICATION_ID` (the blueprints in ``dashboards/`` use the same id), time on the
``vehicle_time`` duration timeline from ``t_us``.

Cost control (the pipeline calls ``publish`` at 100 Hz per vehicle):

- plot values are sampled at ``plot_rate_hz`` (20 Hz default) into column buffers and sent with
  one ``send_columns`` per entity every ``flush_period_s`` (1 s default, so the live view lags
  by up to 1 s; alarms are not delayed). One ``rr.log`` costs
  ~90 µs, one ``send_columns`` ~200 µs regardless of a few rows (stack-notes section 2), so
  batching is ~20x cheaper than per-sample logging;
- alarm events are logged immediately (``rr.TextLog``);
- the 3-D track/attitude is logged at ``track_rate_hz`` (2 Hz default).

``rr.log`` and ``send_columns`` never block: the SDK batches on its own threads.

Entity paths come from :func:`entity_path` only (see its docstring for the tree).
"""

from __future__ import annotations

import logging
import math
import shutil
import socket
import subprocess
import sys
import time
import urllib.parse
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from gcs_monitor.core.constants import EARTH_RADIUS_M
from gcs_monitor.core.frames import quat_from_euler
from gcs_monitor.core.types import ChannelId, Vec, Vec3
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, ChannelStatus, SetStatus
from gcs_monitor.fdi.records import Coverage, Estimate, StepOutput
from gcs_monitor.sinks.schema import channel_unit, dumps, health_to_dict
from gcs_monitor.telemetry.frame import Frame

log = logging.getLogger(__name__)

APPLICATION_ID = "gcs_monitor"
TIMELINE = "vehicle_time"
US_PER_S = 1_000_000

# Display-only geometry of the 3-D view (not physics).
VEHICLE_BOX_HALF_SIZES_FRD_M = (10.0, 14.0, 2.0)  # drawn oversized so it is visible over km
BODY_AXIS_ARROW_M = 25.0
TRACK_MAX_POINTS = 1200  # 10 min at 2 Hz

ALARM_COLORS_RGB = {  # amber / red / green text-log accents
    "warn": (255, 170, 0),
    "error": (230, 40, 40),
    "info": (60, 180, 75),
}
THRESHOLD_COLOR_RGB = (230, 40, 40)
FUSED_COLOR_RGB = (20, 20, 20)


def channel_path(channel: ChannelId) -> str:
    """Entity sub-path of a channel: ``acc/0/x``, ``aoa/2`` (no axis)."""
    base = f"{rr.escape_entity_path_part(channel.kind)}/{int(channel.instance)}"
    return f"{base}/{rr.escape_entity_path_part(channel.axis)}" if channel.axis else base


def entity_path(vehicle: int, *parts: str | int) -> str:
    """The one builder of entity paths. The tree per vehicle is::

        /<v>/sets/<set>/measured/<i>    per-instance measurement of a redundant set
        /<v>/sets/<set>/fused           adaptive weighted fusion (Wan2018 eq. 19)
        /<v>/sets/<set>/reference       what residuals are taken against
        /<v>/sets/<set>/rms/<i>         residual RMS J (Wan2018 eq. 18)
        /<v>/sets/<set>/threshold       J_th
        /<v>/sets/<set>/weight/<i>      voting weights
        /<v>/channels/<ch>/value|rms|threshold        ChannelStatus (ch = kind/instance[/axis])
        /<v>/channels/<ch>/measured|corrected         raw vs corrected (virtual sensor) value
        /<v>/channels/<ch>/fault/<estimator>          reconstructed fault
        /<v>/channels/<ch>/true_fault                 simulation truth (log_true_faults)
        /<v>/estimates/<estimator>/<state>            state vectors (one series per element)
        /<v>/coverage/<family>          share of the last window the family judged
        /<v>/alarms                     TextLog of alarm transitions
        /<v>/health                     TextDocument with the latest health dict
        /<v>/world/track                LineStrips3D of the local NED track
        /<v>/world/vehicle              Transform3D (position + attitude) with box and body axes

    ``parts`` are joined with ``/``; a ChannelId should be passed through :func:`channel_path`.
    """
    tail = "/".join(str(p) for p in parts)
    return f"/{int(vehicle)}/{tail}" if tail else f"/{int(vehicle)}"


def rerun_quat_xyzw(q_ned_frd_wxyz: Vec) -> list[float]:
    """Reorder a scalar-first quaternion to Rerun's ``[x, y, z, w]`` (the only place we do this)."""
    w, x, y, z = (float(v) for v in q_ned_frd_wxyz)
    return [x, y, z, w]


def geodetic_to_local_ned(
    lat_rad: float, lon_rad: float, alt_msl_m: float, origin: tuple[float, float, float]
) -> Vec3:
    """Local NED position (m) relative to ``origin`` = (lat0_rad, lon0_rad, alt0_m).

    Equirectangular (flat-earth) approximation on the spherical earth of Lu2016 eq. 11
    (``EARTH_RADIUS_M``). For display only: error < 0.1 % of the distance within ~50 km.
    """
    lat0, lon0, alt0 = origin
    north = (lat_rad - lat0) * EARTH_RADIUS_M
    east = (lon_rad - lon0) * EARTH_RADIUS_M * math.cos(lat0)
    down = -(alt_msl_m - alt0)
    return np.array([north, east, down])


def imu_measured_value(frame: Frame, channel: ChannelId) -> float:
    """Raw IMU value of an ``acc``/``gyro`` channel from a Frame (NaN when absent)."""
    axes = {"x": 0, "y": 1, "z": 2, "p": 0, "q": 1, "r": 2}
    if channel.kind not in ("acc", "gyro") or channel.axis not in axes:
        return float("nan")
    if channel.instance >= len(frame.imu):
        return float("nan")
    s = frame.imu[channel.instance]
    if s is None:
        return float("nan")
    vec = s.acc_frd_mps2 if channel.kind == "acc" else s.omega_frd_radps
    return float(vec[axes[channel.axis]])


def vehicle_time(t_us: int) -> np.timedelta64:
    """``t_us`` as an exact duration (float seconds would round 2.05 s to 2049999999 ns)."""
    return np.timedelta64(int(t_us), "us")


@dataclass
class _Column:
    times_us: list[int]
    values: list[Any]


class _ColumnBuffer:
    """Per-entity buffers of (time, value) flushed with one ``send_columns`` each."""

    def __init__(self) -> None:
        self._cols: dict[str, _Column] = {}

    def add(self, path: str, t_us: int, value: float | Sequence[float]) -> None:
        col = self._cols.get(path)
        if col is None:
            col = self._cols[path] = _Column([], [])
        col.times_us.append(t_us)
        col.values.append(value)

    def flush(self, rec: rr.RecordingStream) -> int:
        """Send and clear every buffer; returns the number of rows sent."""
        n = 0
        for path, col in self._cols.items():
            if not col.times_us:
                continue
            values = np.asarray(col.values, dtype=np.float64)
            rec.send_columns(
                path,
                indexes=[
                    rr.TimeColumn(
                        TIMELINE, duration=np.asarray(col.times_us, dtype="timedelta64[us]")
                    )
                ],
                columns=rr.Scalars.columns(scalars=values),
            )
            n += len(col.times_us)
            col.times_us.clear()
            col.values.clear()
        return n

    def paths(self) -> set[str]:
        return set(self._cols)


def _alarm_level(event: AlarmEvent) -> rr.TextLogLevel:
    if event.state == AlarmState.CLEARED:
        return rr.TextLogLevel.INFO
    if event.kind == AlarmKind.SET_LOST:
        return rr.TextLogLevel.ERROR
    return rr.TextLogLevel.WARN


def alarm_text(event: AlarmEvent) -> str:
    """One human line per alarm transition (used in the Rerun alarm log)."""
    unit = channel_unit(event.channel)
    mag = "n/a" if math.isnan(event.magnitude) else f"{event.magnitude:+.4g} {unit}".rstrip()
    text = (
        f"{event.state.value.upper()} {event.kind.value} {event.channel} "
        f"{event.fault_type.value} magnitude {mag}, confidence {event.confidence:.2f}, "
        f"J={event.residual_rms:.4g} "
        f"J_th={event.threshold:.4g} [{event.estimator}]"
    )
    return f"{text}: {event.message}" if event.message else text


class WebViewer:
    """A Rerun web viewer and its gRPC proxy, served by the ``rerun`` program on ``bind``.

    Rerun's in-process ``serve_web_viewer`` listens on every interface (0.0.0.0) and has no
    option to change that, so the viewer runs as ``rerun --serve-web --bind <bind>``: on
    127.0.0.1 by default, reachable from elsewhere only when ``bind`` says so. Recordings
    stream to it through ``grpc_url`` (``RerunSink(connect_grpc=viewer.grpc_url)``); one viewer
    shows every vehicle. A port already in use is a ValueError naming it.
    """

    def __init__(self, *, bind: str = "127.0.0.1", web_port: int = 9090,
                 grpc_port: int = 9876, start_timeout_s: float = 30.0) -> None:
        for port in (web_port, grpc_port):
            if not 0 < port < 65536:
                raise ValueError(f"web viewer: port {port} is outside 1..65535")
            with socket.socket() as probe:
                try:
                    probe.bind((bind, port))
                except OSError as exc:
                    why = "already in use" if exc.errno == 98 else (exc.strerror or str(exc))
                    raise ValueError(f"web viewer: cannot listen on {bind}:{port}: {why}"
                                     ) from None
        exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
        self.bind = bind
        host = "127.0.0.1" if bind in ("0.0.0.0", "::") else bind
        self.proc = subprocess.Popen(
            [exe, "--serve-web", "--bind", bind, "--web-viewer-port", str(web_port),
             "--port", str(grpc_port)],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        self.grpc_url = f"rerun+http://{host}:{grpc_port}/proxy"
        self.viewer_url = (f"http://{host}:{web_port}/?url="
                           f"{urllib.parse.quote(self.grpc_url, safe='')}")
        t_end = time.monotonic() + start_timeout_s
        while time.monotonic() < t_end:
            if self.proc.poll() is not None:
                err = (self.proc.stderr.read() if self.proc.stderr else b"").decode(
                    errors="replace").strip().splitlines()
                raise ValueError(f"web viewer: rerun exited: {err[-1] if err else '?'}")
            try:
                with socket.create_connection((host, grpc_port), timeout=0.2), \
                        socket.create_connection((host, web_port), timeout=0.2):
                    break
            except OSError:
                time.sleep(0.1)
        else:
            self.close()
            raise ValueError(f"web viewer: rerun did not listen within {start_timeout_s:g} s")
        log.info("rerun web viewer: %s", self.viewer_url)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        if self.proc.stderr is not None:
            self.proc.stderr.close()


class RerunSink:
    """Rerun output for one vehicle (Sink protocol).

    Parameters
    ----------
    vehicle : MAVLink system id
    rrd_path : write the recording (with the default blueprint embedded) to this .rrd file
    web : serve live: a :class:`WebViewer` of this sink alone (gRPC on ``127.0.0.1:grpc_port``,
        the web viewer on ``127.0.0.1:web_port``; no browser is opened; the URL is logged and in
        ``viewer_url``). Several vehicles share one: start a WebViewer and pass its
        ``grpc_url`` as ``connect_grpc``
    grpc_port, web_port : ports for ``web`` (Rerun defaults 9876 / 9090 when None)
    connect_grpc : stream to an already running viewer (``rerun+http://host:port/proxy``).
        Pitfall: a URL nobody listens on makes close() block 5-10 s (stack-notes section 2).
    blueprint : the default blueprint the viewer applies (``dashboards.default_blueprint``);
        None sends none
    plot_rate_hz : sampling rate of the time-series plots (vehicle time)
    flush_period_s : how much vehicle time of plot samples is buffered per ``send_columns``
    track_rate_hz : rate of the 3-D track/attitude update
    recording_id : defaults to ``vehicle-<vehicle>-<wall time>``
    """

    def __init__(
        self,
        vehicle: int,
        *,
        rrd_path: Path | str | None = None,
        web: bool = False,
        grpc_port: int | None = None,
        web_port: int | None = None,
        connect_grpc: str | None = None,
        blueprint: rrb.BlueprintLike | None = None,
        plot_rate_hz: float = 20.0,
        flush_period_s: float = 1.0,
        track_rate_hz: float = 2.0,
        recording_id: str | None = None,
    ) -> None:
        if rrd_path is None and not web and connect_grpc is None:
            raise ValueError("RerunSink needs rrd_path, web=True or connect_grpc")
        if plot_rate_hz <= 0 or track_rate_hz <= 0 or flush_period_s < 0:
            raise ValueError("plot_rate_hz and track_rate_hz must be > 0, flush_period_s >= 0")
        self.vehicle = int(vehicle)
        self._plot_period_us = round(US_PER_S / plot_rate_hz)
        self._track_period_us = round(US_PER_S / track_rate_hz)
        self._flush_period_us = round(flush_period_s * US_PER_S)
        rid = recording_id or f"vehicle-{self.vehicle}-{int(time.time() * 1e3)}"
        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=rid)
        self.rrd_path = Path(rrd_path) if rrd_path is not None else None
        self.viewer_url: str | None = None
        self.grpc_url: str | None = None
        sinks: list[Any] = []
        if self.rrd_path is not None:
            self.rrd_path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.rrd_path)))
        self._viewer: WebViewer | None = None
        if web:
            self._viewer = WebViewer(web_port=web_port if web_port is not None else 9090,
                                     grpc_port=grpc_port if grpc_port is not None else 9876)
            self.grpc_url = self._viewer.grpc_url
            self.viewer_url = self._viewer.viewer_url
            sinks.append(rr.GrpcSink(self.grpc_url))
            log.info("rerun web viewer for vehicle %d: %s", self.vehicle, self.viewer_url)
        if connect_grpc is not None:
            sinks.append(rr.GrpcSink(connect_grpc))
        self.rec.set_sinks(*sinks, default_blueprint=blueprint)

        self._paths: dict[tuple[str | int, ...], str] = {}
        self._buf = _ColumnBuffer()
        self._styled: set[str] = set()
        self._last_plot_us: int | None = None
        self._last_sets_us: int | None = None
        self._last_flush_us: int | None = None
        self._last_track_us: int | None = None
        self._last_truth_us: int | None = None
        self._last_t_us = 0
        self._origin: tuple[float, float, float] | None = None
        self._track: deque[list[float]] = deque(maxlen=TRACK_MAX_POINTS)
        self._closed = False
        self.n_publish = 0
        self.n_rows_sent = 0
        self.n_alarms = 0
        self._log_static_world()

    # ----------------------------------------------------------------- helpers
    def _path(self, *parts: str | int) -> str:
        # Memoised: building ~60 path strings per sample was a third of the publish cost.
        p = self._paths.get(parts)
        if p is None:
            p = self._paths[parts] = entity_path(self.vehicle, *parts)
        return p

    def _style(
        self, path: str, name: str | list[str], color: tuple[int, int, int] | None = None
    ) -> None:
        """Series name/colour, logged once per entity as static data."""
        if path in self._styled:
            return
        self._styled.add(path)
        if color is None:
            self.rec.log(path, rr.SeriesLines(names=name), static=True)
        else:
            self.rec.log(path, rr.SeriesLines(names=name, colors=[color]), static=True)

    def _log_static_world(self) -> None:
        world = self._path("world")
        # NED is right-handed (N x E = D): show it as is, with "down" pointing down on screen.
        self.rec.log(world, rr.ViewCoordinates.RIGHT_HAND_Z_DOWN, static=True)
        veh = self._path("world", "vehicle")
        self.rec.log(
            f"{veh}/body",
            rr.Boxes3D(half_sizes=[VEHICLE_BOX_HALF_SIZES_FRD_M], colors=[(80, 130, 230)]),
            static=True,
        )
        a = BODY_AXIS_ARROW_M
        self.rec.log(
            f"{veh}/axes",
            rr.Arrows3D(
                vectors=[[a, 0, 0], [0, a, 0], [0, 0, a]],
                colors=[(230, 40, 40), (40, 180, 40), (40, 80, 230)],
                labels=["F", "R", "D"],
            ),
            static=True,
        )

    # ----------------------------------------------------------------- Sink protocol
    def publish(self, frame: Frame, out: StepOutput) -> None:
        estimates, events, sets, channels = out.estimates, out.events, out.sets, out.channels
        if self._closed:
            return
        self.n_publish += 1
        t_us = int(frame.t_us)
        self._last_t_us = t_us
        if events:
            self._log_events(events)
        if self._last_plot_us is None or t_us - self._last_plot_us >= self._plot_period_us:
            self._last_plot_us = t_us
            self._sample_plots(frame, estimates, sets, channels)
            self._sample_coverage(t_us, out.coverage)
            if sets:
                self._last_sets_us = t_us
        elif sets and (self._last_sets_us is None
                       or t_us - self._last_sets_us >= self._plot_period_us):
            # set statuses come with air-data frames, which need not be the decimated plot frames
            self._last_sets_us = t_us
            self._sample_plots(frame, (), sets, ())
        if self._last_track_us is None or t_us - self._last_track_us >= self._track_period_us:
            self._last_track_us = t_us
            self._log_world(frame)
        if self._last_flush_us is None:
            self._last_flush_us = t_us
        elif t_us - self._last_flush_us >= self._flush_period_us or t_us < self._last_flush_us:
            self._last_flush_us = t_us
            self.n_rows_sent += self._buf.flush(self.rec)

    def update_health(self, health: dict[str, Any]) -> None:
        if self._closed:
            return
        payload = health_to_dict(health, vehicle=self.vehicle, wall_time_s=time.time())
        self.rec.set_time(TIMELINE, duration=vehicle_time(self._last_t_us))
        text = "```json\n" + dumps(payload) + "\n```"
        self.rec.log(self._path("health"), rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN))

    def log_true_faults(self, t_us: int, faults: dict[ChannelId, float]) -> None:
        """Simulation truth of the injected faults (SI), drawn beside the reconstructed fault."""
        if (
            self._last_truth_us is not None
            and 0 <= t_us - self._last_truth_us < self._plot_period_us
        ):
            return  # same decimation as the plots
        self._last_truth_us = t_us
        for ch, value in faults.items():
            p = self._path("channels", channel_path(ch), "true_fault")
            self._style(p, f"{ch} true fault", (120, 120, 120))
            self._buf.add(p, t_us, float(value))

    def flush(self) -> None:
        """Send buffered plot samples now."""
        self.n_rows_sent += self._buf.flush(self.rec)

    def close(self) -> None:
        if self._closed:
            return
        self.flush()
        self._closed = True
        self.rec.flush(timeout_sec=5.0)
        self.rec.disconnect()
        if self._viewer is not None:
            self._viewer.close()

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------------- internals
    def _log_events(self, events: Sequence[AlarmEvent]) -> None:
        path = self._path("alarms")
        for ev in events:
            self.rec.set_time(TIMELINE, duration=vehicle_time(ev.t_us))
            self.rec.log(path, rr.TextLog(alarm_text(ev), level=_alarm_level(ev)))
            self.n_alarms += 1

    def _sample_plots(
        self,
        frame: Frame,
        estimates: Sequence[Estimate],
        sets: Sequence[SetStatus],
        channels: Sequence[ChannelStatus],
    ) -> None:
        t_us = int(frame.t_us)
        add = self._buf.add
        for s in sets:
            name = s.name
            for i, v in enumerate(s.measured):
                p = self._path("sets", name, "measured", i)
                self._style(p, f"{name} {i}")
                add(p, t_us, v)
            for i, v in enumerate(s.rms):
                p = self._path("sets", name, "rms", i)
                self._style(p, f"J {name} {i}")
                add(p, t_us, v)
            for i, v in enumerate(s.weights):
                p = self._path("sets", name, "weight", i)
                self._style(p, f"w {name} {i}")
                add(p, t_us, v)
            p = self._path("sets", name, "fused")
            self._style(p, f"{name} fused", FUSED_COLOR_RGB)
            add(p, t_us, s.fused)
            p = self._path("sets", name, "reference")
            self._style(p, f"{name} reference", (150, 150, 150))
            add(p, t_us, s.reference)
            p = self._path("sets", name, "threshold")
            self._style(p, f"J_th {name}", THRESHOLD_COLOR_RGB)
            add(p, t_us, s.threshold)
        measured_done: set[ChannelId] = set()
        for c in channels:
            base = channel_path(c.channel)
            for leaf, v in (("value", c.value), ("rms", c.rms), ("threshold", c.threshold)):
                p = self._path("channels", base, leaf)
                if leaf == "threshold":
                    self._style(p, f"{c.channel} J_th", THRESHOLD_COLOR_RGB)
                else:
                    self._style(p, f"{c.channel} {leaf}")
                add(p, t_us, v)
            self._add_measured(frame, c.channel, t_us, measured_done)
        for est in estimates:
            if not est.available:
                continue
            for state, vec in est.states.items():
                arr = np.atleast_1d(np.asarray(vec, dtype=np.float64))
                p = self._path("estimates", est.name, state)
                self._style(p, [f"{state}[{k}]" for k in range(arr.size)])
                add(p, t_us, arr.tolist())
            for ch, v in est.faults.items():
                p = self._path("channels", channel_path(ch), "fault", est.name)
                self._style(p, f"{ch} fault ({est.name})")
                add(p, t_us, v)
            for ch, v in est.virtual.items():
                p = self._path("channels", channel_path(ch), "corrected")
                self._style(p, f"{ch} corrected")
                add(p, t_us, v)
                self._add_measured(frame, ch, t_us, measured_done)

    def _sample_coverage(self, t_us: int, coverage: Sequence[Coverage]) -> None:
        """Each family's share of the last window judged (fdi.coverage); 0.9 is the line below
        which monitor_degraded is raised."""
        for c in coverage:
            if c.recent != c.recent:  # unavailable or starting: nothing to plot
                continue
            p = self._path("coverage", c.family)
            self._style(p, f"{c.family} coverage")
            self._buf.add(p, t_us, c.recent)

    def _add_measured(self, frame: Frame, ch: ChannelId, t_us: int, done: set[ChannelId]) -> None:
        if ch in done or ch.kind not in ("acc", "gyro"):
            return
        done.add(ch)
        v = imu_measured_value(frame, ch)
        if not math.isnan(v):
            p = self._path("channels", channel_path(ch), "measured")
            self._style(p, f"{ch} measured")
            self._buf.add(p, t_us, v)

    def _log_world(self, frame: Frame) -> None:
        if not (math.isfinite(frame.lat_rad) and math.isfinite(frame.lon_rad)):
            return
        alt = frame.alt_msl_m if math.isfinite(frame.alt_msl_m) else 0.0
        if self._origin is None:
            self._origin = (frame.lat_rad, frame.lon_rad, alt)
        pos_ned_m = geodetic_to_local_ned(frame.lat_rad, frame.lon_rad, alt, self._origin)
        self._track.append(pos_ned_m.tolist())
        self.rec.set_time(TIMELINE, duration=vehicle_time(frame.t_us))
        self.rec.log(
            self._path("world", "track"),
            rr.LineStrips3D([list(self._track)], colors=[(255, 140, 0)], radii=[1.5]),
        )
        if frame.euler_rad is not None:
            q_xyzw = rerun_quat_xyzw(quat_from_euler(*(float(a) for a in frame.euler_rad)))
            self.rec.log(
                self._path("world", "vehicle"),
                rr.Transform3D(
                    translation=pos_ned_m.tolist(), quaternion=rr.Quaternion(xyzw=q_xyzw)
                ),
            )
        else:
            self.rec.log(
                self._path("world", "vehicle"), rr.Transform3D(translation=pos_ned_m.tolist())
            )
