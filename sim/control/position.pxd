# Cython declarations for position.py (written once, in position.py): the outer loops as extension types and
# their per-tick locals as C doubles, the same IEEE double operations in the same order as the Python module
# (docs/benchmarks.md, "Compiled tick").
import cython

cimport rotorlab._libm as math  # math.sin etc. of the .py as C calls of libm (rotorlab/_libm.pxd)

cdef double _DEG

cdef class PositionHold:
    cdef public object gains, vx, vy

    @cython.locals(kp=cython.double, vmax=cython.double, tilt_max=cython.double, v=cython.double,
                   vx_ref=cython.double, vy_ref=cython.double, ax=cython.double, ay=cython.double,
                   psi=cython.double, c=cython.double, s=cython.double, a_fwd=cython.double, a_right=cython.double,
                   theta_ref=cython.double, phi_ref=cython.double)
    cpdef tuple step(self, double x_ref, double y_ref, double x, double y, double vx, double vy, double psi_deg)


cdef class AltitudeHold:
    cdef public object gains, vz

    @cython.locals(v=cython.double, vmax=cython.double, vh_ref=cython.double, a_up=cython.double,
                   tilt=cython.double)
    cpdef double step(self, double h_ref, double h, double vh, double phi_deg, double theta_deg)
