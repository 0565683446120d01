"""Wind: Dryden spectra (Lu2016 eqs. 21-23), shear profile, exact discretisation."""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import welch

from sim_vehicle.environment.wind import (
    SHEAR_DURATION_S,
    DrydenTurbulence,
    WindField,
    dryden_psd,
    shear_ned_mps,
)


def _record(n: int, dt_s: float, tas_mps: float, seed: int) -> np.ndarray:
    turb = DrydenTurbulence(3.54, 530.0, dt_s, np.random.default_rng(seed))
    out = np.empty((n, 3))
    for i in range(n):
        out[i] = turb.step(tas_mps)
    return out


def test_dryden_psd_matches_lu2016_eqs_21_23() -> None:
    # 10 Hz is enough below 2 rad/s (the discretisation is exact, aliasing of the Dryden tail
    # at the 31 rad/s Nyquist frequency is < 1e-3 of the in-band level); 16.7 h of turbulence.
    dt_s, tas = 0.1, 25.0
    rec = _record(600_000, dt_s, tas, seed=1)
    f_hz, pxx = welch(rec, fs=1.0 / dt_s, nperseg=8192, axis=0)  # one-sided, (m/s)^2/Hz
    omega = 2.0 * np.pi * f_hz
    # Compare in 12 log-spaced bands over 0.1-2 rad/s (each band averages several Welch bins,
    # so the estimate's scatter is a few %, well inside the 30 % tolerance).
    edges = np.geomspace(0.1, 2.0, 13)
    # Phi(omega) d omega = S(f) df  ->  Phi = S / (2 pi)
    phi_meas = pxx / (2.0 * np.pi)
    phi_true = np.stack(dryden_psd(omega, 3.54, 530.0, tas), axis=1)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (omega >= lo) & (omega < hi)
        assert sel.sum() >= 2
        ratio = phi_meas[sel].mean(axis=0) / phi_true[sel].mean(axis=0)
        assert np.all(np.abs(ratio - 1.0) < 0.30), (lo, hi, ratio)
    # and the variance is sigma^2 (Lu2016: sigma = 3.54 m/s), within the sampling error of a
    # record ~ 2800 correlation times (L/V = 21 s) long
    np.testing.assert_allclose(rec.std(axis=0), 3.54, rtol=0.05)


def test_dryden_psd_integrates_to_sigma_squared() -> None:
    # Hand check of the normalisation of eqs. 21-23: int_0^inf Phi d omega = sigma^2.
    omega = np.linspace(0.0, 2000.0, 2_000_001)
    for phi in dryden_psd(omega, 2.0, 300.0, 50.0):
        integral = np.trapezoid(phi, omega)
        assert abs(integral - 4.0) < 0.02  # tail beyond 2000 rad/s: ~ 2 sigma^2 V/(pi L w_max)


def test_dryden_exact_discretisation_is_step_size_independent() -> None:
    # The lag-1 autocorrelation of u at dt equals exp(-V dt / L) exactly (first-order filter).
    dt_s, tas = 0.5, 100.0
    rec = _record(200_000, dt_s, tas, seed=3)[:, 0]
    rho1 = np.corrcoef(rec[:-1], rec[1:])[0, 1]
    assert abs(rho1 - math.exp(-tas * dt_s / 530.0)) < 0.01


def test_turbulence_is_reproducible_from_seed() -> None:
    a = _record(100, 0.01, 25.0, seed=7)
    b = _record(100, 0.01, 25.0, seed=7)
    c = _record(100, 0.01, 25.0, seed=8)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_block_noise_is_the_per_step_sequence(monkeypatch) -> None:  # noqa: ANN001
    # Noise drawn 1024 steps at a time gives the same turbulence as one draw of 5 per step,
    # across a block boundary and through a re-discretisation (airspeed change > 2 %).
    from sim_vehicle.environment import wind

    tas = np.where(np.arange(2500) < 1200, 25.0, 30.0)

    def rec() -> np.ndarray:
        turb = DrydenTurbulence(3.54, 530.0, 0.01, np.random.default_rng(11))
        return np.array([turb.step(float(v)) for v in tas])

    blocked = rec()
    monkeypatch.setattr(wind, "NOISE_BLOCK", 1)
    np.testing.assert_array_equal(blocked, rec())


def test_shear_profile_shape() -> None:
    t0, amp = 15.0, 10.0
    assert shear_ned_mps(t0 - 1.0, t0, amp, 0.0) == (0.0, 0.0, 0.0)
    assert shear_ned_mps(t0 + SHEAR_DURATION_S + 1.0, t0, amp, 0.0) == (0.0, 0.0, 0.0)
    n, e, d = shear_ned_mps(t0 + 0.5 * SHEAR_DURATION_S, t0, amp, 0.0)
    assert math.isclose(n, -amp) and abs(e) < 1e-12 and math.isclose(d, 0.5 * amp)
    # heading 90 deg: the head-wind component is along -East
    n, e, _ = shear_ned_mps(t0 + 0.5 * SHEAR_DURATION_S, t0, amp, math.pi / 2)
    assert abs(n) < 1e-9 and math.isclose(e, -amp)


def test_wind_field_constant_and_calm() -> None:
    eye = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    rng = np.random.default_rng(0)
    kw = dict(
        sigma_mps=3.54,
        scale_m=530.0,
        shear_start_s=15.0,
        shear_amplitude_mps=10.0,
        shear_heading_rad=0.0,
        dt_s=0.01,
        rng=rng,
    )
    assert WindField("calm", (5.0, 1.0, 0.0), **kw).wind_ned(20.0, eye) == (0.0, 0.0, 0.0)
    assert WindField("constant", (5.0, 1.0, 0.5), **kw).wind_ned(20.0, eye) == (5.0, 1.0, 0.5)
