"""The evaluation's process pool (gcs_monitor.evaluation.runner.run_parallel)."""

from __future__ import annotations

import os

import numpy as np

from gcs_monitor.evaluation.runner import run_parallel


def _draw(job: tuple[int, int]) -> tuple[int, float, int]:
    """A run: its own seeded generator, its index and the process that ran it."""
    index, seed = job
    return index, float(np.random.default_rng(seed).normal()), os.getpid()


def test_results_in_work_order_and_independent_of_jobs() -> None:
    work = [(i, 100 + i) for i in range(7)]
    one = run_parallel(_draw, work, 1, progress=False)
    two = run_parallel(_draw, work, 2, progress=False)
    assert [r[:2] for r in one] == [r[:2] for r in two]
    assert [r[0] for r in two] == list(range(7))
    assert {r[2] for r in one} == {os.getpid()}  # jobs=1 runs in this process
    assert os.getpid() not in {r[2] for r in two}  # jobs=2 in forked workers
    assert run_parallel(_draw, [], 2, progress=False) == []
