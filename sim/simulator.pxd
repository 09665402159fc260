# Cython declarations for simulator.py (written once, in simulator.py): the simulator as an extension type whose
# state a tick reads (MuJoCo's model and data, the buffers' memoryviews, the IMU, the rotor slots) sits in slots;
# every value stays a Python object, so the tick does what the Python module does (docs/benchmarks.md, "Compiled
# tick"). Everything else stays in the instance dict.
cdef class Simulator:
    cdef dict __dict__
    cdef public object model, data, disturbances, _opt, n_substeps, _forces_at_tick, _force_sensors, _update_stage
    cdef public object _xfrc_v, wind_world, _rotates_air, air_rate_world, _air_map, _wind_v, _ctrl_v, aero_ids
    cdef public object _warn_mv, _warn_counts, _warn_ids, stops, _qpos_mv, _af_xmat_mv, _af_xpos_mv, _af_xquat_mv
    cdef public object imu, _sd_mv, _noise, sensor_noise, _free, _pos_mv, _vel_mv, _omega_mv, _gyro_scale, _airframe
    cdef public object _n_thrust, rotor_pct, _ctrl_mv, _rotor_slots, vehicle, _ctrl_scratch
