"""The one process pool of the evaluation: every campaign and experiment maps its runs with it.

Results come back in the order of the work list whatever ``jobs`` is, and every run draws its
random numbers from its own seeded generators (the scenario's seed), so the same command gives
the same tables with ``--jobs 1`` and ``--jobs 8``.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Sequence
from typing import TypeVar

from tqdm import tqdm

W = TypeVar("W")
R = TypeVar("R")


def _indexed(job: tuple[Callable[[W], R], int, W]) -> tuple[int, R]:
    fn, i, w = job
    return i, fn(w)


def run_parallel(fn: Callable[[W], R], work: Sequence[W], jobs: int, *, desc: str = "runs",
                 progress: bool = True) -> list[R]:
    """``[fn(w) for w in work]`` with ``jobs`` forked worker processes, in the order of ``work``.

    Parameters
    ----------
    fn : a module-level function (the workers receive it by reference)
    work : one picklable item per run
    jobs : worker processes; 1 (or a single item) runs in this process
    desc : label of the progress bar
    progress : show a tqdm progress bar on stderr (one tick per finished run)
    """
    bar = tqdm(total=len(work), unit="run", desc=desc) if progress else None
    done: dict[int, R] = {}
    try:
        if jobs <= 1 or len(work) <= 1:
            for i, w in enumerate(work):
                done[i] = fn(w)
                if bar is not None:
                    bar.update(1)
        else:
            # fork: the workers share the modules the parent imported (the evaluation modules
            # import the simulator and the estimators at their top), so a campaign runs one
            # version of the code even if files change while it runs
            os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
            ctx = multiprocessing.get_context("fork")
            with ctx.Pool(jobs) as pool:
                for i, r in pool.imap_unordered(_indexed, [(fn, i, w) for i, w in enumerate(work)]):
                    done[i] = r
                    if bar is not None:
                        bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return [done[i] for i in range(len(work))]
