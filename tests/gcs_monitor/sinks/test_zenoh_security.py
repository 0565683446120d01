"""Zenoh TLS and access control: a subscriber without the certificate, or outside the access
control list, receives nothing; the operator receives the alarms. Certificates are made here
with the openssl command line (a CA, the monitor's server certificate, two client
certificates: ``operator`` and ``intruder``), on loopback only."""

from __future__ import annotations

import json
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.fdi.records import StepOutput
from gcs_monitor.link.zenoh_bus import ZenohError, ZenohOptions
from gcs_monitor.sinks.zenoh_sink import AlarmSubscriber, ZenohSink
from gcs_monitor.telemetry.frame import Frame
from tests.helpers.fleet import free_port

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl CLI")


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pki")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    _openssl("req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.pem", "-days", "2",
             "-subj", "/CN=gcs-test-ca", cwd=d)
    for name in ("server", "operator", "intruder"):
        _openssl("req", *ec, "-keyout", f"{name}.key", "-out", f"{name}.csr",
                 "-subj", f"/CN={name}", cwd=d)
        (d / f"{name}.ext").write_text(
            "subjectAltName=DNS:localhost,IP:127.0.0.1\nbasicConstraints=CA:FALSE\n"
            "keyUsage=digitalSignature\nextendedKeyUsage=serverAuth,clientAuth\n")
        _openssl("x509", "-req", "-in", f"{name}.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
                 "-CAcreateserial", "-out", f"{name}.pem", "-days", "2",
                 "-extfile", f"{name}.ext", cwd=d)
    acl = {"access_control": {
        "enabled": True, "default_permission": "deny",
        "rules": [{"id": "alarms", "permission": "allow", "flows": ["egress", "ingress"],
                   "messages": ["put", "delete", "declare_subscriber", "query",
                                "declare_queryable", "reply", "liveliness_token",
                                "declare_liveliness_subscriber", "liveliness_query"],
                   "key_exprs": ["gcs/**"]}],
        "subjects": [{"id": "operators", "cert_common_names": ["operator"]}],
        "policies": [{"rules": ["alarms"], "subjects": ["operators"]}]}}
    (d / "acl.json5").write_text(json.dumps(acl, indent=2))
    return d


def _alarm(t_us: int) -> AlarmEvent:
    return AlarmEvent(t_us, ChannelId("aoa", 1), AlarmState.RAISED, AlarmKind.SENSOR_FAULT,
                      FaultType.BIAS, 0.05, 0.04, 0.02, "voting", "", vehicle=1)


def _deliver(server: ZenohOptions, clients: dict[str, ZenohOptions]) -> dict[str, int | str]:
    """Alarms each client received of 5 published by a sink on ``server`` (``"refused"``: it
    could not even open its session: a Zenoh client that reaches no router fails at once)."""
    got: dict[str, list[dict]] = {name: [] for name in clients}  # type: ignore[type-arg]
    refused = set()
    with ZenohSink(1, options=server) as sink:
        subs = []
        for name, opts in clients.items():
            try:
                subs.append(AlarmSubscriber("gcs/*/alarm", options=opts, history=0,
                                            callback=got[name].append))
            except ZenohError as exc:
                assert "cannot reach" in str(exc)
                refused.add(name)
        try:
            time.sleep(1.5)  # links up (or refused)
            for k in range(5):
                sink.publish(Frame(t_us=k, imu=[]), StepOutput(events=[_alarm(k * 1000)]))
            time.sleep(1.5)
        finally:
            for s in subs:
                s.close()
    return {name: "refused" if name in refused else len(v) for name, v in got.items()}


def test_a_subscriber_without_the_certificate_receives_nothing(pki: Path) -> None:
    ep = f"tls/127.0.0.1:{free_port()}"
    server = ZenohOptions(listen=(ep,), tls_ca=pki / "ca.pem", tls_cert=pki / "server.pem",
                          tls_key=pki / "server.key")
    n = _deliver(server, {
        "operator": ZenohOptions(connect=(ep,), tls_ca=pki / "ca.pem",
                                 tls_cert=pki / "operator.pem", tls_key=pki / "operator.key"),
        "no certificate": ZenohOptions(connect=(ep,), tls_ca=pki / "ca.pem"),
        "plain tcp": ZenohOptions(connect=(ep.replace("tls/", "tcp/"),)),
        # a peer retries in the background instead of failing: it still gets nothing
        "no certificate, peer": ZenohOptions(mode="peer", connect=(ep,), tls_ca=pki / "ca.pem"),
    })
    assert n == {"operator": 5, "no certificate": "refused", "plain tcp": "refused",
                 "no certificate, peer": 0}


def test_a_subscriber_outside_the_access_control_list_receives_nothing(pki: Path) -> None:
    ep = f"tls/127.0.0.1:{free_port()}"
    server = ZenohOptions(listen=(ep,), config_file=pki / "acl.json5", tls_ca=pki / "ca.pem",
                          tls_cert=pki / "server.pem", tls_key=pki / "server.key")

    def client(name: str) -> ZenohOptions:
        return ZenohOptions(connect=(ep,), tls_ca=pki / "ca.pem", tls_cert=pki / f"{name}.pem",
                            tls_key=pki / f"{name}.key")

    n = _deliver(server, {"operator": client("operator"), "intruder": client("intruder")})
    assert n == {"operator": 5, "intruder": 0}  # same CA, but not in the ACL


def test_without_the_certificate_gcs_monitor_alarms_fails_clearly(pki: Path) -> None:
    ep = f"tls/127.0.0.1:{free_port()}"
    server = ZenohOptions(listen=(ep,), tls_ca=pki / "ca.pem", tls_cert=pki / "server.pem",
                          tls_key=pki / "server.key")
    with ZenohSink(1, options=server), pytest.raises(ZenohError, match=f"cannot reach {ep}"):
        AlarmSubscriber(options=ZenohOptions(connect=(ep,), tls_ca=pki / "ca.pem",
                                             connect_timeout_s=2.0))
