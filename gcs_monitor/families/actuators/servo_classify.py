"""Which of Lu2017's five actuator faults a detected servo fault is (Lu2017 secs. IV.A, V.A).

Input to :func:`classify_servo`: the recent history of one surface's filters (oldest first,
from the onset of the detection on), output: the case, input or output fault, the alarm's fault
type and magnitude, and the numbers an operator needs (frequency and amplitude of an
oscillation, stuck position, runaway rate, rod-sensor bias).

The tests, in this order (each threshold a documented parameter of
:class:`ServoClassifierConfig`; sigma_rod is the rod sensor noise):

1. **liquid jam** (a bias of the rod sensor while the surface is still under control, Lu2017
   sec. V.A): the rod and surface sensors disagree -- ``d = f_rod - f_surf`` of the RTS-EKF,
   i.e. rod minus surface position in m of rod -- by more than ``disagreement_m`` on average
   over the recent window. Magnitude: that mean (the rod sensor's bias, m). The servo closes
   its loop on the biased sensor, so the surface sits the bias off its command.
2. **solid jam / runaway at the stop**: the measured rod does not move over the recent window
   (detrended spread below ``stuck_sigmas`` sigma_rod and drift below the same) while it is
   away from the nominal servo. At a mechanical stop (within ``stop_margin_m``) it is a
   runaway that ended there (Lu2017 sec. V.A: "persists until the moving surface stops";
   magnitude: the steepest rod rate of the history, m/s); elsewhere a solid jam (magnitude:
   the stuck rod position, m).
3. **runaway in progress**: over the newest ``ramp_s`` the measured rod moves along a line
   (fit R^2 >= ``ramp_r2``) faster than ``runaway_rate_mps``, away from the nominal servo (the
   deviation has the sign of the motion). Magnitude: the rod rate (m/s).
4. **oscillatory failure case**: the input-fault estimate ``f^i`` or the valve command it
   implies, ``u = u_NDI(x_hat) + f^i``, has a dominant spectral line (Lu2017 sec. IV.A: a
   spurious sinusoid in the servo loop) holding more than ``osc_power_fraction`` of its
   detrended variance over at least ``osc_min_cycles`` periods. A liquid OFC *adds* a
   zero-mean sinusoid to the valve command, so ``f^i`` is that sinusoid and ``u`` carries the
   loop's action besides -- and the rod still follows its command; a solid OFC *replaces* the
   command, so ``u`` is the zero-mean sinusoid, ``f^i = u - u_NDI`` carries the loop's
   (ignored) action, and the rod no longer follows. When the command moved in the window (the
   nominal servo's spread above ``command_motion_sigmas`` sensor sigmas) the rod is regressed
   on the nominal servo and the sinusoid: a coefficient below 1/2 is a solid OFC. Without
   command motion a sinusoid without offset is fitted to ``f^i`` and to ``u``, and the one it
   explains better names the case (solid when the valve command's relative residual is below
   ``solid_fit_ratio`` times the fault estimate's; with the loop at rest the two read alike and
   the liquid case is kept). Magnitude: the amplitude (valve units) of the named signal's fit
   -- of a solid OFC found by the regression, the rod's oscillation amplitude converted through
   the bypassed loop, ``2 pi f a_rod / v_max`` (the rod integrates the valve flow; the
   hydraulic mode at ~9 Hz adds ~1/(1 - (f/9 Hz)^2), 12 % at 3 Hz) -- with the frequency; an
   amplitude below ``osc_min_amplitude`` is not named.
5. otherwise **unknown**, on the axis (input or output) whose detector is further above its
   threshold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_monitor.core.params import param
from gcs_monitor.fdi.events import FaultType

CASES = ("liquid_ofc", "solid_ofc", "liquid_jam", "solid_jam", "runaway")
CASE_LABELS = {"liquid_ofc": "liquid OFC", "solid_ofc": "solid OFC", "liquid_jam": "liquid jam",
               "solid_jam": "solid jam", "runaway": "runaway", "unknown": "actuator fault"}
INPUT_CASES = frozenset({"liquid_ofc", "solid_ofc"})
FAULT_TYPES = {"liquid_ofc": FaultType.OSCILLATION, "solid_ofc": FaultType.OSCILLATION,
               "liquid_jam": FaultType.BIAS, "solid_jam": FaultType.STUCK,
               "runaway": FaultType.RUNAWAY, "unknown": FaultType.UNKNOWN}


@dataclass(frozen=True, slots=True)
class ServoClassifierConfig:
    """Shape tests of the servo fault classes (ours; Lu2017 defines the classes, not tests)."""

    recent_s: float = param(0.3, "recent window of the jam, stop and ramp tests", positive=True)
    disagreement_m: float = param(2.0e-3, "rod minus surface position (m of rod) above which "
                                  "the rod sensor is biased (liquid jam)", positive=True)
    stuck_sigmas: float = param(4.0, "a rod whose detrended spread and drift over the recent "
                                "window stay below this many rod-sensor sigmas is not moving",
                                positive=True)
    deviation_m: float = param(2.0e-3, "smallest deviation from the nominal servo (m of rod) "
                               "of a jam or a runaway", positive=True)
    stop_margin_m: float = param(2.0e-3, "a rod within this of its stroke is at a mechanical "
                                 "stop", positive=True)
    runaway_rate_mps: float = param(0.2, "deviation rate above which a ramp is a runaway (the "
                                    "Lu2017 servo's full-valve rod rate is ~1 m/s)",
                                    positive=True)
    ramp_r2: float = param(0.9, "coefficient of determination of the ramp fit", positive=True)
    ramp_s: float = param(0.1, "window of the runaway-in-progress test (the newest samples: a "
                          "runaway at the full-valve rate crosses the stroke in ~0.3 s)",
                          positive=True)
    osc_power_fraction: float = param(0.5, "share of the detrended variance the strongest "
                                      "frequency must carry", positive=True)
    osc_min_cycles: float = param(2.0, "periods an oscillation must show since the detection's "
                                  "onset", positive=True)
    osc_min_amplitude: float = param(0.01, "smallest OFC amplitude worth naming (valve units)",
                                     positive=True)
    command_motion_sigmas: float = param(10.0, "the nominal servo must move this many rod-sensor "
                                         "sigmas (std) in the window for the liquid/solid test "
                                         "on the command", positive=True)
    solid_fit_ratio: float = param(0.5, "without command motion: a solid OFC when the valve "
                                   "command's sinusoid fit residual is below this fraction of "
                                   "the fault estimate's", positive=True)


@dataclass(frozen=True, slots=True)
class ServoWindow:
    """One surface's filter history (oldest first) from the onset of a detection on.

    Attributes
    ----------
    dt_s : sample period (s, measured)
    f_in : (N,) IOTSEKF input-fault estimate (valve units)
    u : (N,) valve command it implies, ``u_NDI(x_hat) + f^i``
    y_rod : (N,) rod position sensor (m)
    f_rod, f_surf : (N,) RTS-EKF output faults of the rod and surface sensors (m of rod)
    x_nom : (N,) the nominal servo's rod position (the RTS-EKF's state: the response to the
        command)
    valve_rate_mps : rod rate per unit valve command at no load (``phi_n / A_p``)
    stroke_m : rod stroke (m)
    rod_sigma_m : rod sensor noise (m)
    """

    dt_s: float
    f_in: np.ndarray
    u: np.ndarray
    y_rod: np.ndarray
    f_rod: np.ndarray
    f_surf: np.ndarray
    x_nom: np.ndarray
    stroke_m: float
    rod_sigma_m: float
    valve_rate_mps: float = 1.0


@dataclass(frozen=True, slots=True)
class ServoClass:
    """A classification: the case, ``input`` or ``output``, the alarm's fault type and
    magnitude (SI: valve units, m or m/s), the case's numbers (NaN where they do not apply) and
    the operator's message (without the surface name)."""

    case: str
    axis: str
    fault_type: FaultType
    magnitude: float
    message: str
    frequency_hz: float = math.nan
    amplitude: float = math.nan
    position_m: float = math.nan
    rate_mps: float = math.nan


def _line(t: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """Least-squares line ``v ~ a + b t``: (slope b, residual std, R^2)."""
    tm = t - t.mean()
    vm = v - v.mean()
    stt = float(tm @ tm)
    if stt <= 0.0:
        return 0.0, float(np.std(v)), 0.0
    b = float(tm @ vm) / stt
    e = vm - b * tm
    svv = float(vm @ vm)
    sse = float(e @ e)
    return b, math.sqrt(sse / v.size), (1.0 - sse / svv) if svv > 0.0 else 0.0


def _sine_fit(t: np.ndarray, v: np.ndarray, f_hz: float) -> tuple[float, float]:
    """Least squares ``v ~ c sin + d cos`` at ``f_hz`` (no offset: an OFC is a zero-mean
    sinusoid): (amplitude, relative residual ``SSE / sum(v^2)``)."""
    w = 2.0 * math.pi * f_hz
    A = np.column_stack([np.sin(w * t), np.cos(w * t)])
    coef, *_ = np.linalg.lstsq(A, v, rcond=None)
    e = v - A @ coef
    svv = float(v @ v)
    return math.hypot(coef[0], coef[1]), (float(e @ e) / svv) if svv > 0.0 else 1.0


def dominant_frequency(v: np.ndarray, dt_s: float) -> tuple[float, float, float]:
    """(frequency Hz, share of the detrended variance in the strongest line and its stronger
    neighbour, cycles in the window) of ``v``; the peak refined by a parabola through the log
    spectrum (zero padding x4)."""
    n = v.size
    t = np.arange(n) * dt_s
    slope, icpt = np.polyfit(t, v, 1)
    e = v - (icpt + slope * t)
    var = float(e @ e) / n
    if var <= 0.0 or n < 8:
        return math.nan, 0.0, 0.0
    spec = np.abs(np.fft.rfft(e)) ** 2
    spec[0] = 0.0
    k = int(np.argmax(spec))
    frac = 2.0 * float(spec[k]) / (n * n) / var
    if 0 < k < spec.size - 1:
        frac += 2.0 * float(max(spec[k - 1], spec[k + 1])) / (n * n) / var
    pad = np.abs(np.fft.rfft(e, 4 * n)) ** 2
    pad[0] = 0.0
    j = int(np.argmax(pad))
    jj = float(j)
    if 0 < j < pad.size - 1 and min(pad[j - 1], pad[j], pad[j + 1]) > 0.0:
        a, b, c = math.log(pad[j - 1]), math.log(pad[j]), math.log(pad[j + 1])
        den = a - 2.0 * b + c
        if den < 0.0:
            jj += 0.5 * (a - c) / den
    f = jj / (4 * n * dt_s)
    return f, frac, k * 1.0


def classify_servo(w: ServoWindow, cfg: ServoClassifierConfig, *, input_ratio: float,
                   output_ratio: float) -> ServoClass:
    """Classify one surface's detected fault (module docstring).

    ``input_ratio`` and ``output_ratio`` are the detectors' residual RMS over their thresholds
    (they pick the axis of an unknown fault).
    """
    n = w.f_in.size
    t = np.arange(n) * w.dt_s
    nr = max(4, min(n, round(cfg.recent_s / w.dt_s)))
    tr, y = t[-nr:], w.y_rod[-nr:]
    d = w.f_rod[-nr:] - w.f_surf[-nr:]
    d_mean = float(np.mean(d))
    # 1. liquid jam: the rod sensor disagrees with the surface sensor
    if abs(d_mean) > cfg.disagreement_m:
        return ServoClass("liquid_jam", "output", FaultType.BIAS, d_mean,
                          f"liquid jam: rod sensor bias {d_mean * 1e3:+.1f} mm",
                          position_m=d_mean)
    dev = float(np.mean(w.f_rod[-nr:]))
    slope_y, spread_y, _ = _line(tr, y)
    still = cfg.stuck_sigmas * w.rod_sigma_m
    # 2. the rod does not move while the nominal servo is elsewhere
    drift = abs(slope_y) * (tr[-1] - tr[0])
    if abs(dev) > cfg.deviation_m and spread_y < still and drift < still:
        pos = float(np.mean(y))
        if abs(pos) >= w.stroke_m - cfg.stop_margin_m:
            rate = _steepest_rate(t, w.y_rod, nr)
            return ServoClass("runaway", "output", FaultType.RUNAWAY, rate,
                              f"runaway to the {'+' if pos > 0 else '-'} stop "
                              f"({pos * 1e3:+.0f} mm), rod rate {rate:+.2f} m/s",
                              position_m=pos, rate_mps=rate)
        return ServoClass("solid_jam", "output", FaultType.STUCK, pos,
                          f"solid jam: rod stuck at {pos * 1e3:+.1f} mm", position_m=pos)
    # 3. runaway in progress: the rod itself moves fast along a line, away from the nominal
    nf = max(4, min(n, round(cfg.ramp_s / w.dt_s)))
    rate, _, r2 = _line(t[-nf:], w.y_rod[-nf:])
    dev_f = float(w.f_rod[-1])
    if abs(rate) >= cfg.runaway_rate_mps and r2 >= cfg.ramp_r2 and \
            abs(dev_f) > cfg.deviation_m and rate * dev_f > 0.0:
        return ServoClass("runaway", "output", FaultType.RUNAWAY, rate,
                          f"runaway: rod rate {rate:+.2f} m/s", rate_mps=rate,
                          position_m=float(w.y_rod[-1]))
    # 4. oscillatory failure case: a dominant line in f^i or in the valve command
    f_hz, frac, _ = dominant_frequency(w.f_in, w.dt_s)
    f_u, frac_u, _ = dominant_frequency(w.u, w.dt_s)
    if frac_u > frac:
        f_hz, frac = f_u, frac_u
    if math.isfinite(f_hz) and frac > cfg.osc_power_fraction and \
            f_hz * t[-1] >= cfg.osc_min_cycles:
        amp_f, res_f = _sine_fit(t, w.f_in, f_hz)
        amp_u, res_u = _sine_fit(t, w.u, f_hz)
        fit = _follows_command(t, w.y_rod, w.x_nom, f_hz, cfg.command_motion_sigmas
                               * w.rod_sigma_m)
        if fit is not None:
            follows, rod_amp = fit
            solid = not follows
            # the loop bypassed, the rod integrates the valve flow: A = 2 pi f a_rod / v_max
            if solid:
                amp_u = 2.0 * math.pi * f_hz * rod_amp / w.valve_rate_mps
        else:
            solid = res_u < cfg.solid_fit_ratio * res_f
        amp = amp_u if solid else amp_f
        if amp >= cfg.osc_min_amplitude:
            case = "solid_ofc" if solid else "liquid_ofc"
            return ServoClass(case, "input", FaultType.OSCILLATION, amp,
                              f"{CASE_LABELS[case]}: {f_hz:.2f} Hz, amplitude {amp:.3f} (valve)",
                              frequency_hz=f_hz, amplitude=amp)
    # 5. unknown
    if input_ratio >= output_ratio:
        mag = float(np.sqrt(np.mean(w.f_in[-nr:] ** 2)))
        return ServoClass("unknown", "input", FaultType.UNKNOWN, mag,
                          f"input fault {mag:.3f} (valve), class pending")
    return ServoClass("unknown", "output", FaultType.UNKNOWN, dev,
                      f"output fault {dev * 1e3:+.1f} mm off the nominal servo, class pending")


def _follows_command(t: np.ndarray, y: np.ndarray, x_nom: np.ndarray, f_hz: float,
                     min_motion_m: float) -> tuple[bool, float] | None:
    """Does the rod still follow its command under an oscillation? The least-squares fit
    ``y ~ a + b x_nom + c sin + d cos`` at the oscillation's frequency: ``b`` near 1 when the
    oscillation adds to the loop (liquid), near 0 when it replaced the command (solid); with
    the rod's oscillation amplitude ``hypot(c, d)``. None when the nominal servo moved too
    little for ``b`` to say (its spread below ``min_motion_m``)."""
    if float(np.std(x_nom)) < min_motion_m:
        return None
    w = 2.0 * math.pi * f_hz
    A = np.column_stack([np.ones_like(t), x_nom, np.sin(w * t), np.cos(w * t)])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return bool(coef[1] > 0.5), math.hypot(coef[2], coef[3])


def _steepest_rate(t: np.ndarray, y: np.ndarray, nr: int) -> float:
    """The steepest rod rate (m/s, signed) of the history: the largest |slope| of line fits
    over windows of ``max(4, nr // 3)`` samples."""
    k = max(4, nr // 3)
    best = 0.0
    for i in range(0, max(1, y.size - k + 1)):
        s, _, _ = _line(t[i:i + k], y[i:i + k])
        if abs(s) > abs(best):
            best = s
    return best
