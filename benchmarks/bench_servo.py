"""Per-sample cost of Lu2017's servo filters (the servo level of the actuator family).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_servo.py [--seconds S]

Data: the simulator's servo bank (transport lever) with a 2 deg 3-2-1-1 on the elevator and a
liquid OFC (0.05 at 1 Hz) from 6 s, sampled at the SURF rate (50 Hz) with the simulator's
sensor noise. Timed, per surface and SURF sample:

* ``IOTSEKF`` -- the command-sampling covariance, the closed-loop propagation with its tangent
  (Phi, Gamma, Q_d) and the two-stage step, through their kernels called from Python (what one
  filter alone costs);
* ``RTS-EKF`` -- the nominal servo's propagation with its tangent, the timing envelope (two more
  propagations) and the three-step update, likewise;
* ``both, compiled`` -- ``_servo_filters_jit.surface_step``, the one call the monitor makes;
* ``both, numpy reference`` -- ``tests/reference/servo_filters.py`` (the same kernels chained
  from Python with numpy, dataclasses and LAPACK);
* ``tier`` -- ``ServoTier.predict + judge + update`` on one Frame: three surfaces and their FDI.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np

from gcs_monitor.core.kernels import load_kernels
from gcs_monitor.core.units import DEG2RAD
from gcs_monitor.families.actuators.servo import ServoTier, ServoTierConfig
from gcs_monitor.families.actuators.servo_filters import (
    N_OUT,
    ServoFilterConfig,
    ServoFilters,
    ServoSensors,
)
from gcs_monitor.families.base import FamilyContext
from gcs_monitor.models.servo import ServoLoopParams, ServoParams, pack_params
from gcs_monitor.telemetry.frame import Frame
from sim_vehicle.actuators.faults import ActuatorFault
from sim_vehicle.actuators.servo_bank import ActuatorGeometry, ServoBank
from tests.reference.servo_filters import ReferenceServoFilters

SIM_DT = 0.01
SURF_DT = 0.02


def _samples(seconds: float) -> np.ndarray:
    """(N, 4) per SURF sample: t, elevator command, rod sensor, surface sensor (noisy)."""
    bank = ServoBank(ActuatorGeometry(1.4, 0.35), (0.0, 0.0, 0.0),
                     faults=(ActuatorFault(1, "liquid_ofc", 6.0, None, 0.05, 1.0),))
    sens = ServoSensors()
    rng = np.random.default_rng(0)
    out = []
    t = 0.0
    for k in range(round(seconds / SIM_DT)):
        tau = (t - 1.0) % 7.0 if t >= 1.0 else -1.0
        cmd = 0.0
        for a, b, sgn in ((0, 3, 1), (3, 5, -1), (5, 6, 1), (6, 7, -1)):
            if a <= tau < b:
                cmd = sgn * 2.0 * DEG2RAD
        bank.step(t, SIM_DT, (0.0, cmd, 0.0))
        t = (k + 1) * SIM_DT
        if (k + 1) % 2 == 0:
            out.append((t, cmd, bank.rod_sensor_m(1) + sens.rod_sigma_m * rng.standard_normal(),
                        bank.deflection_rad(1) + sens.surf_sigma_rad * rng.standard_normal()))
    return np.array(out)


def _time(step: Callable[[int], object], n: int, skip: int = 50) -> tuple[float, float]:
    ts = []
    for i in range(1, n):
        t0 = time.perf_counter()
        step(i)
        ts.append(time.perf_counter() - t0)
    a = np.array(ts[skip:]) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="simulated seconds of SURF data")
    args = ap.parse_args()
    S = _samples(args.seconds)
    n = len(S)
    servo, loop, sens, cfg = ServoParams(), ServoLoopParams(), ServoSensors(), ServoFilterConfig()
    rows: list[tuple[str, float, float]] = []

    # both filters, compiled: the monitor's call
    f = ServoFilters(servo, loop, sens, cfg)
    f.start(S[0, 1], S[0, 2])
    out = np.zeros(N_OUT)
    f.step(SURF_DT, S[1, 1], S[1, 2], S[1, 3], out)  # compile / load outside the timing
    f.start(S[0, 1], S[0, 2])
    rows.append(("both, compiled (surface_step)",
                 *_time(lambda i: f.step(SURF_DT, S[i, 1], S[i, 2], S[i, 3], out), n)))

    # each filter alone, through its kernels
    mk = load_kernels("gcs_monitor.models._servo_jit")
    ik = load_kernels("gcs_monitor.filters._iotsekf_jit")
    tk = load_kernels("gcs_monitor.filters._three_step_jit")
    sk = load_kernels("gcs_monitor.families.actuators._servo_filters_jit")
    prm = pack_params(servo, loop, sens.rod_stroke_m)
    g = sens.rod_gain_radpm
    st = f.st.copy()
    n_sub = max(1, math.ceil(SURF_DT / cfg.substep_s - 1e-9))
    knee = SURF_DT - cfg.command_lead_s
    qs = np.array([*cfg.state_noise_psd, 0.0, 0.0, 0.0])
    H1 = np.zeros((1, 6))
    H1[0, 0] = 1.0
    R1 = np.array([[sens.rod_sigma_m ** 2]])
    Qf = np.array([[(cfg.fault_rate_sigma * SURF_DT) ** 2]])
    Phi, gam, Qd, Qt = np.empty((6, 6)), np.empty(6), np.empty((6, 6)), np.empty((6, 6))
    ots, oin = np.empty(sk.N_IOTS), np.empty(3)
    H2 = np.zeros((2, 6))
    H2[:, 0] = 1.0
    R2 = np.diag([sens.rod_sigma_m ** 2, (sens.surf_sigma_rad / g) ** 2])
    F2 = np.eye(2)
    xr, Pr, Pp = np.empty(6), np.empty((6, 6)), np.empty((6, 6))
    fr, Pfr, w2a, w2b, w2c = (np.empty(2), np.empty((2, 2)), np.empty(2), np.empty(2),
                              np.empty(2))
    y2, hx2 = np.empty(2), np.empty(2)

    def iotsekf(i: int) -> None:
        qc0, qc1 = S[i - 1, 1] / g, S[i, 1] / g
        x = st[sk.S_XHAT:sk.S_XHAT + 6].copy()
        sk.command_noise(x, qc0, qc1, 0.0, 0.0, SURF_DT, n_sub, prm, True, True, Qt)
        mk.propagate(x, qc0, qc1, st[sk.S_F], SURF_DT, knee, n_sub, prm, True,
                     cfg.valve_noise_psd, qs, Phi, gam, Qd)
        xbp = x - (Phi @ st[sk.S_V:sk.S_V + 6] + gam) * st[sk.S_F]
        ik.step(xbp, Phi, gam.reshape(6, 1), Qd + Qt, Qf, st[sk.S_XBAR:sk.S_XBAR + 6],
                st[sk.S_PBAR:sk.S_PBAR + 36].reshape(6, 6), st[sk.S_F:sk.S_F + 1],
                st[sk.S_PF:sk.S_PF + 1].reshape(1, 1), st[sk.S_V:sk.S_V + 6].reshape(6, 1), H1,
                np.array([S[i, 2]]), R1, cfg.gate_sigma, ots, oin)

    def rtsekf(i: int) -> None:
        qc0, qc1 = S[i - 1, 1] / g, S[i, 1] / g
        x = st[sk.S_XNOM:sk.S_XNOM + 6].copy()
        mk.propagate(x, qc0, qc1, 0.0, SURF_DT, knee, n_sub, prm, True, cfg.valve_noise_psd, qs,
                     Phi, gam, Qd)
        xe = st[sk.S_XE:sk.S_XE + 6].copy()
        xl = st[sk.S_XL:sk.S_XL + 6].copy()
        mk.propagate(xe, qc1, qc1, 0.0, SURF_DT, SURF_DT, n_sub, prm, False, 0.0, qs, Phi, gam,
                     Qd)
        mk.propagate(xl, qc0, qc0, 0.0, SURF_DT, SURF_DT, n_sub, prm, False, 0.0, qs, Phi, gam,
                     Qd)
        tk.predict_covariance(st[sk.S_PNOM:sk.S_PNOM + 36].reshape(6, 6), Phi, Qd, Pp)
        y2[0], y2[1] = S[i, 2], S[i, 3] / g
        hx2[0] = hx2[1] = x[0]
        tk.update(x, Pp, hx2, H2, F2, y2, R2, cfg.gate_sigma, xr, Pr, fr, Pfr, w2a, w2b, w2c)

    iotsekf(1)
    rtsekf(1)
    rows.append(("IOTSEKF alone (its kernels from Python)", *_time(iotsekf, n)))
    rows.append(("RTS-EKF alone (its kernels from Python)", *_time(rtsekf, n)))

    ref = ReferenceServoFilters(servo, loop, sens, cfg)
    ref.start(S[0, 1], S[0, 2])
    rows.append(("both, numpy reference", *_time(
        lambda i: ref.step(SURF_DT, S[i, 1], S[i, 2], S[i, 3]), min(n, 400))))

    # the tier: three surfaces and their FDI per Frame
    tier = ServoTier(ServoTierConfig(), FamilyContext(vehicle=1, stale_after_s=0.5))
    frames = [Frame(t_us=round(S[i, 0] * 1e6), imu=[],
                    surf_cmd_rad=np.array([0.0, S[i, 1], 0.0]),
                    surf_pos_rad=np.array([0.0, S[i, 3], 0.0]),
                    rod_pos_m=np.array([0.0, S[i, 2], 0.0]), surf_age_s=0.0) for i in range(n)]

    def tier_step(i: int) -> None:
        fr_ = frames[i]
        p = tier.predict(fr_)
        tier.update(fr_, tier.judge(fr_, p))

    tier_step(0)
    med, p99 = _time(tier_step, n, skip=150)  # after the 2 s warm-up: the FDI runs too
    rows.append(("tier: 3 surfaces + FDI per SURF sample", med, p99))

    print(f"{n} SURF samples at {1 / SURF_DT:g} Hz (a 3-2-1-1 and a liquid OFC on the elevator)")
    print()
    print("| step | median [µs] | p99 [µs] |")
    print("|---|---|---|")
    for name, med_, p99_ in rows:
        print(f"| {name} | {med_:.1f} | {p99_:.1f} |")
    rt = SURF_DT * 1e6 / med
    print()
    print(f"tier at {1 / SURF_DT:g} Hz SURF: {rt:.0f}x real time on its own (median)")


if __name__ == "__main__":
    main()
