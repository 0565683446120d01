"""LPV lateral-directional model of a fixed-wing aircraft (Chen2020 sec. V, eqs. 1 and 59).

State ``x_p = [phi, beta, p, r]`` (roll angle rad, sideslip rad, roll and yaw rate rad/s, body
FRD), input ``u_p = [delta_a, delta_r]`` (aileron and rudder deflection rad, the airframe's sign
conventions), scheduling parameter ``rho = [V_eas, V_eas^2]`` (Chen2020 eq. 59, m/s and m^2/s^2):

    x_p' = A(rho) x_p + B(rho) u_p + c(rho),
    A(rho) = A_0 + rho_1 A_1 + rho_2 A_2   (B and c alike)

``c`` is a trim offset (zero for a linearisation about a symmetric trim; a real aircraft's
identified model carries its lateral trim there). Chen2020 treats ``rho_1`` and ``rho_2`` as
independent (a box Omega), so the model's vertices are the four corners of
``[V_min, V_max] x [V_min^2, V_max^2]``.

Two ways to get a model:

* :func:`fit_lpv`: least squares of the matrices entry by entry over LTI models at several trim
  speeds (the simulator's linearisations, ``sim_vehicle.dynamics.linearise``), with its fit
  error (:class:`LpvFitError`);
* :func:`identify_lateral_model`: equation-error least squares from a clean flight log (Frames:
  attitude, body rates, sideslip, surface positions, airspeed), with the same fit error measured
  on the derivatives it explains.

Pure functions and a frozen dataclass; numpy and scipy only.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gcs_monitor.core.atmosphere import isa_density_kgpm3, tas_from_cas
from gcs_monitor.core.types import Mat, Vec

STATES = ("phi", "beta", "p", "r")
INPUTS = ("aileron", "rudder")
N_X = 4
N_U = 2
RHO0_KGPM3 = 1.225  # ISA sea-level density: V_eas = V_tas sqrt(rho / rho_0)


def rho_of(eas_mps: float) -> tuple[float, float]:
    """Scheduling parameter of Chen2020 eq. 59: ``[V_eas, V_eas^2]``."""
    return eas_mps, eas_mps * eas_mps


def eas_from_tas(tas_mps: float, alt_m: float) -> float:
    """Equivalent airspeed of a true airspeed at an ISA pressure altitude."""
    return tas_mps * math.sqrt(isa_density_kgpm3(alt_m) / RHO0_KGPM3)


@dataclass(frozen=True, slots=True)
class LateralLpv:
    """An LPV lateral-directional model affine in ``rho = [V_eas, V_eas^2]``.

    Attributes
    ----------
    A : (3, 4, 4) ``A_0, A_1, A_2``; ``A(rho) = A_0 + rho_1 A_1 + rho_2 A_2``
    B : (3, 4, 2) ``B_0, B_1, B_2``
    c : (3, 4) trim offsets ``c_0, c_1, c_2`` (rad/s, rad/s^2)
    eas_range_mps : the speeds the model was built on (the set Omega of Chen2020 sec. III)
    source : how it was obtained (airframe and altitude, or the flight log)
    """

    A: Mat
    B: Mat
    c: Mat
    eas_range_mps: tuple[float, float]
    source: str = ""

    def __post_init__(self) -> None:
        if self.A.shape != (3, N_X, N_X) or self.B.shape != (3, N_X, N_U) \
                or self.c.shape != (3, N_X):
            raise ValueError(f"LateralLpv shapes A {self.A.shape}, B {self.B.shape}, "
                             f"c {self.c.shape}; expected (3,4,4), (3,4,2), (3,4)")
        lo, hi = self.eas_range_mps
        if not 0.0 < lo <= hi:
            raise ValueError(f"eas_range_mps must satisfy 0 < min <= max, got {lo}, {hi}")

    def matrices(self, eas_mps: float) -> tuple[Mat, Mat, Vec]:
        """``A(rho), B(rho), c(rho)`` at one equivalent airspeed."""
        r1, r2 = rho_of(eas_mps)
        return (self.A[0] + r1 * self.A[1] + r2 * self.A[2],
                self.B[0] + r1 * self.B[1] + r2 * self.B[2],
                self.c[0] + r1 * self.c[1] + r2 * self.c[2])

    def vertices(self) -> list[tuple[float, float]]:
        """The four corners of Omega in ``(rho_1, rho_2)``, rho_1 and rho_2 independent
        (Chen2020 sec. V: "the conservative assumption ... independent of each other")."""
        lo, hi = self.eas_range_mps
        return [(r1, r2) for r1 in (lo, hi) for r2 in (lo * lo, hi * hi)]

    def at_rho(self, rho1: float, rho2: float) -> tuple[Mat, Mat]:
        """``A, B`` at a point of the (rho_1, rho_2) box (a vertex need not be a real speed)."""
        return (self.A[0] + rho1 * self.A[1] + rho2 * self.A[2],
                self.B[0] + rho1 * self.B[1] + rho2 * self.B[2])

    def to_dict(self) -> dict[str, Any]:
        return {"A": self.A.tolist(), "B": self.B.tolist(), "c": self.c.tolist(),
                "eas_range_mps": list(self.eas_range_mps), "source": self.source,
                "states": list(STATES), "inputs": list(INPUTS)}

    @staticmethod
    def from_dict(d: dict[str, Any]) -> LateralLpv:
        if list(d.get("states", STATES)) != list(STATES):
            raise ValueError(f"lateral model states {d.get('states')}, expected {STATES}")
        lo, hi = d["eas_range_mps"]
        return LateralLpv(np.asarray(d["A"], dtype=np.float64),
                          np.asarray(d["B"], dtype=np.float64),
                          np.asarray(d.get("c", np.zeros((3, N_X))), dtype=np.float64),
                          (float(lo), float(hi)), str(d.get("source", "")))


@dataclass(frozen=True, slots=True)
class LpvFitError:
    """How well an LPV model reproduces what it was fitted to.

    Attributes
    ----------
    rel_A, rel_B : worst ``||M_fit - M|| / ||M||`` (Frobenius) over the LTI points (linear fit),
        or NaN (identification)
    max_abs_A, max_abs_B : (4, 4), (4, 2) worst absolute entry error over the points
    eig_max_rad_s : worst distance between an eigenvalue of ``A`` and the nearest of
        ``A_fit`` over the points, rad/s
    nrmse : (4,) per state derivative, RMS of the equation error over the RMS of the derivative
        (identification; the linear fit reports the same on its points)
    n_points : LTI models or samples used
    """

    rel_A: float
    rel_B: float
    max_abs_A: Mat
    max_abs_B: Mat
    eig_max_rad_s: float
    nrmse: Vec
    n_points: int

    def summary(self) -> str:
        nr = ", ".join(f"{s} {v:.3g}" for s, v in zip(STATES, self.nrmse, strict=True))
        return (f"A rel. error {self.rel_A:.3g}, B rel. error {self.rel_B:.3g}, eigenvalues "
                f"within {self.eig_max_rad_s:.3g} rad/s; derivative NRMSE {nr} "
                f"({self.n_points} points)")


def _regressors(eas: Vec) -> Mat:
    return np.column_stack([np.ones_like(eas), eas, eas * eas])


def fit_lpv(eas_mps: Sequence[float], A: Sequence[Mat], B: Sequence[Mat], *,
            source: str = "") -> tuple[LateralLpv, LpvFitError]:
    """Fit ``A(rho)``, ``B(rho)`` affine in ``[V_eas, V_eas^2]`` to LTI models (Chen2020 eq. 59).

    Parameters
    ----------
    eas_mps : (N,) equivalent airspeed of each LTI model, N >= 3
    A, B : N matrices (4, 4) and (4, 2) (states and inputs in :data:`STATES`/:data:`INPUTS`)

    Returns
    -------
    the model (trim offset zero, Omega = the fitted speed range) and its fit error on the N
    points
    """
    v = np.asarray(eas_mps, dtype=np.float64)
    if v.size < 3:
        raise ValueError(f"need at least 3 LTI models, got {v.size}")
    Aa = np.asarray(A, dtype=np.float64)
    Ba = np.asarray(B, dtype=np.float64)
    X = _regressors(v)
    coefA, *_ = np.linalg.lstsq(X, Aa.reshape(v.size, -1), rcond=None)
    coefB, *_ = np.linalg.lstsq(X, Ba.reshape(v.size, -1), rcond=None)
    model = LateralLpv(np.asarray(coefA.reshape(3, N_X, N_X), dtype=np.float64),
                       np.asarray(coefB.reshape(3, N_X, N_U), dtype=np.float64),
                       np.zeros((3, N_X)), (float(v.min()), float(v.max())), source)
    Af = (X @ coefA).reshape(Aa.shape)
    Bf = (X @ coefB).reshape(Ba.shape)
    rel_A = max(float(np.linalg.norm(a - b) / np.linalg.norm(b)) for a, b in zip(Af, Aa,
                                                                                  strict=True))
    rel_B = max(float(np.linalg.norm(a - b) / np.linalg.norm(b)) for a, b in zip(Bf, Ba,
                                                                                  strict=True))
    eig = 0.0
    for a, b in zip(Af, Aa, strict=True):
        ea, eb = np.linalg.eigvals(a), np.linalg.eigvals(b)
        eig = max(eig, float(max(np.min(np.abs(ea - x)) for x in eb)))
    # derivative NRMSE on unit-normal states and inputs at every point: ||(M_fit - M) z|| / ||M z||
    dM = np.concatenate([Af - Aa, Bf - Ba], axis=2)
    M = np.concatenate([Aa, Ba], axis=2)
    num = np.sqrt(np.sum(dM ** 2, axis=(0, 2)))
    den = np.sqrt(np.sum(M ** 2, axis=(0, 2)))
    nrmse = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)
    return model, LpvFitError(rel_A, rel_B, np.max(np.abs(Af - Aa), axis=0),
                              np.max(np.abs(Bf - Ba), axis=0), eig, nrmse, int(v.size))


# ------------------------------------------------------------------------------------------------
# identification from a flight log
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class LateralSamples:
    """Time series for identification: uniformly resampled, SI.

    t_s : (N,) time; x : (N, 4) [phi, beta, p, r]; u : (N, 2) [aileron, rudder]; eas_mps : (N,)
    """

    t_s: Vec
    x: Mat
    u: Mat
    eas_mps: Vec


# what identification needs, in the order a Frame is checked (the first one absent is named)
LATERAL_INPUTS = ("body rates (IMU)", "attitude (ATTITUDE)", "sideslip (AOA_SSA)",
                  "surface positions or commands (SURF)", "airspeed (AIRSPEED)")


class LateralRecorder:
    """The lateral signals of a flight's Frames, one row per Frame that carries them all, and
    per input how many Frames carried it (so that a flight lacking one can say which).

    Uses ``euler_rad[0]``, ``ssa_rad``, the primary IMU's p and r, ``surf_pos_rad`` (aileron 0,
    rudder 2; ``surf_cmd_rad`` when positions are absent), the median valid CAS instance and
    ``baro_alt_m`` for the equivalent airspeed.
    """

    def __init__(self) -> None:
        # t, phi, beta, p, r, da, dr, eas; float arrays: an hour at 100 Hz is 23 MB
        self.cols: list[array[float]] = [array("d") for _ in range(8)]
        self.seen = dict.fromkeys(LATERAL_INPUTS, 0)
        self.frames = 0

    def add(self, f: Any) -> None:
        """Record one Frame."""
        self.frames += 1
        imu = f.primary_imu
        surf = f.surf_pos_rad if f.surf_pos_rad is not None else f.surf_cmd_rad
        cas = [c for c in np.asarray(f.cas_mps).tolist() if math.isfinite(c)]
        have = (imu is not None, f.euler_rad is not None, math.isfinite(f.ssa_rad),
                surf is not None, bool(cas))
        for name, ok in zip(LATERAL_INPUTS, have, strict=True):
            self.seen[name] += ok
        if not all(have):
            return
        alt = f.baro_alt_m if math.isfinite(f.baro_alt_m) else 0.0
        tas = tas_from_cas(float(np.median(cas)), alt)
        row = (f.t_us * 1e-6, float(f.euler_rad[0]), float(f.ssa_rad),
               float(imu.omega_frd_radps[0]), float(imu.omega_frd_radps[2]),
               float(surf[0]), float(surf[2]), eas_from_tas(tas, alt))
        for c, v in zip(self.cols, row, strict=True):
            c.append(v)

    def missing(self) -> list[str]:
        """The inputs no recorded Frame carried (empty when each was there at least once)."""
        return [k for k, n in self.seen.items() if n == 0]

    def samples(self, *, period_s: float = 0.02, stale_s: float = 0.5) -> LateralSamples:
        """The recorded rows resampled every ``period_s`` (see :func:`lateral_samples`)."""
        return _resample([np.asarray(c) for c in self.cols], period_s, stale_s)


def lateral_samples(frames: Iterable[Any], *, period_s: float = 0.02,
                    stale_s: float = 0.5) -> LateralSamples:
    """The lateral signals of a flight's Frames (:class:`LateralRecorder`), resampled every
    ``period_s`` (linear interpolation of each signal on its own valid instants; a Frame lacking
    an input leaves a gap, and samples of a gap longer than ``stale_s`` are dropped). Frames of
    several flights may follow one another: where the time goes back a new flight starts.
    """
    rec = LateralRecorder()
    for f in frames:
        rec.add(f)
    return rec.samples(period_s=period_s, stale_s=stale_s)


def _resample(cols: list[np.ndarray], period_s: float, stale_s: float) -> LateralSamples:
    t = cols[0]
    # several flights (or a reboot): each restarts its clock; lay them end to end with a gap
    # longer than ``stale_s`` so that no interpolation or derivative crosses from one to the next
    back = np.flatnonzero(np.diff(t) <= 0.0) + 1
    if back.size:
        t = t.copy()
        for b in back:
            t[b:] += t[b - 1] - t[b] + 2.0 * stale_s + period_s
    if t.size < 2:
        raise ValueError("the frames carry too few lateral samples (attitude, sideslip, body "
                         "rates, surfaces and airspeed all needed)")
    grid = np.arange(t[0], t[-1], period_s)
    idx = np.searchsorted(t, grid)
    prev = t[np.clip(idx - 1, 0, t.size - 1)]
    nxt = t[np.clip(idx, 0, t.size - 1)]
    ok = (nxt - prev) <= stale_s
    data = [np.interp(grid, t, c) for c in cols[1:]]
    return LateralSamples(grid[ok], np.column_stack(data[:4])[ok],
                          np.column_stack(data[4:6])[ok], data[6][ok])


def identify_lateral_model(frames: Iterable[Any] | LateralSamples, *,
                           period_s: float = 0.02, smooth_s: float = 0.3,
                           min_span_ratio: float = 0.15,
                           source: str = "flight log") -> tuple[LateralLpv, LpvFitError]:
    """The LPV lateral model of a clean flight (equation-error least squares).

    The state derivatives come from a Savitzky-Golay filter (cubic, ``smooth_s`` window) of the
    resampled signals; each row of ``[A | B | c]`` is regressed on ``[x, u, 1] (x) [1, V, V^2]``.
    A flight flown at one speed cannot separate the speed terms: when the span of ``V_eas`` is
    below ``min_span_ratio`` of its mean, the model is constant (``A_1 = A_2 = 0``) and valid only
    over the flown speeds.

    Parameters
    ----------
    frames : Frames of a fault-free flight with lateral excitation (turns, doublets), or
        samples from :func:`lateral_samples`
    period_s : resampling period (s)
    smooth_s : derivative filter window (s)
    min_span_ratio : relative speed span needed to fit the speed terms

    Returns
    -------
    the model and its fit error (``nrmse`` per state derivative; ``rel_A``/``rel_B`` NaN)
    """
    from scipy.signal import savgol_filter

    s = frames if isinstance(frames, LateralSamples) else lateral_samples(frames,
                                                                           period_s=period_s)
    n = s.t_s.size
    win = max(5, int(round(smooth_s / period_s)) | 1)
    if n < 4 * win:
        raise ValueError(f"{n} lateral samples: too few to identify a model")
    # contiguous runs only: the derivative filter must not straddle a gap
    breaks = np.flatnonzero(np.diff(s.t_s) > 1.5 * period_s) + 1
    xs, xd, us, vs = [], [], [], []
    for seg in np.split(np.arange(n), breaks):
        if seg.size < 2 * win:
            continue
        x = s.x[seg]
        xs.append(savgol_filter(x, win, 3, axis=0))
        xd.append(savgol_filter(x, win, 3, deriv=1, delta=period_s, axis=0))
        us.append(savgol_filter(s.u[seg], win, 3, axis=0))
        vs.append(s.eas_mps[seg])
    if not xs:
        raise ValueError("no contiguous stretch of lateral samples long enough")
    X, Xd, U, V = (np.concatenate(a) for a in (xs, xd, us, vs))
    base = np.column_stack([X, U, np.ones(len(V))])  # (N, 7)
    span = float(V.max() - V.min())
    scheduled = span >= min_span_ratio * float(V.mean())
    if scheduled:
        vn = V / float(V.mean())  # conditioning: regress on V / V_mean, rescaled below
        reg = np.concatenate([base, base * vn[:, None], base * (vn * vn)[:, None]], axis=1)
    else:
        reg = base
    coef, *_ = np.linalg.lstsq(reg, Xd, rcond=None)  # (k * 7, 4)
    resid = Xd - reg @ coef
    nrmse = np.sqrt(np.mean(resid ** 2, axis=0)) / np.maximum(
        np.sqrt(np.mean(Xd ** 2, axis=0)), 1e-12)
    A = np.zeros((3, N_X, N_X))
    B = np.zeros((3, N_X, N_U))
    c = np.zeros((3, N_X))
    vm = float(V.mean())
    for k in range(3 if scheduled else 1):
        blk = coef[7 * k:7 * (k + 1)].T / vm ** k  # (4, 7)
        A[k], B[k], c[k] = blk[:, :4], blk[:, 4:6], blk[:, 6]
    model = LateralLpv(A, B, c, (float(V.min()), float(V.max())), source)
    nan = math.nan
    err = LpvFitError(nan, nan, np.full((N_X, N_X), nan), np.full((N_X, N_U), nan), nan,
                      nrmse, int(len(V)))
    return model, err
