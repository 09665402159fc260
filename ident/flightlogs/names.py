"""The one table of autopilot topic and field names the flight-log readers (and the twin's writers) use.

Each :class:`NameRow` says where one signal of one axis lives in one autopilot's log, for which software
versions, in which unit, and how to bring it to the project's convention (SI: rad, rad/s, s; the rate-loop
output stays normalised, unit ``"1"``, as the autopilot mixes it). Rows are tried in the order given; the first
whose topic and fields are in the log wins, so newer layouts come first. ``tests/test_flightlogs.py`` writes a
log for every row and reads the signal back through it.

Sources (facts, not code): PX4 uORB message definitions (``msg/*.msg``, PX4-Autopilot; ``actuator_controls``
was replaced by ``vehicle_torque_setpoint``/``vehicle_thrust_setpoint`` in v1.14, ``vehicle_angular_velocity``
arrived in v1.11 next to ``sensor_combined``'s ``gyro_rad``; 2017 logs carry the raw ``sensor_gyro``);
ArduPilot's log-message definitions (``ArduCopter/Log.cpp``, ``libraries/AC_AttitudeControl``: ``RATE``
``RDes/R/ROut`` in deg/s, deg/s and the normalised output since Copter 3.4, ``ATT`` ``DesRoll/Roll`` in deg).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["NameRow", "SIGNALS", "AXES", "PX4_ROWS", "ARDUPILOT_ROWS", "rows_for", "SIGNAL_UNITS",
           "PX4_AUTOTUNE_STATES", "PX4_AUTOTUNE_NEW_LAYOUT", "ARDUPILOT_SID_AXES", "ARDUCOPTER_MODES", "PX4_NAV_STATES"]

AXES = ("roll", "pitch", "yaw")
SIGNALS = ("rate_sp", "rate", "rate_out", "att", "att_sp")
# the project's units for each signal after conversion
SIGNAL_UNITS = {"rate_sp": "rad/s", "rate": "rad/s", "rate_out": "1", "att": "rad", "att_sp": "rad"}

DEG = math.pi / 180.0


@dataclass(frozen=True)
class NameRow:
    """Where one signal of the three axes lives in one log layout.

    Attributes
    ----------
    autopilot : {"px4", "ardupilot"}
    signal : str
        One of :data:`SIGNALS`.
    topic : str
        uORB topic (PX4) or DataFlash message name (ArduPilot).
    fields : tuple of str
        Field per axis (roll, pitch, yaw); for ``"quaternion"`` rows the four quaternion fields w, x, y, z.
    unit : str
        Unit in the log.
    scale : float
        Multiplier to the project's unit (:data:`SIGNAL_UNITS`).
    versions : str
        Software versions that log it, for the reader's message and the docs.
    kind : {"axes", "quaternion"}
        ``"quaternion"``: the attitude as a unit quaternion, converted to roll/pitch/yaw (ZYX Euler angles).
    """

    autopilot: str
    signal: str
    topic: str
    fields: tuple[str, ...]
    unit: str
    scale: float
    versions: str
    kind: str = "axes"


PX4_ROWS: tuple[NameRow, ...] = (
    NameRow("px4", "rate_sp", "vehicle_rates_setpoint", ("roll", "pitch", "yaw"), "rad/s", 1.0, "all"),
    NameRow("px4", "rate", "vehicle_angular_velocity", ("xyz[0]", "xyz[1]", "xyz[2]"), "rad/s", 1.0, ">= v1.11"),
    NameRow("px4", "rate", "sensor_combined", ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"), "rad/s", 1.0,
            "v1.5 - current"),
    NameRow("px4", "rate", "sensor_gyro", ("x", "y", "z"), "rad/s", 1.0, "2017 (raw gyro, sensor frame)"),
    NameRow("px4", "rate", "vehicle_attitude", ("rollspeed", "pitchspeed", "yawspeed"), "rad/s", 1.0, "< v1.9"),
    NameRow("px4", "rate_out", "vehicle_torque_setpoint", ("xyz[0]", "xyz[1]", "xyz[2]"), "1", 1.0, ">= v1.14"),
    NameRow("px4", "rate_out", "actuator_controls_0", ("control[0]", "control[1]", "control[2]"), "1", 1.0,
            "< v1.14"),
    NameRow("px4", "att", "vehicle_attitude", ("q[0]", "q[1]", "q[2]", "q[3]"), "1", 1.0, ">= v1.5",
            "quaternion"),
    NameRow("px4", "att", "vehicle_attitude", ("roll", "pitch", "yaw"), "rad", 1.0, "< v1.5"),
    NameRow("px4", "att_sp", "vehicle_attitude_setpoint", ("q_d[0]", "q_d[1]", "q_d[2]", "q_d[3]"), "1", 1.0,
            ">= v1.10", "quaternion"),
    NameRow("px4", "att_sp", "vehicle_attitude_setpoint", ("roll_body", "pitch_body", "yaw_body"), "rad", 1.0,
            "< v1.10"),
)

ARDUPILOT_ROWS: tuple[NameRow, ...] = (
    NameRow("ardupilot", "rate_sp", "RATE", ("RDes", "PDes", "YDes"), "deg/s", DEG, "Copter >= 3.4"),
    NameRow("ardupilot", "rate_sp", "RATE", ("RllDes", "PitDes", "YawDes"), "deg/s", DEG, "Copter 3.2 - 3.3"),
    NameRow("ardupilot", "rate", "RATE", ("R", "P", "Y"), "deg/s", DEG, "Copter >= 3.4"),
    NameRow("ardupilot", "rate", "RATE", ("Rll", "Pit", "Yaw"), "deg/s", DEG, "Copter 3.2 - 3.3"),
    NameRow("ardupilot", "rate_out", "RATE", ("ROut", "POut", "YOut"), "1", 1.0, "Copter >= 3.4"),
    NameRow("ardupilot", "rate_out", "RATE", ("RllOut", "PitOut", "YawOut"), "1", 1.0, "Copter 3.2 - 3.3"),
    NameRow("ardupilot", "att", "ATT", ("Roll", "Pitch", "Yaw"), "deg", DEG, "all"),
    NameRow("ardupilot", "att_sp", "ATT", ("DesRoll", "DesPitch", "DesYaw"), "deg", DEG, "all"),
)


def rows_for(autopilot: str, signal: str) -> tuple[NameRow, ...]:
    """The rows of ``autopilot`` for ``signal``, in the order the readers try them."""
    table = PX4_ROWS if autopilot == "px4" else ARDUPILOT_ROWS
    return tuple(r for r in table if r.signal == signal)


# PX4 autotune_attitude_control_status.state: the excitation states per axis. The amplitude-detection states
# (PX4-Autopilot pull request 25508, merged September 2025, msg/AutotuneAttitudeControlStatus.msg) shifted the
# numbering; the layout is told by the log's release (ver_sw_release): v1.17 (its first) and later.
PX4_AUTOTUNE_STATES = {
    "legacy": {"roll": (2,), "pitch": (4,), "yaw": (6,)},
    "v1.17": {"roll": (2, 3), "pitch": (5, 6), "yaw": (8, 9)},
}
PX4_AUTOTUNE_NEW_LAYOUT = (1, 17)

# ArduPilot SID_AXIS (libraries/AP_... mode_systemid.cpp, ArduCopter SYSID mode): 1-3 angle input, 4-6
# recovery, 7-9 rate, 10-12 mixer, each roll/pitch/yaw; 13 mixer thrust.
ARDUPILOT_SID_AXES = {k: AXES[(k - 1) % 3] for k in range(1, 13)}

ARDUCOPTER_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
                    7: "CIRCLE", 9: "LAND", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE",
                    16: "POSHOLD", 17: "BRAKE", 18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS",
                    21: "SMART_RTL", 22: "FLOWHOLD", 23: "FOLLOW", 24: "ZIGZAG", 25: "SYSTEMID"}

PX4_NAV_STATES = {0: "MANUAL", 1: "ALTCTL", 2: "POSCTL", 3: "AUTO_MISSION", 4: "AUTO_LOITER", 5: "AUTO_RTL",
                  10: "ACRO", 12: "DESCEND", 13: "TERMINATION", 14: "OFFBOARD", 15: "STAB",
                  17: "AUTO_TAKEOFF", 18: "AUTO_LAND", 19: "AUTO_FOLLOW_TARGET", 20: "AUTO_PRECLAND",
                  21: "ORBIT", 22: "AUTO_VTOL_TAKEOFF"}
