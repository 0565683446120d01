"""Which worker monitors which vehicle: a pure function of the live workers.

Rendezvous (highest-random-weight) hashing: every worker scores every (worker, vehicle) pair
with the same hash and a vehicle belongs to the best-scoring live worker whose scope includes
it. When a worker disappears only its vehicles move, each to the worker that scores next best
for it, so the dead worker's vehicles spread over the survivors; when a worker joins it takes
only the vehicles it now scores best on. ``--shard i/n`` gives a worker a primary share (the
system ids with ``sysid % n == i``): a live primary owns the vehicle; without one, the rendezvous
rule picks among all workers whose scope includes it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class Member:
    """A live worker as the others see it."""

    wid: str
    scope: str = "mavlink/*/rx"
    shard: tuple[int, int] | None = None


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/n"`` -> (i, n) with 0 <= i < n; ValueError with the expected form otherwise."""
    i_s, sep, n_s = text.partition("/")
    if not sep or not i_s.strip().isdigit() or not n_s.strip().isdigit():
        raise ValueError(f"--shard {text!r}: expected I/N, e.g. 0/3")
    i, n = int(i_s), int(n_s)
    if not 0 <= i < n:
        raise ValueError(f"--shard {text!r}: expected 0 <= I < N")
    return i, n


def score(wid: str, sysid: int) -> int:
    """The rendezvous weight of worker ``wid`` for vehicle ``sysid`` (same on every host)."""
    digest = hashlib.blake2b(f"{wid}|{sysid}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big")


def owner(sysid: int, members: Iterable[Member],
          includes: Callable[[str, int], bool]) -> str | None:
    """The worker that monitors ``sysid`` (None: no live worker's scope includes it)."""
    cands = [m for m in members if includes(m.scope, sysid)]
    if not cands:
        return None
    primaries = [m for m in cands if m.shard is not None and sysid % m.shard[1] == m.shard[0]]
    pool = primaries or cands
    return max(pool, key=lambda m: (score(m.wid, sysid), m.wid)).wid


def assignment(sysids: Iterable[int], members: Iterable[Member],
               includes: Callable[[str, int], bool]) -> dict[int, str | None]:
    """Owner of every vehicle."""
    ms = list(members)
    return {s: owner(s, ms, includes) for s in sysids}
