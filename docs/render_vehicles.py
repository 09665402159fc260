"""Render a picture of every vehicle into its folder (``vehicles/<name>/vehicle.png``), offscreen.

Run ``MUJOCO_GL=egl python docs/render_vehicles.py`` (or ``osmesa`` where EGL is missing) after changing a
vehicle's geometry, and commit the pictures: the vehicle in the free-flight scene, seen from the front left and
above, as MuJoCo's own renderer draws it from the same model ``rotorlab export-mjcf`` writes.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from rotorlab.scenes import build_scene  # noqa: E402
from rotorlab.vehicles import VEHICLES_DIR, list_vehicles  # noqa: E402

WIDTH, HEIGHT = 640, 400


def render(vehicle: str) -> np.ndarray:
    """RGB image (HEIGHT, WIDTH, 3) of ``vehicle`` hovering in the free-flight scene."""
    scene = build_scene("free-flight", vehicle)
    m = scene.model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "hover"))
    mujoco.mj_forward(m, d)
    airframe = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "vehicle/airframe")
    cam = mujoco.MjvCamera()
    cam.lookat[:] = d.xpos[airframe]
    cam.distance = 3.2 * float(max(scene.vehicle.arm_m, 0.2))
    cam.azimuth, cam.elevation = 135.0, -25.0
    opt = mujoco.MjvOption()
    opt.geomgroup[:] = [1, 1, 1, 1, 0, 0]  # visual and collision geoms; not the aero actuators' group
    with mujoco.Renderer(m, HEIGHT, WIDTH) as r:
        r.update_scene(d, cam, opt)
        return r.render()


def main() -> int:
    names = sys.argv[1:] or list_vehicles()
    for name in names:
        path = VEHICLES_DIR / name / "vehicle.png"
        Image.fromarray(render(name)).save(path, optimize=True)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
