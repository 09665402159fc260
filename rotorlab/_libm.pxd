# The C math library under the names of Python's math module, for the compiled per-tick modules: a module's .pxd
# that says `cimport rotorlab._libm as math` turns the `math.sin(x)` of its .py into a C call of the very libm
# function CPython's math.sin calls (the same double, bit for bit), without the Python call, the boxing and the
# attribute lookup. Cython maps no function of Python's math module to C by itself. Only the names the compiled
# modules use are here; a module that needs another adds it (a missing name fails the build, never the run).
# The one difference: where Python's math raises ValueError on a domain error (cos(inf), acos(1.5)) the C function
# returns NaN; the laws clamp their arguments, and a NaN state stops a run (Simulator.check) either way.
from libc.math cimport acos, asin, atan2, cos, isfinite, sin, sqrt, tan
from libc.math cimport INFINITY as inf
from libc.math cimport M_PI as pi


# CPython's math.radians multiplies by this very constant (Modules/mathmodule.c: degToRad = Py_MATH_PI / 180.0; the
# C compiler folds the quotient to the same double)
cdef inline double radians(double x) noexcept nogil:
    return x * (pi / 180.0)
