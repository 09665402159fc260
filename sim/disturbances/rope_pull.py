"""Rope pull: the published load-disturbance test of the A2-MINI/B test-bed (reference 000, "Experimental
results on test-bed (load disturbance)"): a rope at the tip of the front arm is pulled by hand to impose about
20 deg of pitch, held a couple of seconds, then suddenly released.

Physics: a MuJoCo spatial tendon from the front-arm tip site to a site on a mocap anchor, ``limited`` with range
``[0, length]``: below its length the rope is slack and does nothing, at its length a unilateral constraint
holds it (a rope, not a spring). The "hand" is the anchor: it starts below the arm tip with the rope slack,
moves (linear ramp) to where a rope of that length holds the arm at the wanted angle, holds, and jumps back
(release). Tension is logged from a ``tendonlimitfrc`` sensor (the limit constraint force), the rope length from
the tendon.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.scenes import PREFIX
from rotorlab.sim.disturbances.base import Disturbance

TIP_SITE = f"{PREFIX}arm_front_tip"


class RopePull(Disturbance):
    """Rope from the front-arm tip to a moving anchor below it.

    Parameters
    ----------
    pull_deg : float
        Pitch angle the rope imposes, deg (negative: the rope pulls the front arm down, nose down).
    t_pull_s : float
        When the hand starts pulling, s.
    ramp_s : float
        Duration of the pull (anchor moving from slack to the pulled position), s.
    hold_s : float
        How long the angle is held before the release, s.
    length_m : float
        Rope length, m.
    slack_m : float
        Slack of the rope before the pull (and right after the release), m.
    """

    name = "rope"
    scenes = ("pitch-rig",)
    columns = {"rope_tension": "N", "rope_length": "m", "rope_pulled": "-"}
    stage = mujoco.mjtStage.mjSTAGE_POS  # the mocap anchor

    def __init__(self, pull_deg: float = -20.0, t_pull_s: float = 1.0, ramp_s: float = 0.5, hold_s: float = 2.0,
                 length_m: float = 1.0, slack_m: float = 0.05):
        if not 0 < abs(pull_deg) < 90:
            raise ConfigError(field="pull_deg", expected="an angle with 0 < |angle| < 90 deg", got=pull_deg)
        if not (t_pull_s >= 0 and ramp_s > 0 and hold_s >= 0):
            raise ConfigError(field="t_pull_s/ramp_s/hold_s", expected="t_pull_s >= 0, ramp_s > 0, hold_s >= 0",
                              got=(t_pull_s, ramp_s, hold_s))
        if not 0 < slack_m < length_m:
            raise ConfigError(field="length_m/slack_m", expected="0 < slack_m < length_m", got=(length_m, slack_m))
        self.pull_deg = float(pull_deg)
        self.t_pull_s, self.ramp_s, self.hold_s = float(t_pull_s), float(ramp_s), float(hold_s)
        self.length_m, self.slack_m = float(length_m), float(slack_m)

    @property
    def t_release_s(self) -> float:
        return self.t_pull_s + self.ramp_s + self.hold_s

    def check_scene(self, scene: str) -> None:
        if scene == "free-flight":
            raise ConfigError("the rope-pull test needs a test-bed: the free-flight scene has no anchor to pull "
                              "from (the rope would only be a tether)", field="disturbances",
                              expected=list(self.scenes), got=scene)
        super().check_scene(scene)

    def edit(self, spec, scene: str, vehicle) -> bool:
        anchor = spec.worldbody.add_body(name="rope_anchor", mocap=True, pos=[0.0, 0.0, 0.0])
        anchor.add_site(name="rope_anchor", size=[0.01, 0, 0], rgba=[0.8, 0.2, 0.1, 1])
        ten = spec.add_tendon(name="rope", limited=True, range=[0.0, self.length_m], width=0.004,
                              rgba=[0.9, 0.8, 0.3, 1])
        ten.wrap_site(TIP_SITE)
        ten.wrap_site("rope_anchor")
        spec.add_sensor(name="rope_tension", type=mujoco.mjtSensor.mjSENS_TENDONLIMITFRC,
                        objtype=mujoco.mjtObj.mjOBJ_TENDON, objname="rope")
        return True

    def reset(self, sim, rng) -> None:
        m, d = sim.model, sim.data
        self._mocap = m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "rope_anchor")]
        self._tendon = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "rope")
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "rope_tension")
        self._sens = m.sensor_adr[sid]
        tip = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, TIP_SITE)
        down = np.array([0.0, 0.0, 1.0])
        # tip positions level and at the pulled angle, from the kinematics of a scratch copy of the state
        # (the simulator resets the disturbances before its own forward pass)
        scratch = mujoco.MjData(m)
        scratch.qpos[:] = d.qpos
        mujoco.mj_kinematics(m, scratch)
        self._slack_pos = scratch.site_xpos[tip] - (self.length_m - self.slack_m) * down
        scratch.qpos[m.jnt_qposadr[sim._bearing]] = math.radians(self.pull_deg)
        scratch.qpos[m.jnt_qposadr[sim._mount]] = 0.0
        mujoco.mj_kinematics(m, scratch)
        self._pulled_pos = scratch.site_xpos[tip] - self.length_m * down
        d.mocap_pos[self._mocap] = self._slack_pos

    def anchor_position(self, t: float) -> tuple[np.ndarray, float]:
        """Anchor position (world, m) for the control period starting at ``t``, and the pull fraction 0..1."""
        if t < self.t_pull_s or t >= self.t_release_s:
            return self._slack_pos, 0.0
        f = min(1.0, (t - self.t_pull_s) / self.ramp_s)
        return self._slack_pos + f * (self._pulled_pos - self._slack_pos), f

    def update(self, sim, t: float) -> None:
        pos, _ = self.anchor_position(t)
        sim.data.mocap_pos[self._mocap] = pos

    def values(self, sim) -> dict:
        d = sim.data
        return {"rope_tension": abs(float(d.sensordata[self._sens])), "rope_length": float(d.ten_length[self._tendon]),
                "rope_pulled": self.anchor_position(sim.time)[1]}


__all__ = ["RopePull", "TIP_SITE"]
