"""Run loop, truth file, in-memory packets, Wan2018 generator (stand-in physics: fast)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent / "sensors"))
from test_suite import make_state  # noqa: E402

from gcs_monitor.core.units import KT2MPS  # noqa: E402
from sim_vehicle.faults.profiles import drift_profile, runaway_profile  # noqa: E402
from sim_vehicle.run import iter_packets, run_scenario  # noqa: E402
from sim_vehicle.scenario import load_scenario, parse_scenario, to_toml, with_overrides  # noqa: E402
from sim_vehicle.truth import load_truth  # noqa: E402
from sim_vehicle.wan2018_gen import generate  # noqa: E402


class FakeSim:
    """Stand-in physics: a steady state whose CAS and AoA vary slowly with time."""

    def __init__(self, sc: object) -> None:
        self.dt_s = 0.01
        self.k = 0

    def _st(self):  # noqa: ANN202
        t = self.k * self.dt_s
        return make_state(t, cas_mps=95.0 + math.sin(0.2 * t), aoa_rad=0.05 + 0.01 * math.sin(t))

    def state(self):  # noqa: ANN201
        return self._st()

    def step(self):  # noqa: ANN201
        self.k += 1
        return self._st()


def demo(duration_s: float = 40.0):  # noqa: ANN201
    return with_overrides(load_scenario("demo_airdata_faults"), duration_s=duration_s)


def test_truth_records_applied_faults(tmp_path: Path) -> None:
    sc = demo()
    res = run_scenario(sc, tmp_path, progress=False, simulation_factory=FakeSim)
    for p in (res.tlog_path, res.truth_path, res.scenario_path):
        assert p is not None and p.is_file()
    assert not list(tmp_path.glob("*.part"))  # temp files renamed
    tr = load_truth(res.truth_path)
    assert len(tr["state.t_s"]) == 4001  # 100 Hz truth, 0..40 s inclusive
    # cas0: drift 0.5 kts/s from 25 s capped at 20 kts; cas2: runaway -5 kts/s limit 40 kts
    t = tr["fault.cas0.t_s"]
    exp = [drift_profile(x - 25.0, 0.5 * KT2MPS, 20 * KT2MPS) if x >= 25 else 0.0 for x in t]
    np.testing.assert_allclose(tr["fault.cas0.value"], exp, atol=1e-9)
    t = tr["fault.cas2.t_s"]
    exp = [runaway_profile(x - 35.0, -5 * KT2MPS, 40 * KT2MPS) if x >= 35 else 0.0 for x in t]
    np.testing.assert_allclose(tr["fault.cas2.value"], exp, atol=1e-9)
    after = tr["fault.aoa1.t_s"] >= 20
    np.testing.assert_allclose(tr["fault.aoa1.value"][after], 3 * math.pi / 180)
    assert [e["channel"] for e in tr["fault_events"]] == ["aoa1", "cas0", "cas2"]
    assert parse_scenario(tr["scenario_toml"], "x") == parse_scenario(to_toml(sc), "x")
    assert res.counts["AIRSPEED"] == 3 * 801 and res.counts["HEARTBEAT"] == 41


def test_in_memory_packets_deterministic_and_equal_to_tlog(tmp_path: Path) -> None:
    sc = demo(3.0)
    a = list(iter_packets(sc, simulation_factory=FakeSim))
    b = list(iter_packets(sc, simulation_factory=FakeSim))
    assert a == b
    assert all(a[i][0] <= a[i + 1][0] for i in range(len(a) - 1))
    res = run_scenario(sc, tmp_path, progress=False, simulation_factory=FakeSim)
    data = res.tlog_path.read_bytes()
    # .tlog = (8-byte timestamp + packet) for exactly these packets, in order
    assert len(data) == sum(8 + len(p) for _, p in a)
    assert data[8 : 8 + len(a[0][1])] == a[0][1]


def test_wan2018_generator_deterministic_and_in_ranges() -> None:
    a = generate(40, seed=3)
    assert a == generate(40, seed=3)
    assert a != generate(40, seed=4)
    n_faulty = 0
    for sc in a:
        assert 60.0 <= sc.duration_s <= 700.0
        assert 1 <= len(sc.faults) <= 6 or not sc.faults  # Table I category IV: all six
        n_faulty += bool(sc.faults)
        assert {f.channel[:3] for f in sc.faults} <= {"aoa", "cas"}
        for f in sc.faults:
            if f.kind == "bias" and f.channel.startswith("cas"):
                assert 10 * KT2MPS - 1e-9 <= abs(f.get("bias")) <= 200 * KT2MPS + 1e-9
            if f.kind == "nrz":
                assert f.params == (("level", 0.1),)  # the output falls to 10 %
        # every generated scenario survives the TOML round trip (validation included)
        assert parse_scenario(to_toml(sc), sc.source) == sc
    assert 0 < n_faulty < 40


def test_feedback_hook_reaches_the_autopilot_not_the_sensors() -> None:
    # The autopilot sees 30 m too much altitude, so the aircraft settles 30 m lower; the truth
    # reports the real altitude. Real physics (transport), 15 s.
    import dataclasses

    from sim_vehicle.run import RunState, iter_run
    from sim_vehicle.state import TrueState

    sc = with_overrides(load_scenario("lu2016_calm"), duration_s=15.0)
    seen: list[float] = []

    def biased(st: TrueState) -> TrueState:
        seen.append(st.t_s)
        return dataclasses.replace(st, alt_m=st.alt_m + 30.0)

    alt_end = {}
    for name, hook in (("truth", None), ("biased", biased)):
        rs = RunState()
        n = sum(1 for _ in iter_run(sc, record_truth=True, run_state=rs, feedback=hook))
        assert n > 0
        alt = np.asarray(rs.truth.arrays()["state.alt_m"])
        alt_end[name] = float(alt[-1])
    assert len(seen) == 1500  # once per step, with the state at the step start
    assert seen[0] == 0.0 and math.isclose(seen[-1], 14.99)
    assert abs(alt_end["truth"] - 1000.0) < 1.0
    assert abs(alt_end["biased"] - 970.0) < 2.0


def test_feedback_needs_a_simulation_that_accepts_it() -> None:
    import pytest

    with pytest.raises(TypeError, match="feedback"):
        next(iter_packets(demo(1.0), simulation_factory=FakeSim, feedback=lambda s: s))
