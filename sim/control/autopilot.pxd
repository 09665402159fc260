# Cython declarations for autopilot.py (written once, in autopilot.py): the plug-in as an extension type and the
# per-tick conversions as C doubles, the same IEEE double operations in the same order as the Python module
# (docs/benchmarks.md, "Compiled tick").
import cython

cimport rotorlab._libm as math  # math.sin etc. of the .py as C calls of libm (rotorlab/_libm.pxd)

cdef double _D2R

@cython.locals(h=cython.double, t=cython.double, y=cython.double, cr=cython.double, sr=cython.double,
               cp=cython.double, sp=cython.double, cy=cython.double, sy=cython.double)
cpdef tuple euler_to_quat(double phi_rad, double theta_rad, double psi_rad)


cdef class AutopilotController:
    cdef public object spec, ap, rate, att, _rate_step, _att_update, rate_reference, rate_excitation, outputs
    cdef public double dt
    cdef public tuple limits, _sat_pos, _sat_neg
    cdef public bint _px4, add_commands

    @cython.locals(tq0=cython.double, tq1=cython.double, tq2=cython.double, u0=cython.double, u1=cython.double,
                   u2=cython.double, l0=cython.double, l1=cython.double, l2=cython.double, r0=cython.double,
                   r1=cython.double, r2=cython.double)
    cpdef tuple fly(self, double t, double phi, double theta, double psi, double phi_ref, double theta_ref,
                    double psi_ref, double p, double q, double r, double u_lat=*, double u_lon=*, double u_yaw=*)
