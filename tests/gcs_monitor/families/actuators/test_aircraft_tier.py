"""Aircraft tier of the actuator family on hand-made Frames of a known linear aircraft: the
reference models converge to the true coefficients, a stuck aileron is raised on the aileron
with its class and position, nothing is raised in healthy flight, missing inputs are reported
and a logger's repeated samples are not taken as measurements."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_monitor.core.types import ChannelId
from gcs_monitor.families.actuators.aircraft import AircraftTier
from gcs_monitor.families.actuators.config import ActuatorFamilyConfig
from gcs_monitor.families.actuators.family import ActuatorFamily
from gcs_monitor.families.base import AIRSPEED_CAS, FUSED, FamilyContext
from gcs_monitor.fdi.events import AlarmKind, AlarmState, FaultType
from gcs_monitor.telemetry.frame import Frame, HudSample, ImuSample, ServoOutputs

DT = 0.02  # 50 Hz servo outputs and body rates
MAX_DEFL = 0.4  # rad at full pulse (ServoMapConfig default)
# p_k = A p_{k-1} + B u_{k-1} (the aileron axis; the other axes alike with their own surface)
A, B = 0.8, 2.0
CTX = FamilyContext(vehicle=1, stale_after_s=0.5)


def _frames(duration_s: float, *, stuck_at_s: float | None = None, stuck_rad: float = 0.05,
            seed: int = 0, repeat: int = 1, stop_from_s: float | None = None,
            rudder_from_s: float = 0.0):
    """Frames of a linear aircraft driven by random surface commands (every ``repeat``-th
    response is a new measurement, the others repeat it, as a logger's forward fill); from
    ``stop_from_s`` the aileron is commanded to its end stop, and goes to its travel's end
    (70 % of the command's full deflection: a stop that is not where the PWM range says)."""
    rng = np.random.default_rng(seed)
    w = np.zeros(3)
    u_prev = np.zeros(3)
    held = None
    for k in range(round(duration_s / DT)):
        t = k * DT
        t_us = round(t * 1e6)
        u = 0.1 * np.sin(2 * math.pi * np.array([0.3, 0.23, 0.17]) * t + np.arange(3)) \
            + 0.03 * rng.standard_normal(3)
        if t < rudder_from_s:
            u[2] = 0.0  # the rudder not used yet (a coordinated autopilot in straight flight)
        if stop_from_s is not None and t >= stop_from_s:
            u[0] = MAX_DEFL
        acting = u_prev.copy()
        if stop_from_s is not None and t >= stop_from_s + DT:
            acting[0] = 0.7 * MAX_DEFL  # the surface's travel ends short of the command's
        if stuck_at_s is not None and t >= stuck_at_s:
            acting[0] = stuck_rad
        w = A * w + B * acting + 0.002 * rng.standard_normal(3)
        u_prev = u
        if held is None or k % repeat == 0:
            held = (w.copy(), np.array([0.0, 0.0, -9.81]) + 0.01 * rng.standard_normal(3))
        pwm = tuple(float(round(1500 + 500 * x / MAX_DEFL)) for x in u) + (1500.0,) + (
            math.nan,) * 12
        yield Frame(t_us, [ImuSample(t_us, 0, held[1], held[0])], euler_rad=np.zeros(3),
                    att_age_s=0.0, att_rate_frd_radps=held[0],
                    servo=ServoOutputs(t_us, pwm, tuple((x - 1500) / 500 for x in pwm)),
                    servo_age_s=0.0, hud=HudSample(t_us, 25.0, 25.0, 0.0, 0.5), hud_age_s=0.0,
                    gps_vel_ned_mps=np.array([20.0, 0.0, 0.0]))  # a 5 m/s headwind


def _run(tier, frames):
    events, statuses = [], []
    for f in frames:
        v = tier.judge(f, tier.predict(f))
        tier.update(f, v)
        events += v.events
        statuses.append(v.status)
    return events, statuses


def _tier() -> AircraftTier:
    return AircraftTier(ActuatorFamilyConfig().aircraft, CTX)


def test_a_command_at_its_end_stop_does_not_move_the_effectiveness_check():
    """From 30 s the autopilot holds the aileron at its end stop: a command that does not vary
    says nothing of the effectiveness (the tracking slope has no excitation), so the aileron's
    effectiveness check holds its J while the command stays there, whatever the response (the
    triplex campaign's run 90: an aileron held at the stop for 10 s in an upset was called
    stuck). The residual check goes on: a response off the model still counts."""
    tier = _tier()
    frames = list(_frames(40.0, stop_from_s=30.0))
    at_stop = round(30.1 / DT)  # the first sample whose acting command is at the stop
    _run(tier, frames[:at_stop])
    ax = tier.axes[0]
    assert ax.eff is not None
    j_before = ax.eff.J
    _run(tier, frames[at_stop:])
    assert ax.eff.J == j_before  # without the hold: J 41 within 2 s, "23 % lost" raised
    assert ax.res is not None and ax.judged  # the residual check goes on judging the axis


def test_reference_model_converges_to_the_true_coefficients():
    tier = _tier()
    events, statuses = _run(tier, _frames(40.0))
    ax = tier.axes[0]
    assert ax.mode == "servo" and ax.ref is not None
    # phi = [u s, p_prev, r_prev, 1] with s = 1 (constant airspeed): theta = [B, A, 0, 0];
    # tolerance: 2000 samples of 0.002 rad/s noise against ~0.1 rad of command
    np.testing.assert_allclose(ax.ref.theta, [B, A, 0.0, 0.0], atol=0.02)
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]  # healthy flight
    assert statuses[-1].judged and statuses[-1].inputs


def test_stuck_aileron_is_isolated_with_its_position():
    tier = _tier()
    events, _ = _run(tier, _frames(45.0, stuck_at_s=35.0, stuck_rad=0.05))
    raised = [e for e in events if e.state is AlarmState.RAISED]
    assert raised, "no alarm"
    first = raised[0]
    assert first.kind is AlarmKind.ACTUATOR_FAULT
    assert first.channel == ChannelId("actuator", 0, "aileron")
    assert {e.channel for e in raised} == {first.channel}  # no other surface
    assert 35.0 < first.t_us * 1e-6 < 36.0  # within a second of the jam
    last = [e for e in events if e.channel == first.channel][-1]
    assert last.fault_type is FaultType.STUCK
    assert abs(last.magnitude - 0.05) < 0.01  # rad: the position that explains the response
    assert "stuck at" in last.message


def test_repeated_samples_are_not_measurements_and_slow_streams_are_not_judged():
    tier = _tier()
    _, statuses = _run(tier, _frames(30.0, repeat=5))  # new responses at 10 Hz of 50 Hz frames
    period = tier.axes[0].period.seconds()
    assert abs(period - 5 * DT) < 1e-9
    slow = AircraftTier(dataclasses.replace(ActuatorFamilyConfig().aircraft, min_rate_hz=20.0),
                        CTX)
    _, statuses = _run(slow, _frames(30.0, repeat=5))
    assert not any(s.judged for s in statuses)
    last = [s for s in statuses if s.sample][-1]  # the last frame with a new control sample
    assert "10.0 Hz, below the 20 Hz" in last.reason


def test_without_commands_the_family_says_it_cannot_judge():
    fam = ActuatorFamily(ActuatorFamilyConfig(), CTX)
    for f in _frames(5.0):
        bare = dataclasses.replace(f, servo=None, hud=None, euler_rad=None)
        v = fam.judge(bare, fam.predict(bare))
        assert fam.update(bare, v) == []
    assert not v.status.judged and not v.status.inputs
    assert "no command" in v.status.reason


@pytest.mark.parametrize("source", ["servo", "setpoint"])
def test_command_source_is_respected(source):
    cfg = dataclasses.replace(ActuatorFamilyConfig().aircraft, command_source=source)
    tier = AircraftTier(cfg, CTX)
    _run(tier, _frames(3.0))
    # the frames carry servo outputs and no setpoints: only "servo" finds a command
    assert (tier.axes[0].mode == "servo") is (source == "servo")


def test_commands_and_responses_on_different_frames_still_step():
    """ALFA-like: a new command every 2nd Frame, a new response every 5th. An axis steps at each
    new response that follows a command newer than its last step (every 5th Frame here)."""
    frames = list(_frames(20.0, repeat=5))
    held = frames[0].servo
    out = []
    for k, f in enumerate(frames):
        if k % 2 == 0:
            held = f.servo
        out.append(dataclasses.replace(f, servo=held))
    tier = _tier()
    _run(tier, out)
    assert abs(tier.axes[0].period.seconds() - 5 * DT) < 1e-9
    assert tier.axes[0].steps == pytest.approx(len(frames) / 5, abs=2)



def test_the_airspeed_reference_is_never_zero():
    """A real log (Zipline) starts at 0 m/s airspeed: the dynamic-pressure scaling
    (V / V_ref)^2 takes its reference from the first airspeed at which the surfaces can be
    judged, not from 0 (the replay divided by zero)."""
    from types import SimpleNamespace

    tier = _tier()
    assert tier._scale(SimpleNamespace(airspeed_mps=0.0)) == 1.0  # no reference yet
    assert tier._scale(SimpleNamespace(airspeed_mps=3.0)) == 1.0  # below min_airspeed_mps
    assert tier._scale(SimpleNamespace(airspeed_mps=20.0)) == 1.0  # the reference
    assert tier._scale(SimpleNamespace(airspeed_mps=40.0)) == pytest.approx(4.0)


def _engine_frames(duration_s: float, *, tau_s: float, out_at_s: float | None = None,
                   seed: int = 0, throttle=None, loss: float = 1.0):
    """Frames of an engine whose thrust follows the throttle through a first-order lag of
    ``tau_s`` (f_x = 2 thrust - 1 m/s^2, thrust = lag(throttle)), the throttle stepping between
    0.3 and 0.8 every 4 s; the engine loses the share ``loss`` of its thrust from
    ``out_at_s`` (all of it by default)."""
    rng = np.random.default_rng(seed)
    thrust = thr = 0.55
    a = math.exp(-DT / tau_s)
    for k in range(round(duration_s / DT)):
        t = k * DT
        t_us = round(t * 1e6)
        acting = (1.0 - loss) * thr if out_at_s is not None and t >= out_at_s else thr
        thrust = a * thrust + (1.0 - a) * acting
        thr = throttle(t) if throttle else (0.3 if int(t / 4.0) % 2 == 0 else 0.8)
        fx = 2.0 * thrust - 1.0 + 0.01 * rng.standard_normal()
        w = 0.002 * rng.standard_normal(3)
        pwm = (1500.0, 1500.0, 1500.0, 1000.0 + 1000.0 * thr) + (math.nan,) * 12
        yield Frame(t_us, [ImuSample(t_us, 0, np.array([fx, 0.0, -9.81]), w)],
                    euler_rad=np.zeros(3), att_age_s=0.0, att_rate_frd_radps=w,
                    servo=ServoOutputs(t_us, pwm, tuple((x - 1500) / 500 for x in pwm)),
                    servo_age_s=0.0, hud=HudSample(t_us, 25.0, 25.0, 0.0, thr), hud_age_s=0.0)


def test_the_engine_lag_is_the_one_the_data_show():
    """A turbofan-like lag (1.5 s): of the candidate lags (0, 0.4, 1.2, 3.6 s by default) the
    engine check ends on the closest, 1.2 s, and the throttle steps raise nothing; the same
    steps through a model without lag (``engine_lag_max_s = 0``) leave residuals over twice as
    large, which is what the search is for."""
    tier = _tier()
    events, _ = _run(tier, _engine_frames(80.0, tau_s=1.5))
    eng = tier.axes[3]
    assert eng.lag_models[eng.lag_k].tau_s == pytest.approx(1.2)
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]
    cfg = ActuatorFamilyConfig().aircraft
    no_lag = AircraftTier(dataclasses.replace(
        cfg, model=dataclasses.replace(cfg.model, engine_lag_max_s=0.0)), CTX)
    _run(no_lag, _engine_frames(80.0, tau_s=1.5))
    assert [m.tau_s for m in no_lag.axes[3].lag_models] == [0.0]
    assert no_lag.axes[3].sigma2 > 4.0 * eng.sigma2  # RMS over twice as large


def test_engine_out_is_raised_and_a_deficit_is_bounded_by_the_thrust():
    """The engine delivers nothing from 50 s: the engine channel raises a loss of thrust; the
    deficit an engine can explain is bounded by the modelled thrust (no loss above 100 %)."""
    tier = _tier()
    events, _ = _run(tier, _engine_frames(60.0, tau_s=0.3, out_at_s=50.0))
    raised = [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT
              and e.state is AlarmState.RAISED]
    assert raised and raised[0].channel == ChannelId("actuator", 3, "engine")
    assert 50.0 < raised[0].t_us * 1e-6 < 53.0
    assert raised[0].fault_type is FaultType.LOSS_OF_EFFECTIVENESS
    later = [e for e in events if e.channel == raised[0].channel]
    assert all(not e.magnitude > 1.0 for e in later)


@pytest.mark.parametrize(("loss", "raised"), [(0.1, False), (0.5, True)])
def test_an_engine_alarm_names_a_loss_the_model_resolves(loss: float, raised: bool) -> None:
    """An engine alarm claims a loss of thrust: it is raised only when the classifier's
    history holds at least ``engine_min_loss`` (25 %) of the modelled thrust missing. A 10 %
    loss from 50 s stays below that (the triplex campaign's healthy engines read up to 13 %
    in manoeuvres the model has not learnt); half the thrust lost is raised and named."""
    tier = _tier()
    events, _ = _run(tier, _engine_frames(70.0, tau_s=0.3, out_at_s=50.0, loss=loss))
    up = [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT
          and e.state is AlarmState.RAISED]
    assert bool(up) is raised
    if raised:
        assert up[0].channel == ChannelId("actuator", 3, "engine")
        assert up[0].magnitude == pytest.approx(loss, abs=0.15)


def test_a_link_outage_restarts_the_engine_lags():
    """3 s without telemetry while the throttle steps from 0.8 to 0.3 (at 40 s): the lag
    filters restart at the throttle after the gap, as the other lagged terms do; a filter
    carried across it expects the old throttle's thrust and reads a deficit (a fleet soak's
    false engine alarm)."""
    tier = _tier()
    frames = [f for f in _engine_frames(70.0, tau_s=1.5) if not 39.0 <= f.t_us * 1e-6 < 42.0]
    events, _ = _run(tier, frames)
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]


def test_after_a_gap_the_engine_settles_before_it_is_judged():
    """The throttle dips to 0.2 inside a 3 s telemetry gap and is at 0.9 when the link
    returns: the engine (1.5 s lag) is still spooling up, a deficit no model of the throttle
    seen can explain. The engine is not judged for three of its lag's time constants after the
    gap (a live soak's false engine alarm), and is judged again after them."""
    def thr(t: float) -> float:
        if 40.0 <= t < 41.8:
            return 0.2
        if 41.8 <= t < 46.0:
            return 0.9
        return 0.3 if int(t / 4.0) % 2 == 0 else 0.8

    tier = _tier()
    frames = [f for f in _engine_frames(70.0, tau_s=1.5, throttle=thr)
              if not 39.0 <= f.t_us * 1e-6 < 42.0]
    events, statuses = _run(tier, frames)
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]
    eng = tier.axes[3]
    assert eng.settle_us == pytest.approx(42.0e6 + 3.0 * 1.2e6, abs=0.05e6)
    assert eng.judged  # judged again by the end


def test_a_surface_first_used_late_is_not_a_fault():
    """The rudder is not used for 30 s (command exactly neutral), then the autopilot starts
    using it (an S-turn): its model has never seen the command's effect, and cannot predict
    its first use. The surface is judged once that effect is identified (|b| above 3 standard
    errors), not before (the triplex campaign's run 90: "rudder stuck" 1 s into its first
    use); judged without that rule, the same flight raises the rudder."""
    tier = _tier()
    frames = list(_frames(50.0, rudder_from_s=30.0))
    events, _ = _run(tier, frames[:round(29.0 / DT)])
    ax = tier.axes[2]
    assert tier.axes[0].judged and not ax.judged and not ax.identified  # past the warm-up
    more, _ = _run(tier, frames[round(29.0 / DT):])
    assert not [e for e in events + more if e.kind is AlarmKind.ACTUATOR_FAULT]
    assert ax.ref is not None and ax.judged and ax.identified
    assert abs(float(ax.ref.theta[0]) - B) < 0.05  # the rudder's effectiveness, learnt
    cfg = ActuatorFamilyConfig().aircraft
    always = AircraftTier(dataclasses.replace(
        cfg, model=dataclasses.replace(cfg.model, identified_se=0.0)), CTX)
    events, _ = _run(always, _frames(50.0, rudder_from_s=30.0))
    assert [e.channel.axis for e in events if e.state is AlarmState.RAISED] == ["rudder"]


def test_a_change_of_airspeed_source_restarts_the_models():
    """The air-data family shares its fused CAS, then loses its CAS set and withdraws it: the
    tier falls back to the ground speed (5 m/s less here), and its dynamic-pressure scale
    (V / V_ref)^2 would jump by a third. That is no actuator fault: the models restart on the
    new source, coverage says why, and they judge again after their warm-up."""
    ctx = FamilyContext(vehicle=1, stale_after_s=0.5)
    tier = AircraftTier(ActuatorFamilyConfig().aircraft, ctx)
    events, statuses = [], []
    switch_s = 30.0
    for f in _frames(55.0):
        t = f.t_us * 1e-6
        if t < switch_s:
            ctx.shared.put(AIRSPEED_CAS, 25.0, f.t_us, FUSED)
        else:
            ctx.shared.withdraw(AIRSPEED_CAS, f.t_us, "no healthy CAS instance")
        v = tier.judge(f, tier.predict(f))
        events += v.events
        statuses.append((t, v.status))
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]
    after = [st for t, st in statuses if switch_s < t < switch_s + 5.0 and st.sample]
    assert after and not any(st.judged for st in after)
    assert "airspeed from the ground speed, was the air-data family's fused CAS" in \
        after[-1].reason
    assert statuses[-1][1].judged  # judged again after the warm-up


def test_the_engine_is_not_judged_on_an_airspeed_that_drifts():
    """The air-data family shares the last healthy pitot of its set (``survivor``), which then
    runs away at -1 m/s^2: the engine model's drag term would follow it (Wan2018 run 153).
    The engine is not judged on it, and coverage says why; it is judged again once the
    airspeed is cross-checked again. Its models go on learning meanwhile."""
    ctx = FamilyContext(vehicle=1, stale_after_s=0.5)
    tier = AircraftTier(ActuatorFamilyConfig().aircraft, ctx)
    events, statuses = [], []
    for f in _engine_frames(70.0, tau_s=0.3):
        t = f.t_us * 1e-6
        lone = 30.0 <= t < 45.0
        v = 25.0 - (t - 30.0) if lone else 25.0
        ctx.shared.put(AIRSPEED_CAS, v, f.t_us, FUSED, survivor=lone)
        out = tier.judge(f, tier.predict(f))
        events += out.events
        statuses.append((t, out.status))
    assert not [e for e in events if e.kind is AlarmKind.ACTUATOR_FAULT]
    during = [st for t, st in statuses if 30.5 < t < 45.0 and st.sample]
    assert during and not any(st.judged for st in during)
    assert "the last healthy pitot of its set, unchecked" in during[-1].reason
    assert any(st.judged for t, st in statuses if t > 50.0)
