# Cython declarations for ardupilot.py (the law stays written once, in ardupilot.py): the laws' classes as
# extension types and their per-tick locals as C doubles, the same IEEE double operations in the same order as the
# Python module (docs/benchmarks.md, "Compiled tick").
import cython

cimport rotorlab._libm as math  # math.sin etc. of the .py as C calls of libm (rotorlab/_libm.pxd)

cdef class RateController:
    cdef public double dt
    cdef public list _axes, _g
    cdef public tuple _gyro
    cdef public object target, error, derivative, integral
    cdef public bint _reset_filter

    @cython.locals(gb0=cython.double, gb1=cython.double, gb2=cython.double, ga1=cython.double, ga2=cython.double,
                   dt=cython.double, first=cython.bint, i=cython.Py_ssize_t, r=cython.double, gyro=cython.double,
                   kp=cython.double, ki=cython.double, kd=cython.double, ff=cython.double, imax=cython.double,
                   a_t=cython.double, a_e=cython.double, a_d=cython.double, g=list, g0=cython.double,
                   g1=cython.double, x0=cython.double, y=cython.double, t=cython.double, e=cython.double,
                   d=cython.double, e_last=cython.double, integ=cython.double, out=list)
    cpdef tuple step(self, rate_sp, rate, limit=*)


cdef class AttitudeController:
    cdef public tuple p, rate_limit

    @cython.locals(w1=cython.double, x1=cython.double, y1=cython.double, z1=cython.double, w2=cython.double,
                   x2=cython.double, y2=cython.double, z2=cython.double, w=cython.double, v0=cython.double,
                   v1=cython.double, v2=cython.double, s=cython.double, k=cython.double, p0=cython.double,
                   p1=cython.double, p2=cython.double, l0=cython.double, l1=cython.double, l2=cython.double,
                   r0=cython.double, r1=cython.double, r2=cython.double)
    cpdef tuple update(self, q, q_sp)
