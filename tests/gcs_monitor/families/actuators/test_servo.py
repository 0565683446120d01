"""The servo level of the actuator family (Lu2017 IOTSEKF + RTS-EKF, families/actuators/servo.py):
each of the five fault cases reconstructed and named on a simulated servo, no alarm without a
fault, the kernel against its reference, covariances PSD, unavailable and not-judging reasons,
windows from the measured period, and the whole MAVLink path once."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pytest

from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.families.actuators.servo import (
    SURFACES,
    ServoTier,
    ServoTierConfig,
    axis_of_case,
    case_of,
)
from gcs_monitor.families.actuators.servo_filters import (
    N_OUT,
    O_ENV,
    O_F_IN,
    O_F_ROD,
    O_F_SURF,
    O_JIT,
    O_LEAD,
    O_SF_D,
    O_SF_ROD,
    O_U,
    O_X1,
    ServoFilterBank,
    ServoFilterConfig,
    ServoFilters,
    ServoSensors,
)
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.fdi.events import AlarmEvent, AlarmKind, AlarmState, FaultType
from gcs_monitor.models.servo import ServoLoopParams, ServoParams
from gcs_monitor.telemetry.frame import Frame
from sim_vehicle.actuators.faults import ActuatorFault
from sim_vehicle.actuators.servo_bank import ActuatorGeometry, ServoBank
from tests.reference.servo_filters import ReferenceServoFilters

GEO = ActuatorGeometry(rod_gain_radpm=1.4, rod_stroke_m=0.35)  # the transport's lever
SIM_DT = 0.01  # the simulator's step: commands change at 100 Hz
SENS = ServoSensors()
T_FAULT = 6.0


def command_3211(t: float) -> float:
    """A 2 deg 3-2-1-1 on the elevator from 1 s, repeated every 7 s (Lu2017 sec. IV.C)."""
    tau = (t - 1.0) % 7.0 if t >= 1.0 else -1.0
    for start, end, sign in ((0, 3, 1), (3, 5, -1), (5, 6, 1), (6, 7, -1)):
        if start <= tau < end:
            return sign * 2.0 * DEG2RAD
    return 0.0


def simulate(faults: tuple[ActuatorFault, ...] = (), duration_s: float = 14.0,
             surf_hz: float = 50.0, seed: int = 0, sim_dt: float = SIM_DT,
             command: Callable[[float], float] = command_3211) -> list[Frame]:
    """SURF frames of a servo bank (elevator doing the 3-2-1-1, the others at rest) with the
    simulator's sensor noise; one Frame per SURF sample; ``command`` (rad of time) is
    evaluated every ``sim_dt`` and held over the step."""
    bank = ServoBank(GEO, (0.0, 0.0, 0.0), faults=faults)
    rng = np.random.default_rng(seed)
    every = round(1.0 / (surf_hz * sim_dt))
    frames: list[Frame] = []
    t = 0.0
    for k in range(round(duration_s / sim_dt)):
        cmd = (0.0, command(t), 0.0)
        bank.step(t, sim_dt, cmd)
        t = (k + 1) * sim_dt
        if (k + 1) % every:
            continue
        pos = np.array([bank.deflection_rad(i) for i in range(3)])
        rod = np.array([bank.rod_sensor_m(i) for i in range(3)])
        frames.append(Frame(
            t_us=round(t * 1e6), imu=[], surf_cmd_rad=np.array(bank.cmd_rad),
            surf_pos_rad=pos + SENS.surf_sigma_rad * rng.standard_normal(3),
            rod_pos_m=rod + SENS.rod_sigma_m * rng.standard_normal(3), surf_age_s=0.0))
    return frames


def run_tier(frames: list[Frame], cfg: ServoTierConfig | None = None
             ) -> tuple[ServoTier, list[AlarmEvent], list[bool]]:
    tier = ServoTier(cfg or ServoTierConfig(), FamilyContext(vehicle=1, stale_after_s=0.5))
    events: list[AlarmEvent] = []
    judged = []
    for fr in frames:
        p = tier.predict(fr)
        v = tier.judge(fr, p)
        tier.update(fr, v)
        events += v.events
        judged.append(v.status.judged)
    return tier, events, judged


def test_fault_free_servo_raises_nothing() -> None:
    _, events, judged = run_tier(simulate(duration_s=20.0))
    assert events == []
    assert all(judged[round(2.5 * 50):])  # judged from the end of the 2 s warm-up on


@pytest.mark.parametrize("sim_dt", [0.005, 0.01, 0.02])
def test_command_lead_is_the_autopilot_period_measured_from_the_rod(sim_dt: float) -> None:
    """The command a SURF sample reports took effect one autopilot step before it (the bank's
    commands change every ``sim_dt``): whatever the configured lead (10 ms), the filters
    identify ``sim_dt`` from the rod, and a servo commanded at 200, 100 or 50 Hz raises no
    alarm (at 200 Hz the configured 10 ms alone raises a false input fault in the
    simulator's demo flight: docs/results.md, rate sweep). The command is a smooth 3 deg,
    0.5 Hz sine sampled by the loop (a step on the SURF grid took effect a whole interval
    before the sample, whatever the loop)."""
    frames = simulate(duration_s=20.0, sim_dt=sim_dt,
                      command=lambda t: 3.0 * DEG2RAD * math.sin(math.pi * t))
    f = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    f.start(float(frames[0].surf_cmd_rad[1]), float(frames[0].rod_pos_m[1]))
    out = np.zeros(N_OUT)
    leads = []
    for p, q in zip(frames, frames[1:], strict=False):
        assert f.step((q.t_us - p.t_us) * 1e-6, float(q.surf_cmd_rad[1]),
                      float(q.rod_pos_m[1]), float(q.surf_pos_rad[1]), out)
        leads.append(out[O_LEAD])
    assert leads[0] == pytest.approx(0.01)  # the configured lead first
    assert leads[-1] == pytest.approx(sim_dt)
    assert set(np.round(leads[len(leads) // 2:], 6)) == {round(sim_dt, 6)}  # and it stays
    _, events, _ = run_tier(frames)
    assert events == []


FAULTS = {
    "liquid_ofc": ActuatorFault(1, "liquid_ofc", T_FAULT, None, 0.05, 1.0),
    "solid_ofc": ActuatorFault(1, "solid_ofc", T_FAULT, None, 0.05, 1.0),
    "liquid_jam": ActuatorFault(1, "liquid_jam", T_FAULT, None, 0.02),
    "solid_jam": ActuatorFault(1, "solid_jam", T_FAULT),
    "runaway": ActuatorFault(1, "runaway", T_FAULT, None, 1.0),
}


@pytest.mark.parametrize("case", sorted(FAULTS))
def test_each_lu2017_case_is_reconstructed_and_named(case: str) -> None:
    """One Lu2017 case on the elevator at 6 s: an actuator_fault raised on the elevator's right
    channel within 0.5 s, the case named within 4.5 s, nothing on the other surfaces, and the
    numbers of the case in its magnitude (OFC amplitude and frequency, rod-sensor bias, stuck
    rod position, runaway rate)."""
    tier, events, _ = run_tier(simulate((FAULTS[case],)))
    assert events, "nothing raised"
    assert all(e.kind is AlarmKind.ACTUATOR_FAULT and e.channel.kind == "surface"
               for e in events)
    assert {e.channel.instance for e in events} == {1}  # the elevator only
    first = next(e for e in events if e.state is AlarmState.RAISED)
    assert T_FAULT <= first.t_us * 1e-6 < T_FAULT + 0.5
    named = [e for e in events if case_of(e) == case and e.state is not AlarmState.CLEARED]
    assert named, [e.message for e in events]
    right = named[0]
    assert right.channel.axis == axis_of_case(case)
    assert right.t_us * 1e-6 < T_FAULT + 4.5
    last = named[-1]
    c = tier.classes[1]
    assert c is not None and c.case == case
    if case == "liquid_ofc":
        assert last.fault_type is FaultType.OSCILLATION
        assert c.frequency_hz == pytest.approx(1.0, rel=0.1)
        assert c.amplitude == pytest.approx(0.05, rel=0.2)  # the f^i sinusoid
    elif case == "solid_ofc":
        assert c.frequency_hz == pytest.approx(1.0, rel=0.1)
        assert c.amplitude == pytest.approx(0.05, rel=0.2)  # the valve command's sinusoid
    elif case == "liquid_jam":
        assert last.fault_type is FaultType.BIAS
        assert last.magnitude == pytest.approx(0.02, abs=2e-3)  # m of rod sensor bias
    elif case == "solid_jam":
        assert last.fault_type is FaultType.STUCK
        # the rod where the simulator froze it (the 3-2-1-1 is at -2 deg at 6 s)
        assert last.magnitude == pytest.approx(-2.0 * DEG2RAD / GEO.rod_gain_radpm, abs=1e-3)
    else:
        assert last.fault_type is FaultType.RUNAWAY
        assert last.magnitude == pytest.approx(1.0, rel=0.2)  # m/s, full valve
    assert SURFACES[1] in last.message


def _run_filters(faults: tuple[ActuatorFault, ...]) -> tuple[list[np.ndarray],
                                                             list[ServoFilters]]:
    frames = simulate(faults, duration_s=10.0)
    f = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    f.start(float(frames[0].surf_cmd_rad[1]), float(frames[0].rod_pos_m[1]))
    rows = []
    for a, b in zip(frames, frames[1:], strict=False):
        out = np.zeros(N_OUT)
        assert f.step((b.t_us - a.t_us) * 1e-6, float(b.surf_cmd_rad[1]), float(b.rod_pos_m[1]),
                      float(b.surf_pos_rad[1]), out)
        rows.append(out)
    return rows, [f]


@pytest.mark.parametrize("case", ["liquid_ofc", "runaway"])
def test_kernel_equals_reference(case: str) -> None:
    """The compiled surface step against the same chain of model and filter kernels from
    Python (tests/reference/servo_filters.py): round-off only over 10 s, a fault included
    (1e-12 relative to each output's scale)."""
    frames = simulate((FAULTS[case],), duration_s=10.0)
    a = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    b = ReferenceServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    c0, r0 = float(frames[0].surf_cmd_rad[1]), float(frames[0].rod_pos_m[1])
    a.start(c0, r0)
    b.start(c0, r0)
    out = np.zeros(N_OUT)
    for p, q in zip(frames, frames[1:], strict=False):
        args = ((q.t_us - p.t_us) * 1e-6, float(q.surf_cmd_rad[1]), float(q.rod_pos_m[1]),
                float(q.surf_pos_rad[1]))
        assert a.step(*args, out)
        r = b.step(*args)
        assert r is not None
        for i, key, scale in ((O_F_IN, "f_in", 1.0), (O_U, "u", 1.0), (O_F_ROD, "f_rod", 0.1),
                              (O_F_SURF, "f_surf", 0.1), (O_SF_ROD, "sf_rod", 1e-3),
                              (O_SF_D, "sf_d", 1e-3), (O_JIT, "jit", 1e-3),
                              (O_LEAD, "lead", 1e-3), (O_ENV, "env", 1e-3)):
            assert abs(out[i] - r[key]) <= 1e-12 * scale + 1e-12 * abs(r[key]), key
        np.testing.assert_allclose(out[O_X1:O_X1 + 3], r["x"], rtol=1e-9, atol=1e-13)


def _spreads(cmds: list[float], dt: float = 0.05) -> tuple[list[float], list[float]]:
    """O_JIT of the kernel and ``jit`` of the reference on a command sequence (rod at rest)."""
    a = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    b = ReferenceServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    a.start(cmds[0], 0.0)
    b.start(cmds[0], 0.0)
    out = np.zeros(N_OUT)
    ka, kb = [], []
    for c in cmds[1:]:
        assert a.step(dt, c, c / GEO.rod_gain_radpm, c, out)
        r = b.step(dt, c, c / GEO.rod_gain_radpm, c)
        assert r is not None
        ka.append(float(out[O_JIT]))
        kb.append(r["jit"])
    return ka, kb


def test_a_command_clipped_at_its_limit_keeps_its_unseen_spread() -> None:
    """A jittery command (0.1 rad of white jitter about 0.2 rad, clipped) that runs into its limit,
    0.4 rad, and sits there for 1 s: the samples at the limit are a clipped demand, their zero
    second differences say nothing of the unseen ones, and the spread holds its value from
    before (it used to fall to 0 within the window: run 53 of the Wan2018 campaign, a false
    rudder output alarm when the rod left the stop between two SURF samples). A quiet plateau at
    the extreme (a 3-2-1-1) keeps its zero spread; kernel and reference agree on both."""
    rng = np.random.default_rng(4)
    jitter = [min(0.2 + 0.1 * float(v), 0.4) for v in rng.normal(size=30)]  # the autopilot clips
    ka, kb = _spreads(jitter + [0.4] * 20)
    np.testing.assert_allclose(ka, kb, rtol=1e-12, atol=1e-15)
    at_entry = ka[len(jitter)]  # the last sample with a second difference off the limit
    assert at_entry > 0.0
    assert min(ka[len(jitter) + 1:]) >= at_entry  # held at the limit
    quiet = [0.0] * 20 + [0.4] * 20 + [-0.4] * 20 + [0.4] * 20
    ka, kb = _spreads(quiet)
    np.testing.assert_allclose(ka, kb, rtol=1e-12, atol=1e-15)
    assert max(ka[25:40]) == 0.0 and max(ka[65:80]) == 0.0  # the plateaus, after each step


def test_a_command_that_bounces_off_its_limit_keeps_its_unseen_spread() -> None:
    """The same jittery command held at its 0.4 rad limit for 1 s, then back inside it for a
    sample or two at a time (a rudder banging against its limit in turbulence: 0.37, 0.4,
    0.375, 0.39, 0.4, ...): those samples have the same unseen excursions as the held ones, and
    the window's zeros left their spread a tenth of what it was (the Wan2018 campaign's runs
    42 and 111: false rudder input alarms there). The spread holds its value from before the
    limit over every interval that touches the limit and until the window (0.4 s: 8 samples at
    20 Hz) has none left; then it is the command's own again. Kernel and reference agree."""
    rng = np.random.default_rng(4)
    jitter = [min(0.2 + 0.1 * float(v), 0.4) for v in rng.normal(size=30)]
    bounce = [0.37, 0.4, 0.375, 0.39, 0.4, 0.4, 0.38, 0.4]
    inside = [0.3] * 20  # a quiet command well inside the limit
    ka, kb = _spreads(jitter + [0.4] * 20 + bounce + inside)
    np.testing.assert_allclose(ka, kb, rtol=1e-12, atol=1e-15)
    at_entry = ka[len(jitter)]
    assert at_entry > 0.0
    n_held = len(jitter) + 20
    assert min(ka[len(jitter) + 1:n_held + len(bounce) + 7]) >= at_entry  # bounce and window
    assert ka[-1] < 0.1 * at_entry  # the quiet command inside the limit: its own spread


def test_bank_equals_one_filter_per_surface() -> None:
    """The bank's one kernel call for all surfaces (``surfaces_step``, the tier's path) gives
    bit for bit the states and output rows of one :class:`ServoFilters` per surface, a fault
    on the elevator included."""
    frames = simulate((FAULTS["runaway"],), duration_s=10.0)
    args = (ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    bank = ServoFilterBank(3, *args)
    single = [ServoFilters(*args) for _ in range(3)]
    f0 = frames[0]
    for k in range(3):
        for f in (bank.filters[k], single[k]):
            f.start(float(f0.surf_cmd_rad[k]), float(f0.rod_pos_m[k]))
    rows = np.zeros((3, N_OUT))
    out = np.zeros(N_OUT)
    for p, q in zip(frames, frames[1:], strict=False):
        dt = (q.t_us - p.t_us) * 1e-6
        assert bank.step(dt, q.surf_cmd_rad, q.rod_pos_m, q.surf_pos_rad, rows) == -1
        for k, f in enumerate(single):
            assert f.step(dt, float(q.surf_cmd_rad[k]), float(q.rod_pos_m[k]),
                          float(q.surf_pos_rad[k]), out)
            assert rows[k].tobytes() == out.tobytes()
            assert bank.filters[k].st.tobytes() == f.st.tobytes()


def test_covariances_stay_symmetric_psd_through_faults() -> None:
    """Both filters' covariances stay symmetric PSD through a saturating fault (runaway to the
    stop) and an oscillation."""
    from gcs_monitor.filters.covariance import is_psd as psd

    for case in ("runaway", "solid_ofc"):
        frames = simulate((FAULTS[case],), duration_s=10.0)
        f = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
        f.start(float(frames[0].surf_cmd_rad[1]), float(frames[0].rod_pos_m[1]))
        out = np.zeros(N_OUT)
        for p, q in zip(frames, frames[1:], strict=False):
            assert f.step((q.t_us - p.t_us) * 1e-6, float(q.surf_cmd_rad[1]),
                          float(q.rod_pos_m[1]), float(q.surf_pos_rad[1]), out)
            for P in (f.Px, f.P_nom):
                assert psd(P, tol=1e-9 * np.max(np.abs(P)))
                np.testing.assert_allclose(P, P.T, rtol=0, atol=1e-15 * np.max(np.abs(P)))


def test_state_estimates_follow_the_true_servo() -> None:
    """Fault-free: the IOTSEKF's rod position within 0.1 mm RMS of the truth (the sensor's 0.1 mm
    noise filtered), the RTS-EKF's nominal servo within 0.5 mm (open loop: the command's unknown
    timing at the 3-2-1-1 steps)."""
    bank = ServoBank(GEO, (0.0, 0.0, 0.0))
    frames = simulate(duration_s=10.0)
    # the truth: the same bank without noise, sampled at the frames
    truth = {}
    t = 0.0
    for k in range(round(10.0 / SIM_DT)):
        bank.step(t, SIM_DT, (0.0, command_3211(t), 0.0))
        t = (k + 1) * SIM_DT
        truth[round(t * 1e6)] = bank.rod_m(1)
    f = ServoFilters(ServoParams(), ServoLoopParams(), SENS, ServoFilterConfig())
    f.start(float(frames[0].surf_cmd_rad[1]), float(frames[0].rod_pos_m[1]))
    e_i, e_n = [], []
    out = np.zeros(N_OUT)
    for p, q in zip(frames, frames[1:], strict=False):
        f.step((q.t_us - p.t_us) * 1e-6, float(q.surf_cmd_rad[1]), float(q.rod_pos_m[1]),
               float(q.surf_pos_rad[1]), out)
        if q.t_us > 2_000_000:
            e_i.append(f.x_hat[0] - truth[q.t_us])
            e_n.append(f.x_nom[0] - truth[q.t_us])
    assert math.sqrt(np.mean(np.square(e_i))) < 1e-4
    assert math.sqrt(np.mean(np.square(e_n))) < 5e-4


def test_unavailable_without_surf_and_reasons_when_not_judging() -> None:
    tier = ServoTier(ServoTierConfig(), FamilyContext(vehicle=1, stale_after_s=0.5))
    fr = Frame(t_us=1_000_000, imu=[])
    v = tier.judge(fr, tier.predict(fr))
    assert not v.status.judged and not v.status.inputs and not v.status.sample
    assert "SURF" in v.status.reason
    frames = simulate(duration_s=3.0)
    reasons = []
    for f in frames:
        v = tier.judge(f, tier.predict(f))
        reasons.append(v.status.reason)
    assert v.status.inputs and v.status.judged  # after the warm-up
    assert reasons[1] == "servo filters warm-up"
    stale = Frame(t_us=frames[-1].t_us + 1_000_000, imu=[])
    v = tier.judge(stale, tier.predict(stale))
    assert v.status.inputs and not v.status.judged and "stale" in v.status.reason
    # a gap longer than max_gap_s restarts the filters: warm-up again
    late = dataclasses.replace(frames[-1], t_us=frames[-1].t_us + 1_500_000)
    v = tier.judge(late, tier.predict(late))
    assert not v.status.judged and "restarted" in v.status.reason


def test_windows_come_from_the_measured_surf_period() -> None:
    """The 0.2 s windows are 10 samples at 50 Hz SURF and 20 at 100 Hz; at 25 Hz they hold the
    fdi layer's least 10 samples (0.4 s)."""
    for hz, n in ((50.0, 10), (100.0, 20), (25.0, 10)):
        tier, _, _ = run_tier(simulate(duration_s=3.0, surf_hz=hz))
        assert tier.period_s == pytest.approx(1.0 / hz)
        assert tier._fdi is not None
        assert tier._fdi[0].p["input"].rms.rms_window_n == n


def test_whole_mavlink_path_names_a_liquid_jam() -> None:
    """Simulator -> MAVLink bytes -> Monitor with the servo tier as its family (the actuator
    family's wrapper is built elsewhere): Lu2017 scenario 3 (liquid jam on the elevator at
    12 s) cut at 14 s -- the elevator's output channel raises a liquid jam within 0.3 s with
    the rod-sensor bias (20 mm) within 2 mm; nothing else is raised."""
    from gcs_monitor.monitor import Monitor
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("lu2017_s3"), duration_s=14.0)
    mon = Monitor(families_for=lambda ctx: [ServoTier(ServoTierConfig(), ctx)])
    buf: list[bytes] = []
    for _, pkt in iter_packets(sc):
        buf.append(pkt)
        if len(buf) >= 64:
            mon.feed(b"".join(buf))
            buf = []
    mon.feed(b"".join(buf))
    mon.finish()
    raised = [e for e in mon.events if e.state is AlarmState.RAISED]
    assert len(raised) == 1
    e = raised[0]
    assert (e.channel.instance, e.channel.axis) == (1, "output")
    assert 12.0 <= e.t_us * 1e-6 < 12.3
    last = [x for x in mon.events if x.channel == e.channel][-1]
    assert case_of(last) == "liquid_jam"
    assert last.magnitude == pytest.approx(0.02, abs=2e-3)


def test_frames_slower_than_surf_lose_no_sample() -> None:
    """Frames at 25 Hz (HIGHRES_IMU and ATTITUDE kept at every fourth 100 Hz instant), SURF at
    50 Hz: every SURF sample reaches the tier (Frame.surf_new) and is stepped on -- the tier
    measures the 50 Hz SURF period, not the Frames' 25 Hz -- and scenario 3's liquid jam on the
    elevator is named as at 100 Hz, with no other sensor or actuator alarm."""
    from gcs_monitor.monitor import Monitor
    from sim_vehicle.run import iter_packets
    from sim_vehicle.scenario import load_scenario

    sc = dataclasses.replace(load_scenario("lu2017_s3"), duration_s=14.0)
    tiers: list[ServoTier] = []

    def families(ctx: FamilyContext) -> list[ServoTier]:
        tiers.append(ServoTier(ServoTierConfig(), ctx))
        return tiers[-1:]

    mon = Monitor(families_for=families)
    n_surf = 0
    for t_us, pkt in iter_packets(sc):
        msg_id = int.from_bytes(pkt[7:10], "little")  # MAVLink 2 header
        if msg_id in (105, 30) and round(t_us / 10_000) % 4:  # HIGHRES_IMU, ATTITUDE
            continue
        n_surf += msg_id == 350 and b"SURF" in pkt  # DEBUG_FLOAT_ARRAY
        mon.feed(pkt)
    mon.finish()
    (tier,) = tiers
    assert n_surf > 600
    assert mon.vehicles[1].pipeline is not None
    assert mon.vehicles[1].pipeline.frames == pytest.approx(14.0 * 25, abs=3)
    assert tier.period_s == pytest.approx(0.02)
    # the dropped packets are sequence gaps: a link alarm is right, and the only other one
    raised = [e for e in mon.events if e.state is AlarmState.RAISED
              and e.kind is not AlarmKind.LINK]
    assert [(e.channel.instance, e.channel.axis) for e in raised] == [(1, "output")]
    last = [x for x in mon.events if x.channel == raised[0].channel][-1]
    assert case_of(last) == "liquid_jam"


def test_a_servo_model_of_another_airframe_is_not_judged_and_says_why() -> None:
    """The telemetry's lever (surface over rod position, 1.4 rad/m here) against a configured
    one 3.6x larger (the UAV's): the tier does not judge after its warm-up and says what to set,
    instead of reading the mismatch as output faults; the right lever judges as before."""
    frames = simulate(duration_s=8.0)
    wrong = ServoTierConfig(sensors=dataclasses.replace(SENS, rod_gain_radpm=5.0))
    tier = ServoTier(wrong, FamilyContext(vehicle=1, stale_after_s=0.5))
    verdicts = [tier.judge(fr, tier.predict(fr)) for fr in frames]
    assert not [v for v in verdicts if v.events or v.status.judged]
    reason = verdicts[-1].status.reason
    assert "does not fit" in reason and "elevator" in reason and "5.00 rad/m configured" in reason
    assert "rod_gain_radpm" in reason
    _, events, judged = run_tier(frames)
    assert events == [] and all(judged[round(2.5 * 50):])
