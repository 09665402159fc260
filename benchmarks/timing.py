"""Timing helper the benchmark scripts share (imported as a sibling module: the scripts run as
``python benchmarks/NAME.py``, which puts this folder on the import path)."""

import time

import numpy as np


def best_wall_s(fn, repeat: int = 1):
    """Best wall time of ``repeat`` calls of ``fn`` (s) and the last call's result: the minimum is the run the
    shared machine disturbed least."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out
