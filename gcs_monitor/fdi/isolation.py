"""Fault isolation within a redundant set: which reference each instance's residual uses.

With a model reference (Wan2018 eq. 17) every instance is compared with the same
independent prediction, ``r_i = y_i - y_hat``, and any number of faulty instances can be
isolated, including all of them.

Without a reference the only information is the set itself, and only the *differences*
between instances are observable: faults ``f_1 = f_2 = d`` on two of three sensors produce
exactly the same measurements as ``f_3 = -d`` on the third sensor plus a common signal
change ``d``.  No algorithm, weighted or voted, with or without memory, can tell these two
hypotheses apart from the measurements alone; memory of past weights only re-amplifies the
asymmetry already present in the data (with equal prior weights the weighted consensus is
pulled towards a drifting pair exactly as the median is).  What the set can do is
documented here and in the tests (tests/gcs_monitor/fdi/test_monitor.py):

consensus rule (no reference), over the instances still healthy (valid, not latched out):

- >= 3 healthy: ``r_i = y_i - median(healthy)`` for every usable instance (latched-out
  instances too, for display and classification).  Robust to any single fault, and to
  two faults on opposite sides of the good instance (the median stays on the good one).
- 2 healthy: ``r_i = y_i - y_j`` for both.  A disagreement is detected but cannot be
  isolated; both instances reach the threshold together and both are declared faulty, so
  the set is lost (SET_LOST) rather than keeping a possibly wrong value.
- 1 healthy: no residual (nothing to compare with); its J is held, the set runs unmonitored
  and its configuration label says ``fused 1/n``.

Consequences for a triplex set without a reference (all latched, as Wan2018):

- single fault: detected and isolated;
- two faults on opposite sides: both isolated, the good instance keeps the output;
- two faults on the same side, one confirmed before the other starts: the first is
  isolated, the second is detected as a last-two disagreement: SET_LOST, no faulty value
  is output (majority voting without latching instead excludes the good sensor);
- two simultaneous same-side faults of magnitudes a > b: isolated correctly only while
  ``a > 2 b`` (then as above); otherwise the good sensor is isolated first (false isolation)
  and the set is lost once the faulty pair diverges; if ``a == b`` (common-mode fault such
  as icing of two vanes) the fault is undetectable and the output follows the pair;
- three faults: detected only as growing disagreement, never isolated.

A model reference (an estimator's one-step prediction, Wan2018 eq. 17) removes all of
these limits, which is the point of Wan2018.
"""

from __future__ import annotations

import math

from gcs_monitor.fdi.voting import median_of


def consensus_residuals(
    values: list[float], usable: list[bool], healthy: list[bool]
) -> tuple[float, list[float]]:
    """Residuals of each instance against the consensus of the healthy ones (rule above).

    Parameters
    ----------
    values : (n,) measurements, SI
    usable : (n,) valid and finite this sample
    healthy : (n,) usable and not declared faulty

    Returns
    -------
    consensus : median of the healthy instances (NaN if none), SI
    residuals : (n,) residual per instance, NaN where none can be formed
    """
    n = len(values)
    h = [values[i] for i in range(n) if healthy[i]]
    nh = len(h)
    nan = math.nan
    if nh >= 3:
        c = median_of(h)
        return c, [values[i] - c if usable[i] else nan for i in range(n)]
    if nh == 2:
        c = 0.5 * (h[0] + h[1])
        d = h[0] - h[1]
        out = [nan] * n
        first = True
        for i in range(n):
            if healthy[i]:
                out[i] = d if first else -d
                first = False
            elif usable[i]:
                out[i] = values[i] - c
        return c, out
    if nh == 1:
        c = h[0]
        return c, [values[i] - c if usable[i] and not healthy[i] else nan for i in range(n)]
    return nan, [nan] * n
