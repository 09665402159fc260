"""Flight software: discrete PIDs, attitude cascade, mixer, supervisor, outer loops, plug-ins.

Pure Python/numpy (no MuJoCo): the simulator calls :class:`FlightSoftware.step` every tick.
"""

from rotorlab.sim.control.cascade import DEFAULT_YAW_GAINS, AttitudeController, CascadeAxis, wrap_deg
from rotorlab.sim.control.flight_software import FlightSoftware
from rotorlab.sim.control.mixer import Mixer, quad_plus, quad_x
from rotorlab.sim.control.pid import DiscretePID
from rotorlab.sim.control.plugins import CallbackPlugin, Plugin, StateSpacePlugin
from rotorlab.sim.control.position import AltitudeHold, PositionGains, PositionHold
from rotorlab.sim.control.supervisor import Supervisor

__all__ = [
    "DiscretePID", "CascadeAxis", "AttitudeController", "DEFAULT_YAW_GAINS", "wrap_deg",
    "Mixer", "quad_x", "quad_plus", "Supervisor", "PositionGains", "PositionHold", "AltitudeHold",
    "Plugin", "StateSpacePlugin", "CallbackPlugin", "FlightSoftware",
]
