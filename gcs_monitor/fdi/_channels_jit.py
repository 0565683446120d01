"""Numba kernel of :class:`~gcs_monitor.fdi.monitor.ChannelBank`: the per-sample RMS window
(Wan2018 eq. 18, ``residuals.ResidualRms``), history ring and n_D-of-N_eval confirmation
(``confirmation.Confirmation``) of several channels in one call.

Same arithmetic, same order as those classes, including the periodic exact re-summation, for
which :func:`fsum` reproduces ``math.fsum`` (Shewchuk's algorithm with CPython's correctly
rounded final sum); tests/gcs_monitor/fdi checks the bank against ChannelMonitor sample by
sample, to the bit. Alarm transitions and classification stay in Python. Loaded by
``fdi.monitor.ChannelBank`` through ``gcs_monitor.core.kernels``.

Why the classes stay as well: they are not a reference kept for a test but what runs every
redundant-set monitor (``RedundantSetMonitor``, Wan2018 eqs. 17-19 per triplex instance) and
every channel a bank does not take (different window lengths); this kernel is their batched
form for one estimator's fault channels. Routing the classes through it would cost a numba call
per channel sample where they now do a few float operations, and those classes belong to the
FDI layer's own modules (``fdi/residuals.py``, ``fdi/confirmation.py``).
"""
# mypy: disable-error-code="no-untyped-def"

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, fastmath=False, nogil=True)

# istate columns
RMS_IDX, RMS_COUNT, RMS_SINCE, CONF_IDX, CONF_EXCEED = 0, 1, 2, 3, 4
FAULTY, BELOW, LATCHED, HIST_IDX, HIST_COUNT = 5, 6, 7, 8, 9
N_ISTATE = 10
# flags returned per channel
UPDATED, WAS_FAULTY, IS_FAULTY, NON_FINITE = 1, 2, 4, 8


@jit
def fsum(x):
    """``math.fsum`` of a 1-D float array of finite values (CPython's msum + final rounding)."""
    partials = np.empty(x.shape[0] + 1)
    npart = 0
    for k in range(x.shape[0]):
        v = x[k]
        i = 0
        for j in range(npart):
            y = partials[j]
            if abs(v) < abs(y):
                v, y = y, v
            hi = v + y
            lo = y - (hi - v)
            if lo != 0.0:
                partials[i] = lo
                i += 1
            v = hi
        npart = i
        if v != 0.0:  # CPython keeps only non-zero partials
            partials[npart] = v
            npart += 1
    hi = 0.0
    if npart > 0:
        n = npart
        n -= 1
        hi = partials[n]
        lo = 0.0
        while n > 0:
            xx = hi
            n -= 1
            yy = partials[n]
            hi = xx + yy
            yr = hi - xx
            lo = yy - yr
            if lo != 0.0:
                break
        if n > 0 and ((lo < 0.0 and partials[n - 1] < 0.0) or (lo > 0.0 and partials[n - 1] > 0.0)):
            yy = lo * 2.0
            xx = hi + yy
            yr = xx - hi
            if yy == yr:
                hi = xx
    return hi


@jit
def bank_update(values, valid, threshold, recompute_n, detect_n, clear_ratio, clear_n, latch,
                rms_buf, rms_sum, J, hist, conf_win, istate, flags):
    """One sample of every channel; see the module docstring. ``flags`` (k,) gets UPDATED,
    WAS_FAULTY, IS_FAULTY bits, or NON_FINITE (the square overflowed: ResidualRms raises);
    returns the OR of all flags. Per-channel parameters are (k,) arrays."""
    k = values.shape[0]
    any_flags = 0
    n = rms_buf.shape[1]
    eval_n = conf_win.shape[1]
    hist_n = hist.shape[1]
    for c in range(k):
        v = values[c]
        if not (valid and v == v and abs(v) != math.inf):
            flags[c] = 0
            continue
        # ResidualRms.update
        sq = v * v
        if sq != sq or sq == math.inf:
            flags[c] = NON_FINITE
            any_flags |= NON_FINITE
            continue
        i = istate[c, RMS_IDX]
        rms_sum[c] += sq - rms_buf[c, i]
        rms_buf[c, i] = sq
        i += 1
        istate[c, RMS_IDX] = 0 if i == n else i
        if istate[c, RMS_COUNT] < n:
            istate[c, RMS_COUNT] += 1
        istate[c, RMS_SINCE] += 1
        if istate[c, RMS_SINCE] >= recompute_n:
            rms_sum[c] = fsum(rms_buf[c])
            istate[c, RMS_SINCE] = 0
        s = rms_sum[c]
        j = math.sqrt(s / n) if s > 0.0 else 0.0
        J[c] = j
        # _History.push (residual only)
        h = istate[c, HIST_IDX]
        hist[c, h] = v
        h += 1
        istate[c, HIST_IDX] = 0 if h == hist_n else h
        if istate[c, HIST_COUNT] < hist_n:
            istate[c, HIST_COUNT] += 1
        # Confirmation.update
        was = istate[c, FAULTY]
        th = threshold[c]
        exceeded = j > th
        w = istate[c, CONF_IDX]
        if (conf_win[c, w] != 0) != exceeded:
            istate[c, CONF_EXCEED] += 1 if exceeded else -1
            conf_win[c, w] = 1 if exceeded else 0
        w += 1
        istate[c, CONF_IDX] = 0 if w == eval_n else w
        if not istate[c, FAULTY]:
            if istate[c, CONF_EXCEED] >= detect_n[c]:
                istate[c, FAULTY] = 1
                istate[c, BELOW] = 0
                istate[c, LATCHED] = 1 if latch[c] else 0
        elif not istate[c, LATCHED]:
            if j < clear_ratio[c] * th:
                istate[c, BELOW] += 1
                if istate[c, BELOW] >= clear_n[c]:
                    istate[c, FAULTY] = 0
                    istate[c, BELOW] = 0
            else:
                istate[c, BELOW] = 0
        f = UPDATED
        if was:
            f |= WAS_FAULTY
        if istate[c, FAULTY]:
            f |= IS_FAULTY
        flags[c] = f
        any_flags |= f
    return any_flags
