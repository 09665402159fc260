"""Scenes the vehicle is attached into (``MjSpec.attach``), Menagerie style: the vehicle model and the scene
are kept apart, each scene adds the joints that tie the airframe to the world and a ``hover`` keyframe.

* ``pitch-rig`` / ``roll-rig``: 1-DoF gimbal test-bed. A light ring turns on a damped bearing (the rig's
  stops are joint limits); the airframe sits on the ring through an elastic mount (a spring-damper hinge on
  the same axis). Rotors are 1.5 m above the floor, out of ground effect.
* ``thrust-stand``: one rotor of the vehicle on a load cell (force/torque sensor) with a tachometer.
* ``free-flight``: 6-DoF over a floor; the hover keyframe is at 5 m.
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.vehicles import VehicleSpec, load_vehicle
from rotorlab.vehicles.build import add_rotor, build_vehicle_spec

PHYSICS_DT_S = 0.001
SCENES = ("pitch-rig", "roll-rig", "thrust-stand", "free-flight")
HOVER_HEIGHT_M = 5.0
RIG_HEIGHT_M = 1.5
LOAD_CELL_MASS_KG = 0.2
LOAD_CELL_K = (2.0e4, 50.0)  # N/m along the thrust axis, N m/rad about it
PREFIX = "vehicle/"  # names of the attached vehicle's elements: vehicle/gyro, vehicle/thrust1, ...
RIG_AXES = {"pitch-rig": ("pitch", [0.0, -1.0, 0.0]), "roll-rig": ("roll", [1.0, 0.0, 0.0])}


@dataclasses.dataclass
class Scene:
    """A compiled scene: the model plus what the simulator needs to know about it."""

    name: str
    vehicle: VehicleSpec
    model: mujoco.MjModel
    spec: mujoco.MjSpec
    rig_axis: str | None  # "pitch" / "roll" on a rig
    stop_deg: float | None  # rig stops
    thrust_actuators: np.ndarray  # actuator ids, rotor order
    aero_actuators: dict  # "inflow" / "hx" / "hy" (and "tilt_x" / "tilt_y" for hingeless hubs) -> actuator ids, rotor order
    has_anchor: bool = False
    #: rotor-inertia reaction actuators (variable RPM with rotor inertia), rotor order; they take the same
    #: ctrl as the thrust actuators (vehicles.build.add_rotor)
    spinup_actuators: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def rotor_ctrl_ids(self) -> np.ndarray:
        """Actuator ids that take the per-rotor ctrl: the thrust actuators, then the spin-up ones."""
        return np.concatenate([self.thrust_actuators, self.spinup_actuators]).astype(int)

    @property
    def physics_dt_s(self) -> float:
        return float(self.model.opt.timestep)


def list_scenes() -> list[str]:
    return list(SCENES)


def _world(name: str, dt: float) -> mujoco.MjSpec:
    s = mujoco.MjSpec()
    s.modelname = name
    s.compiler.degree = False
    s.option.timestep = dt
    # implicitfast integrates joint damping implicitly: the stiff IMU mount stays stable at 1 kHz
    s.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    s.option.density = 1.225
    s.visual.global_.offwidth = 640
    s.visual.global_.offheight = 480
    s.worldbody.add_light(name="sun", pos=[0, 0, 8], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    return s


def _floor(s: mujoco.MjSpec):
    s.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[20, 20, 0.1], rgba=[0.55, 0.6, 0.55, 1])


def _attach_vehicle(s: mujoco.MjSpec, v: VehicleSpec, parent, pos) -> mujoco.MjsBody:
    child = build_vehicle_spec(v, float(s.option.timestep))
    frame = parent.add_frame(pos=list(pos))
    return frame.attach_body(child.body("airframe"), PREFIX, "")


def _rig(s, v: VehicleSpec, scene: str):
    axis_name, axis = RIG_AXES[scene]
    if axis_name not in v.rigs:
        raise ConfigError(f"vehicle {v.name} has no [rig.{axis_name}] table, so it cannot be mounted on the {scene}",
                          file=v.path, field=f"rig.{axis_name}")
    rig = v.rigs[axis_name]
    _floor(s)
    w = s.worldbody
    w.add_geom(name="rig_base", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.3, 0.3, 0.02], pos=[0, 0, 0.02],
               rgba=[0.3, 0.3, 0.35, 1])
    w.add_geom(name="rig_post", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.03, (RIG_HEIGHT_M - 0.25) / 2, 0],
               pos=[0, 0, (RIG_HEIGHT_M - 0.25) / 2], rgba=[0.3, 0.3, 0.35, 1])
    ring = w.add_body(name="rig_ring", pos=[0, 0, RIG_HEIGHT_M])
    ring.mass = 0.5
    ring.ipos = [0, 0, 0]
    ring.inertia = [rig.ring_inertia_kgm2] * 3
    ring.explicitinertial = True
    stop = math.radians(rig.stop_deg)
    ring.add_joint(name="rig_bearing", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                   damping=rig.bearing_damping_Nms_per_rad, frictionloss=rig.bearing_friction_Nm,
                   limited=True, range=[-stop, stop])
    ring.add_geom(name="rig_yoke", type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.015, 0.12, 0],
                  euler=[math.pi / 2, 0, 0] if axis_name == "pitch" else [0, math.pi / 2, 0],
                  contype=0, conaffinity=0, mass=0, rgba=[0.7, 0.5, 0.1, 1])
    air = _attach_vehicle(s, v, ring, [0, 0, 0])
    air.add_joint(name="rig_mount", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                  stiffness=rig.mount_stiffness_Nm_per_rad, damping=rig.mount_damping_Nms_per_rad)
    return axis_name, rig.stop_deg


def _thrust_stand(s, v: VehicleSpec):
    _floor(s)
    w = s.worldbody
    w.add_geom(name="stand_post", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.03, 0.5, 0], pos=[0, 0, 0.5],
               rgba=[0.3, 0.3, 0.35, 1])
    # A strain-gauge load cell is a stiff spring whose deflection is the reading: the rotor mount slides
    # along z and turns about z on stiff, well-damped springs (about 50 Hz and 120 Hz, damping ratio 0.7).
    mount = w.add_body(name="rotor_mount", pos=[0, 0, 1.0 + 0.5 * v.rotor.radius_m])
    mount.add_geom(name="motor", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.03, 0.03, 0], mass=LOAD_CELL_MASS_KG,
                   rgba=[0.2, 0.2, 0.2, 1])
    izz = 0.5 * LOAD_CELL_MASS_KG * 0.03**2
    mount.add_joint(name="load_cell_z", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], stiffness=LOAD_CELL_K[0],
                    damping=2 * 0.7 * math.sqrt(LOAD_CELL_K[0] * LOAD_CELL_MASS_KG))
    mount.add_joint(name="load_cell_yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1], stiffness=LOAD_CELL_K[1],
                    damping=2 * 0.7 * math.sqrt(LOAD_CELL_K[1] * izz))
    mount.add_geom(name="disc1", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[v.rotor.radius_m, 0.004, 0],
                   pos=[0, 0, 0.05], contype=0, conaffinity=0, mass=0, rgba=[0.6, 0.7, 0.9, 0.35])
    mount.add_site(name=f"{PREFIX}rotor1", pos=[0, 0, 0.05], size=[0.01, 0, 0])
    for jn in ("load_cell_z", "load_cell_yaw"):
        s.add_sensor(name=jn, type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=jn)
    add_rotor(s, v, 1, float(s.option.timestep), prefix=PREFIX)


def _free_flight(s, v: VehicleSpec):
    _floor(s)
    air = _attach_vehicle(s, v, s.worldbody, [0, 0, HOVER_HEIGHT_M])
    air.add_freejoint(name="free")
    # A mocap anchor for rope-pull experiments in flight is a scene option, not a default.


def build_scene(scene: str, vehicle, physics_dt_s: float = PHYSICS_DT_S, edit=None) -> Scene:
    """Build and compile ``scene`` with ``vehicle`` (name, path or VehicleSpec).

    ``edit(spec, scene_name, vehicle_spec)`` may modify the spec before compilation (disturbances that need
    model elements, e.g. a rope tendon and its anchor, use it).
    """
    if scene not in SCENES:
        raise UnknownNameError("scene", scene, SCENES)
    v = vehicle if isinstance(vehicle, VehicleSpec) else load_vehicle(vehicle, physics_dt_s)
    s = _world(f"{v.name}-{scene}", physics_dt_s)
    rig_axis = stop = None
    if scene in RIG_AXES:
        rig_axis, stop = _rig(s, v, scene)
    elif scene == "thrust-stand":
        _thrust_stand(s, v)
    else:
        _free_flight(s, v)
    has_anchor = bool(edit(s, scene, v)) if edit else False
    try:  # both compiles: the keyframe's reads the model first (MuJoCo refuses e.g. a body with no mass)
        _hover_keyframe(s, v, scene)
        model = s.compile()
    except ValueError as exc:
        msg = " ".join(str(exc).split())
        raise ConfigError(f"MuJoCo could not compile the {scene} scene for {v.name}: {msg}", file=v.path,
                          expected="physical values of a flying multirotor") from None

    def ids(kind: str) -> np.ndarray:
        # the vehicle's rotors 1..n that have actuator ``kind`` (a thrust stand has rotor 1 only)
        return np.array([model.actuator(f"{PREFIX}{kind}{i}").id for i in range(1, v.n_rotors + 1)
                         if _has(model, f"{PREFIX}{kind}{i}")], dtype=int)

    thrust = ids("thrust")
    aero = {k: ids(k) for k in ("inflow", "hx", "hy")}
    # the hingeless hubs' disc-tilt dampers (vehicles.build); a rigid-propeller vehicle has none (no key)
    for ax in "xy":
        tilt = [model.actuator(f"{PREFIX}tilt{i}_{ax}").id for i in range(1, v.n_rotors + 1)
                if _has(model, f"{PREFIX}tilt{i}_{ax}")]
        if tilt:
            aero[f"tilt_{ax}"] = np.array(tilt, dtype=int)
    spinup = ids("spinup")
    return Scene(scene, v, model, s, rig_axis, stop, thrust, aero, has_anchor, spinup)


def _has(model, name) -> bool:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) >= 0


def _hover_keyframe(s: mujoco.MjSpec, v: VehicleSpec, scene: str):
    """Keyframe ``hover``: level attitude, every thrust actuator at its trim with its lag filter settled."""
    m = s.compile()
    key = s.add_key(name="hover")
    qpos = np.array(m.qpos0, dtype=float)
    key.qpos = qpos.tolist()
    key.qvel = np.zeros(m.nv).tolist()
    ctrl = np.zeros(m.nu)
    act = np.zeros(m.na)
    for i in range(m.nu):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
        if name.startswith(f"{PREFIX}thrust"):
            ctrl[i] = v.hover_ctrl()
            act[m.actuator_actadr[i]] = v.hover_ctrl()
        elif name.startswith(f"{PREFIX}spinup"):
            ctrl[i] = v.hover_ctrl()
    key.ctrl = ctrl.tolist()
    key.act = act.tolist()
    key.time = 0.0
