# Cython declarations for frames.py (written once, in frames.py): the per-tick attitude conversion's locals as C
# doubles, the same IEEE double operations in the same order as the Python module (docs/benchmarks.md, "Compiled
# tick").
import cython

cimport rotorlab._libm as math  # math.sin etc. of the .py as C calls of libm (rotorlab/_libm.pxd)

@cython.locals(r00=cython.double, r10=cython.double, r20=cython.double, r21=cython.double, r22=cython.double,
               pitch=cython.double, roll=cython.double, yaw=cython.double)
cpdef tuple euler_deg(double w, double x, double y, double z)
