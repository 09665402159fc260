"""Input-disturbance step on a rig: a constant offset of a fraction of the full axis command at the plant input.

Ref. 002 (figs. 4a, 6 and 8) injects "an input disturbance equivalent to 10 % (30 %) of maximum engine thrust":
its generalized plant adds ``d`` to the controller output ``u`` before the plant ``G`` (motor, delay, inertia,
eq. 13), and the 30 % test "saturat[es] the engines". We read it, as ``rotorlab.tune.loopshaping`` does, as
``d = fraction`` of the full differential motor command added to the rotor commands after the flight software's
saturation and mixer (:meth:`~rotorlab.sim.simulator.Simulator.add_axis_input`): the disturbance reaches the
airframe through the motors' transport delay and lag exactly like a command, and the motors' own range clips
the sum. The controller's saturation at the command limit (40 % on the TUHH twin) leaves ``40 - 100 fraction``
% of authority against it; its anti-windup compensator sees only its own saturation, as on the rig.
"""

from __future__ import annotations

import mujoco
import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.scenes import RIG_AXES
from rotorlab.sim.disturbances.base import Disturbance


def axis_torque_per_pct(vehicle, axis: str = "pitch") -> float:
    """Roll/pitch moment per % of axis command at hover, N m (plus layout: each rotor of the opposite pair gets
    half; any frame: :meth:`~rotorlab.vehicles.spec.VehicleSpec.axis_lever_m`)."""
    return vehicle.axis_lever_m(axis) * vehicle.thrust_gain() * vehicle.dctrl_dcommand()


class InputDisturbanceStep(Disturbance):
    """Step of ``fraction`` of full command at the plant input from ``t_s`` on (for ``hold_s``, default to the
    end); ``d_moment`` logs its nominal (linearised, steady) moment.

    Parameters
    ----------
    fraction : float
        Disturbance as a fraction of the full differential command (0.1 = 10 %); the sign sets the direction
        (positive raises the rig angle, like a positive command).
    t_s : float
        Onset, s.
    hold_s : float, optional
        Duration, s (default: until the end of the run).
    """

    name = "input-step"
    scenes = tuple(RIG_AXES)
    columns = {"d_input": "%", "d_moment": "N m"}
    stage = mujoco.mjtStage.mjSTAGE_ACC  # the rotor controls

    def __init__(self, fraction: float, t_s: float = 1.0, hold_s: float | None = None):
        if not (np.isfinite(fraction) and abs(fraction) <= 1.0):
            raise ConfigError(field="fraction", expected="a fraction of the full command in [-1, 1]", got=fraction)
        if not t_s >= 0:
            raise ConfigError(field="t_s", expected="an onset time >= 0 s", got=t_s)
        if hold_s is not None and not hold_s > 0:
            raise ConfigError(field="hold_s", expected="a duration > 0 s (or None: to the end)", got=hold_s)
        self.fraction, self.t_s = float(fraction), float(t_s)
        self.t_end_s = np.inf if hold_s is None else self.t_s + float(hold_s)

    def reset(self, sim, rng) -> None:
        # [collective, roll, pitch, yaw] slot of the rig's axis
        axis = RIG_AXES[sim.scene.name][0]
        self._slot = ("roll", "pitch").index(axis) + 1
        self._moment_per_pct = axis_torque_per_pct(sim.vehicle, axis)

    def input_pct(self, t: float) -> float:
        # half a tick of tolerance: the tick times are sums of float periods
        return 100.0 * self.fraction if self.t_s - 1e-9 <= t < self.t_end_s - 1e-9 else 0.0

    def update(self, sim, t: float) -> None:
        d = self.input_pct(t)
        if d:
            cmd = [0.0, 0.0, 0.0, 0.0]
            cmd[self._slot] = d
            sim.add_axis_input(cmd)

    def values(self, sim) -> dict:
        d = self.input_pct(sim.time)
        return {"d_input": d, "d_moment": d * self._moment_per_pct}


__all__ = ["InputDisturbanceStep", "axis_torque_per_pct"]
