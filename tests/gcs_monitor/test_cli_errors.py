"""Every CLI error is one line and a non-zero exit; --rrd with --web gives both; the web viewer
listens on 127.0.0.1 unless told otherwise."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from gcs_monitor.cli import main
from tests.helpers.fleet import free_port, template, write_tlog


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("gcs-monitor: ")
    return lines[0]


def test_port_out_of_range(capsys) -> None:
    rc, _, err = _run(capsys, "live", "udpin:127.0.0.1:99999")
    assert rc == 2
    assert _one_line(err) == ("gcs-monitor: 'udpin:127.0.0.1:99999': port 99999 is outside "
                              "1..65535")


def test_alarms_with_nothing_to_connect_to(capsys) -> None:
    rc, _, err = _run(capsys, "alarms", "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "1")
    assert rc == 1
    assert _one_line(err) == ("gcs-monitor: alarm subscriber: cannot reach tcp/127.0.0.1:1 "
                              "(nothing listening, refused, or TLS rejected)")


def test_zenoh_port_in_use(capsys) -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        rc, out, err = _run(capsys, "live", f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                            "--zenoh", "--zenoh-listen", f"tcp/127.0.0.1:{port}",
                            "--duration", "1")
    assert rc == 1 and "listening on" not in out
    assert _one_line(err) == (f"gcs-monitor: zenoh: cannot listen on tcp/127.0.0.1:{port}: "
                              "address already in use")


@pytest.mark.parametrize(("argv", "message"), [
    (["--require-signing"], "gcs-monitor: --require-signing needs --signing-key FILE"),
    (["--signing-key", "/nonexistent/key"],
     "gcs-monitor: signing key /nonexistent/key: No such file or directory"),
    (["--zenoh", "--zenoh-listen", "tcp/127.0.0.1"],
     "gcs-monitor: zenoh endpoint 'tcp/127.0.0.1': expected tcp/HOST:PORT, port 0..65535"),
    (["--zenoh", "--zenoh-cert", "/nonexistent.pem"],
     "gcs-monitor: --zenoh-cert and --zenoh-key go together"),
])
def test_bad_options(capsys, argv: list[str], message: str) -> None:
    rc, _, err = _run(capsys, "live", f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                      "--duration", "0.5", *argv)
    assert rc == 2
    assert _one_line(err) == message


def test_worker_bad_shard(capsys) -> None:
    rc, _, err = _run(capsys, "worker", "--shard", "3/3", "--zenoh-connect", "tcp/127.0.0.1:1")
    assert rc == 2 and _one_line(err) == ("gcs-monitor: --shard '3/3': expected 0 <= I < N")


def test_rrd_and_web_together_give_both(capsys, tmp_path: Path) -> None:
    tlog = write_tlog(tmp_path / "f.tlog", template(3.0, 1, None))
    rrd = tmp_path / "out.rrd"
    web, grpc = free_port(), free_port()
    rc, out, err = _run(capsys, "replay", str(tlog), "--rrd", str(rrd), "--web", "--quiet",
                        "--web-port", str(web), "--web-grpc-port", str(grpc))
    assert rc == 0, err
    assert rrd.stat().st_size > 10_000
    assert f"Rerun web viewer at http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A" \
           f"{grpc}%2Fproxy" in out


def test_web_viewer_port_in_use(capsys, tmp_path: Path) -> None:
    tlog = write_tlog(tmp_path / "f.tlog", template(1.0, 1, None))
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen()
        port = holder.getsockname()[1]
        rc, _, err = _run(capsys, "replay", str(tlog), "--web", "--web-port", str(port),
                          "--web-grpc-port", str(free_port()))
    assert rc == 2
    assert _one_line(err) == (f"gcs-monitor: web viewer: cannot listen on 127.0.0.1:{port}: "
                              "already in use")


def _listening(port: int) -> set[str]:
    """Local addresses listening on TCP ``port`` (IPv4), from /proc/net/tcp."""
    out = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        host_hex, port_hex = local.split(":")
        if state == "0A" and int(port_hex, 16) == port:
            out.add(socket.inet_ntoa(bytes.fromhex(host_hex)[::-1]))
    return out


def test_the_web_viewer_listens_on_localhost_only() -> None:
    from gcs_monitor.sinks.rerun_sink import WebViewer

    web, grpc = free_port(), free_port()
    viewer = WebViewer(web_port=web, grpc_port=grpc)
    try:
        assert _listening(web) == {"127.0.0.1"} and _listening(grpc) == {"127.0.0.1"}
    finally:
        viewer.close()
