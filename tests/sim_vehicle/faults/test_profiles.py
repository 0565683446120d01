"""Fault profiles: the value applied to the measurement equals each fault's definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_monitor.core.units import DEG2RAD
from sim_vehicle.faults.profiles import (
    ExpressionError,
    FaultInjector,
    FaultSpec,
    compile_expression,
)

T0, T1 = 10.0, 30.0
TIMES = np.arange(0.0, 40.0, 0.05)


def true_x(t: float) -> float:
    return 2.0 + math.sin(0.3 * t)  # a time-varying true value


def applied(spec: FaultSpec, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Fault value y - healthy and the measured value for a noise-free healthy signal."""
    inj = FaultInjector((spec,), seed)
    f, y = [], []
    for t in TIMES:
        yt = inj.apply(spec.channel, float(t), true_x(float(t)), true_x(float(t)))
        y.append(yt)
        f.append(yt - true_x(float(t)))
    return np.array(f), np.array(y)


def window(t: float) -> bool:
    return T0 <= t < T1


DEFINITIONS = {
    "bias": (("bias_mps2", 3.0),),
    "drift": (("rate_mps2_per_s", 0.1), ("max_mps2", 1.5)),
    "oscillation": (("amplitude_mps2", 4.0), ("frequency_hz", 0.25), ("phase_rad", 0.3)),
    "runaway": (("rate_mps2_per_s", -0.4), ("limit_mps2", 5.0)),
    "nrz": (("level", 0.1),),
    "nrz_gain": (("gain", 0.1),),
    "scale": (("factor", 1.2),),
}


def expected(kind: str, t: float) -> float:
    if not window(t):
        return 0.0
    tau = t - T0
    if kind == "bias":
        return 3.0
    if kind == "drift":
        return min(0.1 * tau, 1.5)
    if kind == "oscillation":
        return 4.0 * math.sin(2 * math.pi * 0.25 * tau + 0.3)
    if kind == "runaway":
        return max(-0.4 * tau, -5.0)
    if kind == "nrz":
        return -0.9 * true_x(t)  # Wan2018 Table II: the output falls to 10% x current value
    if kind == "nrz_gain":
        return 0.1 * true_x(t)  # the literal reading: f = 0.1 x
    if kind == "scale":
        return 0.2 * true_x(t)
    raise KeyError(kind)


@pytest.mark.parametrize("kind", sorted(DEFINITIONS))
def test_additive_fault_equals_definition(kind: str) -> None:
    spec = FaultSpec("imu0.acc.x", kind.split("_")[0], T0, T1, DEFINITIONS[kind])
    f, _ = applied(spec)
    ref = np.array([expected(kind, float(t)) for t in TIMES])
    np.testing.assert_allclose(f, ref, atol=1e-12)  # same formula, float64 round-off only


def test_nrz_output_is_a_tenth_of_the_true_value() -> None:
    """Wan2018 Table II's non-return to zero: the measurement falls to 10 % of the value."""
    _, y = applied(FaultSpec("cas1", "nrz", T0, T1))  # level 0.1 by default
    inside = np.array([window(float(t)) for t in TIMES])
    x = np.array([true_x(float(t)) for t in TIMES])
    np.testing.assert_allclose(y[inside], 0.1 * x[inside], atol=1e-12)
    np.testing.assert_allclose(y[~inside], x[~inside])


def test_jam_holds_true_value_at_fault_start() -> None:
    spec = FaultSpec("aoa1", "jam", T0, T1)
    f, y = applied(spec)
    inside = np.array([window(float(t)) for t in TIMES])
    np.testing.assert_allclose(y[inside], true_x(T0), atol=1e-12)
    np.testing.assert_allclose(f[~inside], 0.0)


def test_noise_fault_std_and_zero_outside() -> None:
    spec = FaultSpec("cas0", "noise", 0.0, 1000.0, (("sigma_mps", 5.0),))
    inj = FaultInjector((spec,), 3)
    f = np.array([inj.apply("cas0", 0.01 * k, 0.0, 0.0) for k in range(20_000)])
    assert abs(f.std() - 5.0) < 0.15  # 20k samples: std of the std ~0.5%
    inj2 = FaultInjector((spec,), 3)
    f2 = np.array([inj2.apply("cas0", 0.01 * k, 0.0, 0.0) for k in range(100)])
    np.testing.assert_array_equal(f[:100], f2)  # seeded: deterministic


def test_expression_reproduces_lu2016_table2() -> None:
    fz = FaultSpec("imu0.acc.z", "expr", T0, T1, (("expr_mps2", "4*sin(0.5*pi*t)"),))
    fy = FaultSpec("imu0.acc.y", "expr", T0, T1, (("expr_mps2", "0.1*(t-10)"),))
    fq = FaultSpec("imu0.gyro.q", "expr", T0, T1,
                   (("expr_degps", "sin(0.5*pi*(t-10))"), ("si_factor", DEG2RAD)))
    for spec, ref in (
        (fz, lambda t: 4 * math.sin(0.5 * math.pi * t)),
        (fy, lambda t: 0.1 * (t - 10)),
        (fq, lambda t: math.pi * math.sin(0.5 * math.pi * (t - 10)) / 180),
    ):
        f, _ = applied(spec)
        exp = np.array([ref(float(t)) if window(float(t)) else 0.0 for t in TIMES])
        np.testing.assert_allclose(f, exp, atol=1e-12)


def test_chen2020_drift_capped_at_5_degps() -> None:
    spec = FaultSpec("imu0.gyro.r", "drift", 30.0, None,
                     (("rate_radps_per_s", 0.4 * DEG2RAD), ("max_radps", 5.0 * DEG2RAD)))
    inj = FaultInjector((spec,), 0)
    assert inj.apply("imu0.gyro.r", 35.0, 0.0, 0.0) == pytest.approx(2.0 * DEG2RAD)
    assert inj.apply("imu0.gyro.r", 50.0, 0.0, 0.0) == pytest.approx(5.0 * DEG2RAD)
    assert inj.apply("imu0.gyro.r", 29.99, 0.0, 0.0) == 0.0


def test_expression_whitelist() -> None:
    with pytest.raises(ExpressionError):
        compile_expression("__import__('os').system('true')")
    with pytest.raises(ExpressionError):
        compile_expression("x + 1")
    with pytest.raises(ExpressionError):
        compile_expression("'a'")
    assert compile_expression("tau**2 + max(t, 1)")(3.0, 2.0) == 7.0
