# Cython declarations for runner.py (written once, in runner.py): the tick loop's signal dict and truth columns in C
# types, the same IEEE double operations in the same order as the Python module (docs/benchmarks.md, "Compiled
# tick").
import cython

@cython.locals(dt=cython.double, p_prev=cython.double, q_prev=cython.double, t=cython.double,
               p_true=cython.double, q_true=cython.double, sig=dict)
cpdef _loop(sim, fs, log, n_ticks, setup, progress, poses=*)
