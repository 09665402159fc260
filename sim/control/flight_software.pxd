# Cython declarations for flight_software.py (written once, in flight_software.py): the flight software as an
# extension type, so a tick reads its loops and settings from slots and its signal dicts as dicts; every value
# stays a Python object (the same code flies arrays of many simulations), so the arithmetic is the Python module's
# (docs/benchmarks.md, "Compiled tick"). ``mode`` stays in the instance dict: ``set_mode`` asks whether it is set.
import cython

cdef class FlightSoftware:
    cdef dict __dict__
    cdef public object dt, mixer, limits, u_limit_pct, yaw_u_limit_pct, n, attitude, sup_roll, sup_pitch, _mix
    cdef public object position_gains, position, altitude, open_loop_axes, reference, altitude_hold, excitation
    cdef public object plugins, attitude_by_plugin, _plugin_signals, _ref, _engage, _k, _latched, _last, _sig

    @cython.locals(refs=dict, latched=dict, last=dict)
    cpdef step_signals(self, t, dict sig)
