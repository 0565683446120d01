"""The one place that opens Zenoh sessions: configuration, clear errors, and a small bus API.

Every Zenoh user of the monitor (the ``zenoh:`` source, the bridge, fleet workers, the Zenoh
sink, ``gcs-monitor alarms`` and ``gcs-monitor router``) opens its session through
:func:`open_bus`, so one set of rules holds everywhere:

* **Loopback by default.** Listen endpoints default to ``tcp/127.0.0.1:<port>``; Zenoh's own
  default (``tcp/[::]:0``, every interface) is never used. Multicast and gossip scouting are
  off; peers find each other only through explicit endpoints (or a router).
* **Configuration file.** ``config_file`` (JSON5, Zenoh's own format) is the base: TLS
  (``transport/link/tls``), access control (``access_control``), timeouts. Options given on the
  command line override it; where neither says, the defaults above apply. A key the file sets
  (mode, listen or connect endpoints) is kept unless the command line sets it.
* **TLS from the command line.** ``tls_ca`` / ``tls_cert`` / ``tls_key`` set
  ``transport/link/tls``: the CA that verifies the other side, and this side's certificate and
  key (listening and connecting). With a certificate, mutual TLS is on: a listener then refuses
  a peer that shows no certificate signed by the CA.
* **Clear errors.** A port already in use, an endpoint that cannot be reached when
  ``connect_timeout_s`` is set, a bad file: :class:`ZenohError` with one line that says what
  failed, never a Rust backtrace path.

A session with a callback subscriber or queryable hangs the process at exit unless it is
closed (stack-notes section 3): :class:`ZenohBus` undeclares everything it declared and closes
its session in :meth:`ZenohBus.close`, registered with ``atexit``.
"""

from __future__ import annotations

import atexit
import json
import logging
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

log = logging.getLogger(__name__)

DEFAULT_PORT = 7447
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
MODES = ("peer", "client", "router")
LOOPBACK_HOSTS = ("127.", "localhost", "[::1]", "::1")
RAW_PREFIX = "mavlink"  # raw MAVLink frames: mavlink/<sysid>/rx
_RUST_LOCATION = re.compile(r"\s+at /\S+?\.rs:\d+\.?")


class ZenohError(RuntimeError):
    """A Zenoh session could not be opened or used; the message is one line for the operator."""


def short_error(exc: BaseException) -> str:
    """Zenoh's error text without source paths, cut to its first clause."""
    text = _RUST_LOCATION.sub("", str(exc)).strip()
    text = text.replace("\n", " ")
    m = re.search(r"Can not create a new \w+ listener bound to (\S+?): \[.*?: (.+?) \(os error",
                  text)
    if m:
        return f"cannot listen on {m.group(1)}: {m.group(2).lower()}"
    m = re.search(r"Unable to connect to any of \[(.*?)\]", text)
    if m:
        eps = re.findall(r"Single\((.*?)\)", m.group(1)) or [m.group(1)]
        return f"cannot reach {', '.join(eps)} (nothing listening, refused, or TLS rejected)"
    return text[:300]


@dataclass(frozen=True)
class ZenohOptions:
    """How to open a session (module docstring).

    Attributes
    ----------
    mode : ``peer``, ``client`` or ``router``; None: the file's, else ``peer``
    listen, connect : endpoints (``tcp/HOST:PORT``, ``tls/HOST:PORT``); None: the file's, else
        the role's defaults (see :meth:`with_defaults`)
    config_file : Zenoh JSON5 configuration (TLS, access control, ...)
    tls_ca, tls_cert, tls_key : PEM files: the CA, this side's certificate and private key
    connect_timeout_s : fail (``ZenohError``) when no connect endpoint is reachable within this
        time; None: keep retrying in the background (a worker started before its router)
    lease_s : how long a silent peer is kept (Zenoh's lease, 10 s by default); a host that
        vanishes without closing its sockets is noticed after this long
    """

    mode: str | None = None
    listen: tuple[str, ...] | None = None
    connect: tuple[str, ...] | None = None
    config_file: Path | None = None
    tls_ca: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None
    connect_timeout_s: float | None = None
    lease_s: float | None = None

    def __post_init__(self) -> None:
        if self.mode is not None and self.mode not in MODES:
            raise ValueError(f"zenoh mode {self.mode!r}: expected one of {', '.join(MODES)}")
        for ep in (self.listen or ()) + (self.connect or ()):
            check_endpoint(ep)
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("--zenoh-cert and --zenoh-key go together")
        for p in (self.config_file, self.tls_ca, self.tls_cert, self.tls_key):
            if p is not None and not Path(p).is_file():
                raise ValueError(f"{p}: no such file")


def check_endpoint(ep: str) -> None:
    """Raise ValueError unless ``ep`` looks like ``proto/host:port`` with a valid port."""
    proto, sep, rest = ep.partition("/")
    if not sep or proto not in ("tcp", "tls", "udp", "quic", "ws", "unixsock-stream"):
        raise ValueError(f"zenoh endpoint {ep!r}: expected tcp/HOST:PORT or tls/HOST:PORT")
    if proto == "unixsock-stream":
        return
    host, _, port = rest.split("#", 1)[0].rpartition(":")
    if not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"zenoh endpoint {ep!r}: expected {proto}/HOST:PORT, port 0..65535")


def is_loopback(ep: str) -> bool:
    host = ep.partition("/")[2].rpartition(":")[0]
    return host.startswith(LOOPBACK_HOSTS)


def _file_sets(base: zenoh.Config, key: str) -> bool:
    """Whether the configuration file changed ``key`` from Zenoh's default."""
    return bool(base.get_json(key) != zenoh.Config().get_json(key))


@dataclass(frozen=True)
class RoleDefaults:
    """What a role uses where neither the command line nor the file says (loopback only)."""

    mode: str = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()


def make_config(opts: ZenohOptions, defaults: RoleDefaults = RoleDefaults()) -> zenoh.Config:
    """The Zenoh configuration of ``opts`` (module docstring for the precedence)."""
    d_mode, d_listen, d_connect = defaults.mode, defaults.listen, defaults.connect
    try:
        c = zenoh.Config.from_file(str(opts.config_file)) if opts.config_file else zenoh.Config()
    except zenoh.ZError as exc:
        raise ZenohError(f"zenoh config {opts.config_file}: {short_error(exc)}") from None
    from_file = opts.config_file is not None

    def keep(key: str) -> bool:
        return from_file and _file_sets(c, key)

    if opts.mode is not None or not keep("mode"):
        c.insert_json5("mode", json.dumps(opts.mode or d_mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/gossip/enabled", "false")
    if opts.listen is not None or not keep("listen/endpoints"):
        listen = list(opts.listen if opts.listen is not None else d_listen)
        c.insert_json5("listen/endpoints", json.dumps(listen))
    if opts.connect is not None or not keep("connect/endpoints"):
        connect = list(opts.connect if opts.connect is not None else d_connect)
        c.insert_json5("connect/endpoints", json.dumps(connect))
    if opts.connect_timeout_s is not None:
        c.insert_json5("connect/timeout_ms", str(round(opts.connect_timeout_s * 1000)))
        c.insert_json5("connect/exit_on_failure", "true")
    if opts.lease_s is not None:
        c.insert_json5("transport/link/tx/lease", str(round(opts.lease_s * 1000)))
    tls = "transport/link/tls/"
    if opts.tls_ca is not None:
        c.insert_json5(tls + "root_ca_certificate", json.dumps(str(opts.tls_ca)))
    if opts.tls_cert is not None and opts.tls_key is not None:
        for side in ("listen", "connect"):
            c.insert_json5(f"{tls}{side}_certificate", json.dumps(str(opts.tls_cert)))
            c.insert_json5(f"{tls}{side}_private_key", json.dumps(str(opts.tls_key)))
        c.insert_json5(tls + "enable_mtls", "true")
    return c


def endpoints_of(c: zenoh.Config) -> tuple[list[str], list[str]]:
    """(listen, connect) endpoints of a configuration."""
    def eps(key: str) -> list[str]:
        v = json.loads(c.get_json(key))
        if isinstance(v, dict):  # per-mode form {"peer": [...], "router": [...]}
            mode = json.loads(c.get_json("mode")) or "peer"
            v = v.get(mode, [])
        return [str(x) for x in v]
    return eps("listen/endpoints"), eps("connect/endpoints")


class ZenohBus:
    """One Zenoh session and everything declared on it (publishers, subscribers, queryables,
    liveliness tokens); :meth:`close` undeclares them all and closes the session.

    Callbacks run on Zenoh threads: keep them short and protect shared state.
    """

    def __init__(self, opts: ZenohOptions | None = None, *, what: str = "zenoh",
                 defaults: RoleDefaults = RoleDefaults()) -> None:
        self.opts = opts or ZenohOptions()
        conf = make_config(self.opts, defaults)
        self.listen, self.connect = endpoints_of(conf)
        for ep in self.listen:
            if ep.startswith("tcp/") and not is_loopback(ep):
                log.warning("%s listens on %s without TLS: anyone who can reach it can read "
                            "and publish (use tls/... and --zenoh-config with access_control)",
                            what, ep)
        try:
            self.session: zenoh.Session = zenoh.open(conf)
        except zenoh.ZError as exc:
            raise ZenohError(f"{what}: {short_error(exc)}") from None
        self._lock = threading.Lock()
        self._declared: list[Any] = []
        self._closed = False
        atexit.register(self.close)

    @property
    def zid(self) -> str:
        return str(self.session.zid())

    def _keep(self, obj: Any) -> Any:
        with self._lock:
            self._declared.append(obj)
        return obj

    def forget(self, obj: Any) -> None:
        """Undeclare one object declared through this bus."""
        with self._lock:
            if obj in self._declared:
                self._declared.remove(obj)
        try:
            obj.undeclare()
        except zenoh.ZError:
            pass

    # -- publishing ------------------------------------------------------------------------
    def publisher(self, key: str, *, reliable: bool = True, block: bool = False,
                  history: int = 0, heartbeat_s: float | None = None, json_: bool = True) -> Any:
        """A publisher on ``key``. ``history`` > 0: an advanced publisher (``zenoh.ext``) that
        keeps the last ``history`` samples for late or recovering subscribers and announces
        itself, with sequence-number heartbeats every ``heartbeat_s`` so a subscriber notices
        a missed sample even when no new one follows."""
        enc = zenoh.Encoding.APPLICATION_JSON if json_ else zenoh.Encoding.ZENOH_BYTES
        cc = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
        rel = zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT
        if history > 0:
            import zenoh.ext as zx

            miss = (zx.MissDetectionConfig(heartbeat=heartbeat_s, sporadic_heartbeat=None)
                    if heartbeat_s else None)
            pub: Any = zx.declare_advanced_publisher(
                self.session, key, encoding=enc, congestion_control=cc, reliability=rel,
                cache=zx.CacheConfig(max_samples=history), sample_miss_detection=miss,
                publisher_detection=True)
        else:
            pub = self.session.declare_publisher(key, encoding=enc, congestion_control=cc,
                                                 reliability=rel)
        return self._keep(pub)

    # -- receiving -------------------------------------------------------------------------
    def subscribe(self, key: str, callback: Callable[[str, bytes], None]) -> Any:
        """Call ``callback(key, payload)`` for every sample on ``key`` (a zenoh thread)."""
        def on_sample(s: zenoh.Sample) -> None:
            callback(str(s.key_expr), s.payload.to_bytes())

        return self._keep(self.session.declare_subscriber(key, on_sample))

    def subscribe_history(self, key: str, callback: Callable[[str, bytes], None], *,
                          history: int, on_miss: Callable[[str, int], None] | None = None
                          ) -> Any:
        """An advanced subscriber (``zenoh.ext``): on declaration it fetches up to ``history``
        cached samples of every matching advanced publisher (also of publishers that appear
        later), recovers samples it missed (sequence numbers and heartbeats), and reports what
        could not be recovered to ``on_miss(source, count)``."""
        import zenoh.ext as zx

        def on_sample(s: zenoh.Sample) -> None:
            callback(str(s.key_expr), s.payload.to_bytes())

        sub = zx.declare_advanced_subscriber(
            self.session, key, on_sample,
            history=zx.HistoryConfig(detect_late_publishers=True, max_samples=history),
            recovery=zx.RecoveryConfig(heartbeat=True, periodic_queries=None),
            subscriber_detection=True)
        self._keep(sub)
        if on_miss is not None:
            listener = sub.sample_miss_listener(lambda m: on_miss(str(m.source), int(m.nb)))
            if listener is not None and hasattr(listener, "undeclare"):
                self._keep(listener)
        return sub

    def queryable(self, key: str, answer: Callable[[str], str | bytes | None]) -> Any:
        """Answer ``get`` on ``key``: ``answer(selector_key)`` returns the payload (None: no
        reply)."""
        def on_query(q: zenoh.Query) -> None:
            try:
                payload = answer(str(q.key_expr))
                if payload is not None:
                    q.reply(key if "*" not in key else str(q.key_expr), payload,
                            encoding=zenoh.Encoding.APPLICATION_JSON)
            except zenoh.ZError:
                log.debug("reply on %s failed", key, exc_info=True)

        return self._keep(self.session.declare_queryable(key, on_query))

    def get(self, key: str, *, timeout_s: float = 1.0) -> list[tuple[str, bytes]]:
        """Query ``key``: (key, payload) of every reply within ``timeout_s``."""
        out = []
        for r in self.session.get(key, timeout=timeout_s):
            if r.ok is not None:
                out.append((str(r.ok.key_expr), r.ok.payload.to_bytes()))
        return out

    # -- liveliness ------------------------------------------------------------------------
    def token(self, key: str) -> Any:
        """Declare a liveliness token: it disappears for everyone when this session ends."""
        return self._keep(self.session.liveliness().declare_token(key))

    def watch_tokens(self, key: str, callback: Callable[[str, bool], None]) -> Any:
        """``callback(key, alive)`` for tokens matching ``key``: the present ones at once
        (history), then every appearance (True) and disappearance (False)."""
        def on_sample(s: zenoh.Sample) -> None:
            callback(str(s.key_expr), s.kind == zenoh.SampleKind.PUT)

        return self._keep(self.session.liveliness().declare_subscriber(key, on_sample,
                                                                       history=True))

    def close(self) -> None:
        """Undeclare everything and close the session; idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            objs, self._declared = list(reversed(self._declared)), []
        atexit.unregister(self.close)
        for obj in objs:
            try:
                obj.undeclare()
            except Exception:  # noqa: BLE001 - closing must finish
                log.debug("undeclare failed", exc_info=True)
        self.session.close()

    def __enter__(self) -> ZenohBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_bus(opts: ZenohOptions | None = None, *, what: str = "zenoh",
             defaults: RoleDefaults = RoleDefaults()) -> ZenohBus:
    """Open a :class:`ZenohBus` (raises :class:`ZenohError` with one clear line)."""
    return ZenohBus(opts, what=what, defaults=defaults)


def raw_key(sysid: int | str) -> str:
    """Key expression of one vehicle's raw MAVLink frames: ``mavlink/<sysid>/rx``."""
    return f"{RAW_PREFIX}/{sysid}/rx"


def sysid_of_raw_key(key: str) -> int | None:
    """The system id in ``mavlink/<sysid>/rx`` (None if the key has another form)."""
    parts = key.split("/")
    if len(parts) >= 3 and parts[-1] == "rx" and parts[-2].isdigit():
        s = int(parts[-2])
        return s if 0 < s < 256 else None
    return None


def keyexpr_includes(outer: str, inner: str) -> bool:
    """Whether key expression ``outer`` includes every key of ``inner``."""
    return bool(zenoh.KeyExpr(outer).includes(zenoh.KeyExpr(inner)))
