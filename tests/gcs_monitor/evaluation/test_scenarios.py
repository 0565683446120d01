"""Scenario sets of the experiments (gcs_monitor.evaluation.scenarios): deterministic, the mix
the papers ask for."""

from __future__ import annotations

from collections import Counter

import pytest

from gcs_monitor.evaluation import scenarios
from gcs_monitor.evaluation.scoring import channel_of
from sim_vehicle.campaigns import PRESET_SETS, TRIPLEX_KINDS, list_preset_sets
from sim_vehicle.wan2018_gen import Wan2018Ranges, category_plan, generate


def test_preset_sets_are_deterministic_and_cover_the_issue() -> None:
    assert {n for n, _ in list_preset_sets()} == set(PRESET_SETS) >= {"triplex", "wan2018",
                                                                     "fault_free"}
    a = scenarios.preset_set("triplex", 24, seed=5)
    assert a == scenarios.preset_set("triplex", 24, seed=5)
    assert scenarios.preset_set("triplex", 6, seed=5) == a[:6]  # a prefix keeps the mix
    assert a != scenarios.preset_set("triplex", 24, seed=6)
    kinds = {f.kind for sc in a for f in sc.faults}
    assert kinds == set(TRIPLEX_KINDS)
    n_faults = [len(sc.faults) for sc in a]
    assert 0 in n_faults and 1 in n_faults and 2 in n_faults
    for sc in a:
        assert sc.airframe == "transport" and 60.0 <= sc.duration_s <= 120.0
        for f in sc.faults:
            assert channel_of(f.channel) is not None
            assert 15.0 <= f.t_start_s < sc.duration_s
    free = scenarios.preset_set("fault_free", 7)
    assert all(not sc.faults for sc in free)
    assert len({sc.manoeuvre.kind for sc in free}) == 7  # every manoeuvre kind
    with pytest.raises(ValueError, match="unknown preset set"):
        scenarios.preset_set("nope", 1)


def test_fault_free_variant_has_no_faults_and_the_requested_manoeuvre() -> None:
    sc = scenarios.fault_free_variant("s_turn", 7, duration_s=12.0)
    assert sc.faults == () and sc.seed == 7 and sc.duration_s == 12.0
    assert sc.manoeuvre.kind == "s_turn" and sc.wind.kind == "turbulence"


def test_detection_scenario_keeps_only_the_named_imu_group() -> None:
    full = scenarios.preset("lu2016_turbulence", seed=2)
    acc = scenarios.detection_scenario("lu2016_turbulence:acc", 2)
    assert acc.name == "lu2016_turbulence_acc" and acc.seed == 2
    assert acc.faults and all(f.channel.startswith("imu0.acc.") for f in acc.faults)
    assert set(acc.faults) < set(full.faults)
    assert scenarios.detection_scenario("lu2016_turbulence", 2) == full


def test_generator_category_counts_follow_wan2018() -> None:
    assert Counter(category_plan(249, Wan2018Ranges())) == {
        "none": 140, "I": 47, "II": 22, "III": 25, "IV": 15}
    scs = generate(40, 3)
    for sc in scs:
        cat = sc.description.split("category ")[1].split(",")[0]
        ch = {f.channel for f in sc.faults}
        aoa = {c for c in ch if c.startswith("aoa")}
        cas = ch - aoa
        assert (cat == "none") == (not ch)
        if cat == "I":
            assert 0 < len(ch) and len(aoa) < 3 and len(cas) < 3
        if cat in ("II", "IV"):
            assert len(aoa) == 3
        if cat in ("III", "IV"):
            assert len(cas) == 3


def test_nrz_reading_changes_only_the_nrz_faults() -> None:
    """The literal NRZ reading draws no random number: the same runs, the same faults, only
    the NRZ parameter differs (so its campaign compares like with like)."""
    a = scenarios.campaign_scenarios(40, 0, (60.0, 80.0))
    b = scenarios.campaign_scenarios(40, 0, (60.0, 80.0), nrz_gain=scenarios.NRZ_LITERAL_GAIN)
    n_nrz = 0
    for sa, sb in zip(a, b, strict=True):
        assert (sa.duration_s, sa.manoeuvre, sa.wind) == (sb.duration_s, sb.manoeuvre, sb.wind)
        for fa, fb in zip(sa.faults, sb.faults, strict=True):
            assert (fa.channel, fa.kind, fa.t_start_s) == (fb.channel, fb.kind, fb.t_start_s)
            if fa.kind == "nrz":
                n_nrz += 1
                assert fa.params == (("level", 0.1),)  # the output falls to 10 %
                assert fb.params == (("gain", 0.1),)  # f = 0.1 x
            else:
                assert fa.params == fb.params
    assert n_nrz > 0
