"""Ownership is a pure function of the live workers: only a dead worker's vehicles move."""

from __future__ import annotations

import pytest

from gcs_monitor.fleet.ownership import Member, assignment, owner, parse_shard
from gcs_monitor.link.zenoh_bus import keyexpr_includes, raw_key


def includes(scope: str, sysid: int) -> bool:
    return keyexpr_includes(scope, raw_key(sysid))


def test_only_the_dead_workers_vehicles_move_and_they_spread() -> None:
    members = [Member(f"w{k}") for k in range(4)]
    before = assignment(range(1, 201), members, includes)
    counts = {m.wid: sum(o == m.wid for o in before.values()) for m in members}
    assert min(counts.values()) >= 30  # 200 vehicles over 4 workers, roughly even
    after = assignment(range(1, 201), [m for m in members if m.wid != "w2"], includes)
    moved = {s for s in before if before[s] != after[s]}
    assert moved == {s for s, o in before.items() if o == "w2"}
    assert len({after[s] for s in moved}) == 3  # spread over every survivor


def test_shards_are_primary_and_others_cover_a_dead_shard() -> None:
    a, b = Member("a", shard=(0, 2)), Member("b", shard=(1, 2))
    assert [owner(s, [a, b], includes) for s in (1, 2, 3, 4)] == ["b", "a", "b", "a"]
    assert [owner(s, [b], includes) for s in (1, 2, 3, 4)] == ["b"] * 4


def test_a_scope_limits_what_a_worker_may_take() -> None:
    only3 = Member("only3", scope="mavlink/3/rx")
    anyv = Member("any")
    assert owner(5, [only3], includes) is None
    assert owner(5, [only3, anyv], includes) == "any"
    assert owner(3, [only3], includes) == "only3"


def test_shard_syntax() -> None:
    assert parse_shard("1/3") == (1, 3)
    for bad in ("3/3", "1", "a/b", "-1/2"):
        with pytest.raises(ValueError, match="--shard"):
            parse_shard(bad)
