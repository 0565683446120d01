"""Fixed-step run loop: physics -> sensors + faults -> MAVLink packets (+ ground truth).

Three ways to run a :class:`~sim_vehicle.scenario.Scenario`:

* :func:`run_scenario` -- file mode (.tlog as fast as possible) or live (udpout, real time),
  always with the truth NPZ and the scenario TOML beside the .tlog;
* :func:`iter_packets` -- in memory, yields ``(vehicle_time_us, packet_bytes)``, writes nothing
  (for the evaluation harness);
* :func:`iter_run` -- the loop itself, yielding ``(t_us, message_type, packet)``.
"""

from __future__ import annotations

import logging
import time
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

from sim_vehicle.actuators.sensors import SurfaceSensorNoise, SurfaceSensors
from sim_vehicle.mavlink_out import MavlinkEncoder, MavlinkSigner, TlogWriter, UdpSender
from sim_vehicle.scenario import Scenario
from sim_vehicle.sensors.noise import SENSOR_SETS, SensorSet
from sim_vehicle.sensors.suite import SensorSuite
from sim_vehicle.state import TrueState
from sim_vehicle.truth import TruthRecorder, atomic_write_text, fault_events

log = logging.getLogger(__name__)

DEFAULT_UDP = ("127.0.0.1", 14550)
FALLBACK_MAX_DEFLECTION_RAD = (0.35, 0.35, 0.4)


class SimulationLike(Protocol):
    dt_s: float

    def step(self) -> TrueState: ...

    def state(self) -> TrueState: ...


SimulationFactory = Callable[[Scenario], SimulationLike]


FeedbackHook = Callable[[TrueState], TrueState]


def make_simulation(sc: Scenario, *, feedback: FeedbackHook | None = None) -> SimulationLike:
    """The physics (``sim_vehicle.physics.Simulation``) configured from a scenario.

    ``feedback`` maps the true state to what the autopilot sees (closed-loop studies: a faulty
    sensor in the loop); ``None`` = the autopilot sees the truth.
    """
    from sim_vehicle import physics  # late: physics is heavy and optional for sensor-only use

    return physics.Simulation(
        sc.airframe,
        physics.InitialCondition(**asdict(sc.initial)),
        physics.WindConfig(**asdict(sc.wind)),
        physics.ManoeuvreConfig(**asdict(sc.manoeuvre)),
        actuator_faults=sc.actuator_faults,
        seed=sc.seed,
        dt_s=sc.dt_s,
        feedback=feedback,
    )


def airframe_max_deflection(name: str) -> tuple[float, float, float]:
    """``[actuators] max_deflection_rad`` of an airframe file (PWM scaling of SERVO_OUTPUT_RAW)."""
    p = Path(__file__).parent / "airframes" / f"{name}.toml"
    try:
        v = tomllib.loads(p.read_text())["actuators"]["max_deflection_rad"]
        return (float(v[0]), float(v[1]), float(v[2]))
    except (OSError, KeyError, IndexError, TypeError, tomllib.TOMLDecodeError):
        return FALLBACK_MAX_DEFLECTION_RAD


def sensor_set_of(sc: Scenario) -> SensorSet:
    base = SENSOR_SETS[sc.sensors.set_name]
    return SensorSet(base.name, base.noise, sc.sensors.rates, base.source)


@dataclass
class _Clock:
    period_us: int
    next_us: int = 0

    def due(self, t_us: int) -> bool:
        if t_us < self.next_us:
            return False
        self.next_us += self.period_us
        if self.next_us <= t_us:
            self.next_us = t_us + self.period_us
        return True


@dataclass
class RunState:
    """What a run produced besides packets (filled while iterating)."""

    suite: SensorSuite | None = None
    truth: TruthRecorder | None = None
    counts: dict[str, int] = field(default_factory=dict)
    steps: int = 0


def iter_run(
    sc: Scenario,
    *,
    simulation_factory: SimulationFactory = make_simulation,
    record_truth: bool = False,
    run_state: RunState | None = None,
    on_step: Callable[[int], None] | None = None,
    feedback: FeedbackHook | None = None,
) -> Iterator[tuple[int, str, bytes]]:
    """The fixed-step loop; yields ``(t_us, message_type, packet)`` in time order.

    Parameters
    ----------
    sc : the scenario
    simulation_factory : builds the physics (tests pass a stand-in)
    record_truth : keep the true state at ``sc.output.truth_hz`` in ``run_state.truth``
    run_state : receives the sensor suite (fault log), truth recorder and message counts
    on_step : called with the vehicle time (µs) before the packets of each step are yielded
    feedback : what the autopilot sees instead of the true state (``Simulation.feedback``);
        the sensors, MAVLink output and truth always get the true state
    """
    rs = run_state if run_state is not None else RunState()
    sim = simulation_factory(sc)
    if feedback is not None:
        if not hasattr(sim, "feedback"):
            raise TypeError(f"feedback= needs a simulation with a 'feedback' attribute, "
                            f"got {type(sim).__name__}")
        sim.feedback = feedback
    dt_us = round(sc.dt_s * 1e6)
    n_steps = round(sc.duration_s / sc.dt_s)
    suite = SensorSuite(
        sensor_set_of(sc),
        n_imu=sc.sensors.n_imu,
        faults=sc.faults,
        seed=sc.seed,
        gps_latency_s=sc.sensors.gps_latency_s,
    )
    rs.suite = suite
    rs.truth = TruthRecorder() if record_truth else None
    enc = MavlinkEncoder(
        sysid=sc.output.sysid,
        servo_max_deflection_rad=airframe_max_deflection(sc.airframe),
        home_alt_m=sc.initial.alt_m,
    )
    surf_sensors = SurfaceSensors(SurfaceSensorNoise(), sc.seed)  # SURF position sensors
    o = sc.output
    hb = _Clock(round(1e6 / o.heartbeat_hz))
    servo = _Clock(round(1e6 / o.servo_output_raw_hz))
    surf = _Clock(round(1e6 / o.surf_hz))
    nav = _Clock(round(1e6 / o.nav_hz))
    truth_clock = _Clock(round(1e6 / o.truth_hz))
    counts = rs.counts
    st = sim.state()
    for k in range(n_steps + 1):
        t_us = k * dt_us
        if k > 0:
            st = sim.step()
        if on_step is not None:
            on_step(t_us)
        out: list[tuple[str, bytes]] = []
        if hb.due(t_us):
            out.append(enc.heartbeat())
        for smp in suite.step(st, t_us):
            out += enc.encode_sample(smp)
        if servo.due(t_us):
            out.append(enc.servo_output_raw(t_us, st))
        if surf.due(t_us):
            out.append(enc.surf(t_us, surf_sensors.measure(st)))
        if nav.due(t_us):
            out += enc.setpoints(t_us, st)
        if rs.truth is not None and truth_clock.due(t_us):
            rs.truth.record(st)
        rs.steps = k + 1
        for name, pkt in out:
            counts[name] = counts.get(name, 0) + 1
            yield t_us, name, pkt


def iter_packets(
    sc: Scenario,
    *,
    simulation_factory: SimulationFactory = make_simulation,
    feedback: FeedbackHook | None = None,
) -> Iterator[tuple[int, bytes]]:
    """In-memory run: ``(vehicle_time_us, packet_bytes)``; no files, no sockets, no clock."""
    for t_us, _, pkt in iter_run(sc, simulation_factory=simulation_factory, feedback=feedback):
        yield t_us, pkt


@dataclass
class RunResult:
    scenario: Scenario
    tlog_path: Path | None
    truth_path: Path
    scenario_path: Path
    counts: dict[str, int]
    fault_events: list[dict[str, Any]]
    vehicle_duration_s: float
    wall_s: float

    @property
    def realtime_factor(self) -> float:
        return self.vehicle_duration_s / self.wall_s if self.wall_s > 0 else float("inf")


def run_scenario(
    sc: Scenario,
    out_dir: Path | str,
    *,
    live: bool = False,
    udp: tuple[str, int] = DEFAULT_UDP,
    progress: bool = True,
    simulation_factory: SimulationFactory = make_simulation,
    feedback: FeedbackHook | None = None,
    signing_key: bytes | None = None,
) -> RunResult:
    """Run a scenario to a .tlog (file mode) or to UDP in real time (live), plus ground truth.

    Files in ``out_dir``: ``<name>_s<seed>.tlog`` (file mode), ``.truth.npz``,
    ``.scenario.toml``; each written to a temporary name and renamed when complete.
    ``feedback`` is passed to :func:`iter_run` (closed-loop studies). ``signing_key``: every
    packet is MAVLink 2 signed (:class:`~sim_vehicle.mavlink_out.MavlinkSigner`).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"{sc.name}_s{sc.seed}"
    rs = RunState()
    n_steps = round(sc.duration_s / sc.dt_s)
    bar = None
    if progress and not live:
        from tqdm import tqdm

        bar = tqdm(total=n_steps + 1, unit="step", desc=sc.name, leave=False)
    sink: TlogWriter | UdpSender
    sink = UdpSender(*udp) if live else TlogWriter(out / f"{stem}.tlog")
    pace = sink.pace if isinstance(sink, UdpSender) else None

    def on_step(t_us: int) -> None:
        if pace is not None:
            pace(t_us)
        if bar is not None:
            bar.update(1)

    signer = None if signing_key is None else MavlinkSigner(signing_key, wall_clock=live)
    t0 = time.perf_counter()
    ok = False
    try:
        for t_us, _, pkt in iter_run(sc, simulation_factory=simulation_factory,
                                     record_truth=True, run_state=rs, on_step=on_step,
                                     feedback=feedback):
            sink.write(t_us, pkt if signer is None else signer.sign(pkt, t_us))
        ok = True
    finally:
        if isinstance(sink, TlogWriter):
            sink.close(commit=ok)
        else:
            sink.close()
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    assert rs.truth is not None and rs.suite is not None
    truth_path = rs.truth.save(out / f"{stem}.truth.npz", sc, rs.suite.fault_log)
    from sim_vehicle.scenario import to_toml

    scen_path = atomic_write_text(out / f"{stem}.scenario.toml", to_toml(sc))
    log.info("ran %s: %.1f s vehicle in %.2f s wall", sc.name, sc.duration_s, wall)
    return RunResult(
        scenario=sc,
        tlog_path=None if live else out / f"{stem}.tlog",
        truth_path=truth_path,
        scenario_path=scen_path,
        counts=dict(rs.counts),
        fault_events=fault_events(sc),
        vehicle_duration_s=(rs.steps - 1) * sc.dt_s,
        wall_s=wall,
    )
