"""The families' blackboard: the air-data family tells the families after it which airspeed to
trust: the fusion of the pitots its vote keeps (Wan2018 eq. 19), or none when it keeps none,
where the median of the raw pitots would be wrong; the yaw-rate observer schedules on it."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "helpers"))
import airdata_synth as synth  # noqa: E402

from gcs_monitor.families.airdata.config import AirDataFamilyConfig  # noqa: E402
from gcs_monitor.families.airdata.family import AirDataFamily  # noqa: E402
from gcs_monitor.families.base import (  # noqa: E402
    AIRSPEED_CAS,
    VIRTUAL,
    Blackboard,
    FamilyContext,
    SharedValue,
    Verdict,
)
from gcs_monitor.families.yaw_rate.estimator import lateral_inputs  # noqa: E402
from gcs_monitor.fdi.records import FamilyStatus  # noqa: E402
from gcs_monitor.pipeline import VehiclePipeline  # noqa: E402
from gcs_monitor.telemetry.frame import Frame, ImuSample  # noqa: E402


def test_a_value_is_read_while_fresh_and_a_withdrawal_is_nan() -> None:
    b = Blackboard()
    assert b.get(AIRSPEED_CAS, 0, 0.5) is None
    b.put(AIRSPEED_CAS, 80.0, 1_000_000, "fused")
    assert b.get(AIRSPEED_CAS, 1_500_000, 0.5) == SharedValue(80.0, 1_000_000, "fused")
    assert b.get(AIRSPEED_CAS, 1_500_001, 0.5) is None  # older than 0.5 s
    b.withdraw(AIRSPEED_CAS, 2_000_000, "no healthy CAS instance")
    v = b.get(AIRSPEED_CAS, 2_000_000, 0.5)
    assert v is not None and math.isnan(v.value) and v.source == "no healthy CAS instance"


def _frame(cas: tuple[float, float, float]) -> Frame:
    return Frame(t_us=0, imu=[ImuSample(0, 0, np.zeros(3), np.array([0.01, 0.0, 0.02]))],
                 euler_rad=np.array([0.1, 0.0, 0.0]), att_age_s=0.0, ssa_rad=0.0,
                 cas_mps=np.array(cas), cas_age_s=np.zeros(3), baro_alt_m=0.0,
                 surf_pos_rad=np.zeros(3), surf_age_s=0.0)


def test_the_yaw_rate_inputs_take_the_shared_airspeed_over_the_median() -> None:
    fr = _frame((60.0, 90.0, 90.0))  # two pitots read 30 m/s high
    assert abs(lateral_inputs(fr, 0.5).eas_mps - 90.0) < 1e-5  # the median; sea level
    inp = lateral_inputs(fr, 0.5, SharedValue(60.0, 0, "fused"))
    assert abs(inp.eas_mps - 60.0) < 1e-5 and inp.y_p is not None
    for shared in (SharedValue(math.nan, 0, "no healthy CAS instance"),
                   SharedValue(75.0, 0, VIRTUAL)):  # the MHE's while no pitot is healthy
        lost = lateral_inputs(fr, 0.5, shared)
        assert lost.y_p is None and lost.reason == ("no trusted airspeed (the air-data family "
                                                    "keeps no CAS instance)")


def _shared_after(faults: tuple[synth.SensorFault, ...], t_from_us: int,
                  survivor: list[tuple[float, bool]] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, set[str]]:
    """The shared airspeed, the true CAS and the median of the pitots on every air-data sample
    from ``t_from_us`` of a 40 s calm flight through the air-data family (and into
    ``survivor``: time and flag of every shared value)."""
    run = synth.generate(synth.SynthConfig(duration_s=40.0, turb_sigma_mps=0.0, faults=faults),
                         np.random.default_rng(3))
    ctx = FamilyContext(vehicle=1, stale_after_s=0.5)
    p = VehiclePipeline(1, [AirDataFamily(AirDataFamilyConfig(), ctx)])
    shared, truth, median, sources = [], [], [], set()
    k = 0
    for fr in run.frames:
        p.step(fr)
        if fr.air_new:
            v = ctx.shared.get(AIRSPEED_CAS, fr.t_us, 0.5)
            if survivor is not None and v is not None:
                survivor.append((fr.t_us * 1e-6, v.survivor))
            if fr.t_us >= t_from_us and v is not None:
                shared.append(v.value)
                sources.add(v.source)
                truth.append(run.cas_true_mps[k])
                median.append(float(np.median(fr.cas_mps)))
            k += 1
    return np.asarray(shared), np.asarray(truth), np.asarray(median), sources


def test_a_biased_pitot_is_left_out_of_the_shared_airspeed() -> None:
    shared, truth, _, sources = _shared_after((synth.SensorFault("cas", 2, 20.0, "bias", 12.0),),
                                              25_000_000)
    err = shared - truth
    assert len(err) == 300 and sources == {"fused"}
    assert abs(err.mean()) < 0.3 and np.abs(err).max() < 1.5  # the two healthy pitots


def test_the_last_healthy_pitot_is_shared_marked_as_the_survivor() -> None:
    """One pitot biased from 10 s, another from 20 s: the shared airspeed is the fusion of
    three, then of two (not marked), then the last pitot alone, marked ``survivor`` (no vote
    checks it: the aircraft tier does not judge the engine on it)."""
    flags: list[tuple[float, bool]] = []
    faults = (synth.SensorFault("cas", 1, 10.0, "bias", 12.0),
              synth.SensorFault("cas", 2, 20.0, "bias", 12.0))
    shared, truth, _, sources = _shared_after(faults, 25_000_000, flags)
    err = shared - truth  # pitot 0 alone: its noise (0.5 m/s), unbiased
    assert sources == {"fused"} and abs(err.mean()) < 0.3 and np.abs(err).max() < 2.5
    assert not any(f for t, f in flags if t < 20.0)
    assert all(f for t, f in flags if t > 25.0)


def test_with_every_pitot_judged_faulty_the_airspeed_is_the_virtual_cas() -> None:
    """Two of three biased at once: before the pair is isolated the fusion drags the MHE, the
    healthy pitot's residual crosses too and the set is lost (Wan2018 Table I). The shared
    airspeed is then the MHE's virtual CAS, marked as such (0.85 m/s off here, in calm air);
    the median of the pitots is 12 m/s off, which is why a reader must not fall back to it."""
    faults = tuple(synth.SensorFault("cas", i, 20.0, "bias", 12.0) for i in (1, 2))
    shared, truth, median, sources = _shared_after(faults, 25_000_000)
    assert len(shared) == 300 and sources == {VIRTUAL}
    assert np.abs(shared - truth).max() < 2.0
    assert np.mean(median - truth) > 10.0


def test_air_data_without_a_healthy_pitot_or_estimator_withdraws_the_airspeed() -> None:
    ctx = FamilyContext(vehicle=1, stale_after_s=0.5)
    fam = AirDataFamily(AirDataFamilyConfig(estimator="none"), ctx)
    v = Verdict(FamilyStatus("airdata", 5, True), fused={"aoa": 0.05, "cas": None})
    fam._share(5, v)
    got = ctx.shared.get(AIRSPEED_CAS, 5, 0.5)
    assert got is not None and math.isnan(got.value)
    fam._share(6, Verdict(FamilyStatus("airdata", 6, True), fused={"cas": 71.5}))
    assert ctx.shared.get(AIRSPEED_CAS, 6, 0.5) == SharedValue(71.5, 6, "fused")
