# Cython declarations for px4.py (the law stays written once, in px4.py): the laws' classes as extension types
# and their per-tick locals as C doubles, so a compiled build runs each tick's arithmetic unboxed, the same IEEE
# double operations in the same order as the Python module (docs/benchmarks.md, "Compiled tick").
import cython

cimport rotorlab._libm as math  # math.sin etc. of the .py as C calls of libm (rotorlab/_libm.pxd)

cdef double _I_FACTOR_RAD_S
cdef double _NEAR_1

cdef class RateController:
    cdef public double dt
    cdef public list _gains
    cdef public tuple _gyro, _dterm
    cdef public double _yaw_alpha, _yaw_y
    cdef public list _g, _d, _w_prev
    cdef public object integral, rate_error

    @cython.locals(gb0=cython.double, gb1=cython.double, gb2=cython.double, ga1=cython.double, ga2=cython.double,
                   db0=cython.double, db1=cython.double, db2=cython.double, da1=cython.double, da2=cython.double,
                   dt=cython.double, i=cython.Py_ssize_t, r=cython.double, y=cython.double, kp=cython.double,
                   ki=cython.double, kd=cython.double, ff=cython.double, lim=cython.double, g=list, d=list,
                   g0=cython.double, g1=cython.double, x0=cython.double, w=cython.double, e=cython.double,
                   integ=cython.double, d0=cython.double, d1=cython.double, f=cython.double, nxt=cython.double,
                   out=list, w_prev=list)
    cpdef tuple step(self, rate_sp, rate, sat_pos=*, sat_neg=*, bint landed=*)


cdef class AttitudeController:
    cdef public double yaw_w
    cdef public tuple p, rate_limit

    @cython.locals(qw=cython.double, qx=cython.double, qy=cython.double, qz=cython.double,
                   dw=cython.double, dx=cython.double, dy=cython.double, dz=cython.double,
                   sx=cython.double, sy=cython.double, sz=cython.double, tx=cython.double, ty=cython.double,
                   tz=cython.double, cx=cython.double, cy=cython.double, cz=cython.double, dot=cython.double,
                   ox=cython.double, oy=cython.double, oz=cython.double, w=cython.double, x=cython.double,
                   y=cython.double, z=cython.double, n=cython.double, rw=cython.double, rx=cython.double,
                   ry=cython.double, rz=cython.double, mw=cython.double, mz=cython.double, c0=cython.double,
                   c3=cython.double, yw=cython.double, ew=cython.double, ez=cython.double, ex=cython.double,
                   ey=cython.double, p0=cython.double, p1=cython.double, p2=cython.double, r0=cython.double,
                   r1=cython.double, r2=cython.double, z0=cython.double, z1=cython.double, z2=cython.double,
                   l0=cython.double, l1=cython.double, l2=cython.double)
    cpdef tuple update(self, q, q_sp, double yawspeed_sp=*)
