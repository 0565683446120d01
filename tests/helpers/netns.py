"""Several hosts on one machine: network namespaces that a test creates and always removes.

``NetnsLab(n)`` makes a hub namespace with a Linux bridge and ``n`` host namespaces, each joined
to the bridge by a veth pair, with addresses ``10.<net>.0.<k+1>/24`` that exist only inside these
namespaces (nothing is routed to or from the machine's own networks). Processes run in a host
with ``ip netns exec``. Needs root (CAP_NET_ADMIN, CAP_SYS_ADMIN); :func:`skip_reason` says why
a test cannot create them.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30,
                          check=check)


def skip_reason() -> str | None:
    """None if this process can create network namespaces, else why not."""
    if shutil.which("ip") is None:
        return "the `ip` command (iproute2) is not installed"
    if os.geteuid() != 0:
        return "creating network namespaces needs root (CAP_SYS_ADMIN, CAP_NET_ADMIN)"
    probe = f"gcsprobe{uuid.uuid4().hex[:6]}"
    r = _ip("netns", "add", probe, check=False)
    if r.returncode != 0:
        return f"`ip netns add` failed: {r.stderr.strip()}"
    _ip("netns", "del", probe, check=False)
    return None


class NetnsLab:
    """``n`` hosts on a private bridge (module docstring); a context manager."""

    def __init__(self, n: int, *, net: int = 203) -> None:
        tag = uuid.uuid4().hex[:5]
        self.prefix = f"gf{tag}"
        self.hub = f"{self.prefix}hub"
        self.hosts = [f"{self.prefix}h{k}" for k in range(n)]
        self.addrs = [f"10.{net}.0.{k + 1}" for k in range(n)]
        self._made: list[str] = []
        try:
            self._build()
        except BaseException:
            self.close()
            raise

    def _build(self) -> None:
        _ip("netns", "add", self.hub)
        self._made.append(self.hub)
        self.exec(self.hub, "ip", "link", "add", "br0", "type", "bridge")
        self.exec(self.hub, "ip", "link", "set", "br0", "up")
        for k, (host, addr) in enumerate(zip(self.hosts, self.addrs, strict=True)):
            _ip("netns", "add", host)
            self._made.append(host)
            a, b = f"{self.prefix}a{k}", f"{self.prefix}b{k}"
            _ip("link", "add", a, "type", "veth", "peer", "name", b)
            _ip("link", "set", a, "netns", host)
            _ip("link", "set", b, "netns", self.hub)
            self.exec(self.hub, "ip", "link", "set", b, "master", "br0")
            self.exec(self.hub, "ip", "link", "set", b, "up")
            self.exec(host, "ip", "addr", "add", f"{addr}/24", "dev", a)
            self.exec(host, "ip", "link", "set", a, "up")
            self.exec(host, "ip", "link", "set", "lo", "up")

    def exec(self, ns: str, *cmd: str) -> str:
        r = subprocess.run(["ip", "netns", "exec", ns, *cmd], capture_output=True, text=True,
                           timeout=30, check=True)
        return r.stdout

    def link(self, k: int, up: bool) -> None:
        """Cut (or restore) host ``k``'s cable: its processes live on, silent."""
        self.exec(self.hosts[k], "ip", "link", "set", f"{self.prefix}a{k}",
                  "up" if up else "down")

    def close(self) -> None:
        for ns in reversed(self._made):  # deleting a namespace deletes its interfaces
            _ip("netns", "del", ns, check=False)
        self._made.clear()

    def __enter__(self) -> NetnsLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
