"""``rest``: the vehicle trimmed with nothing happening but sensor noise.

On a rig the controllers are off (quasi-open loop with the supervisor armed, zero command): the rig rests
on its mount. In free flight the position hold keeps the hover keyframe (5 m) in still air.
"""

from rotorlab.sim.scenarios import Context, Setup

NAME = "rest"
DESCRIPTION = "trimmed hover / rig at rest, sensor noise only"
SCENES = ("pitch-rig", "roll-rig", "free-flight")
DURATION_S = 10.0


def setup(ctx: Context) -> Setup:
    if ctx.scene == "free-flight":
        return Setup(mode="position")
    return Setup(mode="open-loop")
