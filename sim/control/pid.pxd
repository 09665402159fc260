# Cython declarations for pid.py (written once, in pid.py): the PID as an extension type with C double states and
# gains, the same IEEE double operations in the same order as the Python module (docs/benchmarks.md, "Compiled
# tick").
import cython

cdef class DiscretePID:
    cdef public double dt, u_min, u_max, kp, ki, kd, tf, b, c, _kidt, _kd_tf, _inv_tf, _aw_gain
    cdef public double xi, xd, u, u_unsat, _r, _y
    cdef public object antiwindup, _tt_user, gains
    cdef public long _aw

    @cython.locals(ud=cython.double, u=cython.double, hi=cython.double, lo=cython.double, us=cython.double,
                   e=cython.double, aw=cython.long)
    cpdef double step(self, double r, double y, double u_ff=*)
