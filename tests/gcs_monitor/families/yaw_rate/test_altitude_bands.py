"""Altitude bands of the yaw-rate design: why one LPV model in V_eas (Chen2020 eq. 59) holds at
one altitude only, and how the observer picks and switches its band."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.core.atmosphere import cas_from_tas
from gcs_monitor.families.yaw_rate.config import YawRateFamilyConfig
from gcs_monitor.families.yaw_rate.design import ObserverDesign, load_bands, load_design
from gcs_monitor.families.yaw_rate.estimator import BAND_HYSTERESIS_M, YawRateEstimator
from gcs_monitor.models.lateral import eas_from_tas
from gcs_monitor.telemetry.frame import Frame, ImuSample

CFG = YawRateFamilyConfig()
PHI, BETA, P, R = range(4)


def test_the_shipped_transport_bands_are_contiguous_and_the_first_is_the_reference() -> None:
    bands = load_bands("transport")
    assert [b.alt_range_m for b in bands] == [(-500.0, 3000.0), (3000.0, 6000.0),
                                             (6000.0, 9000.0), (9000.0, 12000.0)]
    ref = load_design("transport")
    assert np.array_equal(ref.model.A, bands[0].model.A)
    assert [b.alt_range_m for b in load_bands("uav")] == [(-500.0, 3500.0)]


def test_at_one_equivalent_airspeed_damping_and_kinematics_scale_with_sqrt_density() -> None:
    """Hand-derived: at a fixed V_eas the dynamic pressure is fixed, so L_beta, N_beta and the
    control derivatives are the same at every altitude, while the damping derivatives
    (L_p = q S b^2 C_lp / (2 V_tas I_x), ...), Y_beta / V_tas and g / V_tas scale with
    1 / V_tas = sqrt(rho / rho_0) / V_eas: the 7500 m band's over the 1500 m band's is
    sqrt(sigma(7500) / sigma(1500)) = 0.7253. A model in V_eas alone (Chen2020 eq. 59) built
    at 1500 m is therefore 27 % off in damping at 7500 m."""
    lo, hi = load_bands("transport")[0], load_bands("transport")[2]
    ratio = eas_from_tas(1.0, 7500.0) / eas_from_tas(1.0, 1500.0)
    assert ratio == pytest.approx(0.7253, abs=1e-4)
    for eas in (90.0, 130.0, 170.0):
        A0, B0, _ = lo.model.matrices(eas)
        A1, B1, _ = hi.model.matrices(eas)
        for i, j in ((P, P), (R, R), (BETA, BETA), (BETA, PHI)):
            assert A1[i, j] / A0[i, j] == pytest.approx(ratio, rel=3e-3), (eas, i, j)
        for i, j in ((P, BETA), (R, BETA)):
            assert A1[i, j] / A0[i, j] == pytest.approx(1.0, rel=1e-6)
        np.testing.assert_allclose(B1[P:], B0[P:], rtol=1e-6)


def test_band_choice_keeps_its_band_within_the_hysteresis() -> None:
    est = YawRateEstimator(CFG)
    h = BAND_HYSTERESIS_M
    assert est._band_at(2900.0) == 0
    est._band = 0
    assert est._band_at(3000.0 + 0.5 * h) == 0  # baro noise at the edge: no switch
    assert est._band_at(3000.0 + 2 * h) == 1
    est._band = 1
    assert est._band_at(3000.0 - 0.5 * h) == 1
    assert est._band_at(3000.0 - 2 * h) == 0
    assert est._band_at(8000.0) == 2
    assert est._band_at(12000.0 + 2 * h) == -1
    assert est._band_at(math.nan) == -1


def test_an_identified_design_of_one_unbounded_band_holds_at_every_altitude(
        tmp_path: Path) -> None:
    d = load_design("uav")
    one = ObserverDesign(d.model, d.sensors, {"command": "test"})
    assert "alt_range_m" not in one.to_dict()
    path = tmp_path / "own.json"
    path.write_text(json.dumps(one.to_dict()))
    est = YawRateEstimator(YawRateFamilyConfig(design=str(path)))
    assert est._band_at(20000.0) == 0 and est._band_at(math.nan) == 0
    back = load_bands(str(path))
    assert len(back) == 1 and back[0].alt_range_m == (-math.inf, math.inf)


def test_overlapping_bands_are_refused(tmp_path: Path) -> None:
    d = load_design("uav")
    a = ObserverDesign(d.model, d.sensors, {}, (0.0, 2000.0)).to_dict()
    b = ObserverDesign(d.model, d.sensors, {}, (1500.0, 4000.0)).to_dict()
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"bands": [a, b]}))
    with pytest.raises(ValueError, match="overlap"):
        load_bands(str(path))


def _frame(t_s: float, alt_m: float, eas: float = 150.0) -> Frame:
    t_us = round(t_s * 1e6)
    tas = eas / eas_from_tas(1.0, alt_m)
    cas = cas_from_tas(tas, alt_m)
    return Frame(t_us=t_us, imu=[ImuSample(t_us, 0, np.zeros(3), np.zeros(3))],
                 euler_rad=np.zeros(3), att_age_s=0.0, ssa_rad=0.0,
                 cas_mps=np.full(3, cas), cas_age_s=np.zeros(3), baro_alt_m=alt_m,
                 surf_pos_rad=np.zeros(3), surf_age_s=0.0)


def test_the_observer_runs_the_band_of_its_altitude_and_says_when_none_holds() -> None:
    est = YawRateEstimator(CFG)
    e = est.step(_frame(0.0, 1000.0))
    assert e.available and est.mats is est._mats[0]
    e = est.step(_frame(0.02, 7600.0))
    assert e.available and est.mats is est._mats[2] and not e.reinit  # re-anchored, judging
    e = est.step(_frame(0.04, 13000.0))
    assert not e.available and e.reason.startswith("altitude above the 'transport' design's")
