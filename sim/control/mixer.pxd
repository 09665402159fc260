# Cython declarations for mixer.py (written once, in mixer.py): the mixer as an extension type and the per-tick
# mix in C doubles, the same IEEE double operations in the same order as the Python module (docs/benchmarks.md,
# "Compiled tick").
import cython

cdef class Mixer:
    cdef public object kind, positions_frd_m, spin_dirs, matrix, pinv
    cdef public double out_min, out_max
    cdef public tuple _rows

    @cython.locals(lo=cython.double, hi=cython.double, a=cython.double, b=cython.double, c=cython.double,
                   d=cython.double, v=cython.double, out=list)
    cpdef tuple mix(self, double collective, double roll, double pitch, double yaw, bint clip=*)
