"""The fused measurement a model-based estimator receives from a redundant set (Wan2018 eq. 19).

FDI policy: which instances feed the model and with which weights. The set monitor
(:class:`gcs_monitor.fdi.monitor.RedundantSetMonitor`) decides who is faulty; this decides what
the estimator is told the quantity is (docs/papers-notes.md, "Slow drift and the MHE's
measurement fusion").
"""

from __future__ import annotations

from gcs_monitor.fdi.events import SetStatus
from gcs_monitor.fdi.isolation import consensus_residuals
from gcs_monitor.fdi.residuals import ResidualRms, RmsWindowParams
from gcs_monitor.fdi.voting import adaptive_weights


class MheMeasurementFusion:
    """The fused measurement of one redundant set that the air-data MHE receives (Wan2018 eq. 19).

    Wan2018 weights each healthy instance by ``1/J^2`` of its model residual.  The model is
    driven by this fused value, so for a fault slower than the wind-rate bound u_w (which the
    wind states absorb) the loop has positive feedback: the instance the model happens to follow
    gets the smallest J, the highest weight, and pulls the model further (a slow CAS drift then
    captures the model and the healthy instances are isolated instead).  Two changes close
    the loop on independent information:

    - J in the weights is ``max(J_model, J_consensus)``: with >= 3 healthy instances the
      residual against the set's median (:func:`consensus_residuals`) is independent of the
      model, so an instance departing from the others loses weight even if the model follows it;
      with fewer healthy instances only J_model is used (two instances cannot isolate each
      other; a fault fast enough to exceed u_w makes J_model of the faulty one rise first);
    - J is floored at ``floor_ratio * J_th`` (not at the sensor noise): healthy instances share
      the weight equally instead of by the noise of their fault-free residuals.

    With ``equal_pair`` (``[fdi.<set>] equal_pair_weights``; ours, off by default) the last two
    healthy instances get equal weights while both are below J_th (J floored at J_th; one
    above J_th still leaves the fusion, as eq. 19's set S says). Two instances cannot isolate
    each other through the consensus, and the model is driven by their fusion: for a fault the
    wind states absorb (a Table II non-return to zero of 0.1 x on one of the last two vanes),
    1/J^2 weights make the model follow whichever instance had the smaller J at the fault's
    onset, so either the faulty one or the healthy one is isolated, by chance. Equal weights
    keep the model at the pair's mean: such a fault is missed (the output carries half of it)
    instead of being isolated on the wrong instance; a fault faster than the wind bounds still
    raises the faulty instance's J first. docs/papers-notes.md ("The last two instances")
    gives the measured trade.

    Detection stays on the model residuals (eq. 17) in the set monitor; the fused value is what
    the instances judged healthy (not latched out, J_model <= J_th) agree on.
    """

    def __init__(self, n: int, threshold: float, n_eval: int, floor_ratio: float,
                 equal_pair: bool = False) -> None:
        self.threshold = threshold
        self.floor_ratio = floor_ratio
        self.floor = floor_ratio * threshold
        self.equal_pair = equal_pair
        self._rms = [ResidualRms(RmsWindowParams(rms_window_n=n_eval)) for _ in range(n)]
        self._j = [0.0] * n

    def set_threshold(self, threshold: float) -> None:
        """A new J_th (scheduled on the estimated turbulence); the floor follows it."""
        self.threshold = threshold
        self.floor = self.floor_ratio * threshold

    def step(self, measured: list[float], usable: list[bool], status: SetStatus
             ) -> tuple[float | None, tuple[float, ...]]:
        """Fused value (None when no instance is healthy) and the weights used."""
        healthy = [u and not f for u, f in zip(usable, status.faulty, strict=True)]
        n_healthy = sum(healthy)
        if n_healthy >= 3:
            _, r = consensus_residuals(measured, usable, healthy)
            for i, ri in enumerate(r):
                if ri == ri:
                    self._j[i] = self._rms[i].update(ri)
        else:
            self._j = [0.0] * len(measured)
        j_eff = [max(a, b) for a, b in zip(status.rms, self._j, strict=True)]
        floor = self.threshold if self.equal_pair and n_healthy == 2 else self.floor
        w = adaptive_weights(j_eff, healthy, self.threshold, floor)
        if not any(w):
            return None, tuple(w)
        return sum(wi * x for wi, x in zip(w, measured, strict=True) if wi), tuple(w)
