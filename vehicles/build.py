"""MJCF of a vehicle, generated with ``mujoco.MjSpec`` from its :class:`VehicleSpec`.

The vehicle model carries no joint to the world: the scene decides (free joint, rig hinge, welded to a
thrust stand). Everything that can be native MuJoCo is:

* thrust per rotor: a site actuator at ``rotor{i}`` whose gear is the thrust axis plus the rotor drag
  torque (``spin * Q/T``, spin +1 = clockwise from above); ``filterexact`` dynamics is the servo/motor lag and the actuator history
  buffer (``nsample``/``delay``) the transport delay;
* axial-inflow damping: a second site actuator on the same axis, ``force = k_w (ctrl - v_axial)``
  where ctrl is the axial wind at the rotor, so thrust depends on the *air-relative* climb speed;
* flapping / H-force: two in-plane site actuators per rotor, ``force = k_h (ctrl - v_inplane)``, whose
  gear adds the flapping moment ``flap_arm * H`` (forward airspeed tilts the disc back: nose-up);
* hingeless hub: each rotor disc is a small body (the blades' tilt inertia) on two hinges (pitch, roll) whose
  springs/dampers are the hub stiffness; two site actuators ``torque = D (ctrl - omega_disc)`` with ctrl = 0
  damp the disc's tilt rate in inertial axes (the air). The disc drags the airframe through the hub spring:
  rotor damping of body rates at low frequency, a spring to the air above ``K_hub / D``;
* the IMU on its own small body, joined to the airframe by three spring-damper hinges (the published
  IMU mass-spring-damper J, k, c), carrying the gyro and accelerometer;
* fuselage drag from MuJoCo's ellipsoid fluid model, driven by ``opt.wind`` (set by the wind disturbances).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from .bodies import airframe_inertial, hub_inertia
from .spec import VehicleSpec, check_delay_steps, check_rate_steps

ROTOR_ACTUATORS = ("thrust", "inflow", "hx", "hy")


def spinup_torque_per_N(v: VehicleSpec, i: int) -> float:
    """Yaw reaction of rotor ``i`` (1-based) per newton of thrust *not yet reached*, m (0 without rotor inertia).

    A variable-RPM rotor that speeds up takes the motor torque ``J_R dOmega/dt`` from the airframe (ref. 002
    eq. 1, the ``J_R dOmega_R`` term of the yaw equation). The thrust actuator's state is ``Omega^2`` behind a
    first-order lag ``tau``: ``T = k Omega^2``, ``dT/dt = (T_cmd - T) / tau`` with ``T_cmd`` the delayed,
    commanded thrust, so ``J_R dOmega/dt = J_R (T_cmd - T) / (2 k Omega tau)``; with ``Omega`` at its hover
    value this is ``c (T_cmd - T)``, exact for the small-signal yaw model the identification fits.
    """
    r = v.rotor
    if v.kind != "variable-rpm" or r.inertia_kgm2 == 0.0:
        return 0.0
    omega_h = float(r.speed(r.hover_command))
    return r.inertia_kgm2 / (2.0 * r.k_thrust * omega_h * r.lag_s[i - 1])


def build_vehicle_spec(v: VehicleSpec, physics_dt_s: float) -> mujoco.MjSpec:
    """Return the vehicle as an ``MjSpec`` whose root body is ``airframe`` (to be attached by a scene)."""
    check_rate_steps(v.control_rate_hz, physics_dt_s, v.path)
    s = mujoco.MjSpec()
    s.modelname = v.name
    s.compiler.degree = False

    # Default classes, Menagerie style: visual geoms never collide, rotor actuators share their settings.
    main = s.default
    main.geom.rgba = [0.25, 0.25, 0.28, 1]
    visual = s.add_default("visual", main)
    visual.geom.contype = 0
    visual.geom.conaffinity = 0
    visual.geom.group = 2
    visual.geom.mass = 0
    visual.geom.density = 0
    collision = s.add_default("collision", main)
    collision.geom.group = 3
    collision.geom.mass = 0
    collision.geom.density = 0

    frame = s.worldbody.add_body(name="airframe")
    pos = v.rotor_positions()
    hub = hub_inertia(v)
    disc_mass = hub[0] if hub else 0.0
    # the TOML mass and inertia are the whole vehicle's: the IMU board's and rotor discs' share comes off
    mass_kg, inertia_kgm2 = airframe_inertial(v)
    frame.mass = mass_kg
    frame.inertia = list(inertia_kgm2)
    # the vehicle's CG (airframe + IMU board + rotor discs) is the airframe origin, which the rigs put on the pivot
    moment = v.imu.mass_kg * np.asarray(v.imu.offset_m) + disc_mass * pos.sum(axis=0)
    frame.ipos = list(-moment / frame.mass)
    frame.explicitinertial = True

    bx, by, bz = v.body_size_m
    fus = frame.add_geom(name="fuselage", default=collision, type=mujoco.mjtGeom.mjGEOM_BOX, size=[bx, by, bz],
                         pos=list(v.cp_offset_m), rgba=[0.2, 0.2, 0.22, 1])
    # Drag acts at the fuselage centre, which is the centre of pressure: the ellipsoid fluid model is MuJoCo's
    # native quadratic drag with the wind of opt.wind.
    fus.fluid_ellipsoid = 1
    R = v.rotor.radius_m
    for i, p in enumerate(pos, start=1):
        ang = math.atan2(p[1], p[0])
        arm_len = float(np.hypot(p[0], p[1]))
        frame.add_geom(name=f"arm{i}", default=visual, type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.012, arm_len / 2, 0],
                       pos=[p[0] / 2, p[1] / 2, p[2] / 2], euler=[0, math.pi / 2, ang], rgba=[0.15, 0.15, 0.15, 1])
        frame.add_geom(name=f"disc{i}", default=visual, type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[R, 0.004, 0],
                       pos=list(p), rgba=[0.6, 0.7, 0.9, 0.35] if v.rotor.spin[i - 1] > 0 else [0.9, 0.6, 0.5, 0.35])
        frame.add_site(name=f"rotor{i}", pos=list(p), size=[0.01, 0, 0])
        # landing feet below each arm tip, the only airframe collision geoms besides the fuselage
        frame.add_geom(name=f"foot{i}", default=collision, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.02, 0, 0],
                       pos=[0.6 * p[0], 0.6 * p[1], -bz - 0.15])
    front = pos[int(np.argmax(pos[:, 0]))]  # the foremost rotor: rotor 1 of the plus layout
    frame.add_site(name="arm_front_tip", pos=[front[0] + R * 0.2, 0, front[2]], size=[0.01, 0, 0])
    frame.add_site(name="cg", pos=[0, 0, 0], size=[0.005, 0, 0])

    imu = v.imu
    ib = frame.add_body(name="imu", pos=list(imu.offset_m))
    ib.mass = imu.mass_kg
    ib.ipos = [0, 0, 0]
    J = imu.inertia_kgm2
    ib.inertia = [J, J, J]
    ib.explicitinertial = True
    # Three hinges rather than a ball joint: MuJoCo springs and dampers act per hinge, which gives the
    # published per-axis mass-spring-damper (J, k, c) exactly.
    for ax_name, axis in (("x", [1, 0, 0]), ("y", [0, 1, 0]), ("z", [0, 0, 1])):
        ib.add_joint(name=f"imu_mount_{ax_name}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                     stiffness=imu.mount_stiffness, damping=imu.mount_damping)
    ib.add_geom(name="imu_board", default=visual, type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[imu.size_m / 2] * 3, rgba=[0.1, 0.6, 0.2, 1])
    ib.add_site(name="imu", size=[0.005, 0, 0])

    s.add_sensor(name="gyro", type=mujoco.mjtSensor.mjSENS_GYRO, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    s.add_sensor(name="accel", type=mujoco.mjtSensor.mjSENS_ACCELEROMETER, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")
    s.add_sensor(name="imu_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")

    for i in range(1, v.n_rotors + 1):
        add_rotor(s, v, i, physics_dt_s)
        if hub:
            _add_hub(s, frame, v, i, pos[i - 1], hub)
    return s


def _add_hub(s: mujoco.MjSpec, frame, v: VehicleSpec, i: int, p, hub) -> None:
    r = v.rotor
    mass, i_tilt, i_spin = hub
    d = frame.add_body(name=f"hub{i}", pos=list(p))
    d.mass = mass
    d.ipos = [0, 0, 0]
    d.inertia = [i_tilt, i_tilt, i_spin]
    d.explicitinertial = True
    for ax_name, axis in (("x", [1, 0, 0]), ("y", [0, 1, 0])):
        d.add_joint(name=f"flap{i}_{ax_name}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                    stiffness=r.hub_stiffness_Nm_per_rad, damping=r.hub_spring_damping_Nms_per_rad)
    d.add_site(name=f"hub{i}", size=[0.005, 0, 0])
    aero = _aero_default(s)
    D = r.hub_damping_Nms_per_rad
    for k, ax_name in enumerate(("x", "y")):
        a = s.add_actuator(name=f"tilt{i}_{ax_name}", target=f"hub{i}", default=aero)
        a.gear = [0, 0, 0] + [1.0 if j == k else 0.0 for j in range(3)]
        a.gainprm[0] = D
        a.biasprm[2] = -D


def _aero_default(s: mujoco.MjSpec):
    aero = s.find_default("aero")
    if aero is None:
        aero = s.add_default("aero", s.default)
        aero.actuator.trntype = mujoco.mjtTrn.mjTRN_SITE
        aero.actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        aero.actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        aero.actuator.ctrllimited = False
        aero.actuator.group = 4
    return aero


def add_rotor(s: mujoco.MjSpec, v: VehicleSpec, i: int, physics_dt_s: float, prefix: str = "") -> None:
    """Add the actuators of rotor ``i`` (1-based) at site ``{prefix}rotor{i}``: thrust, inflow, hx, hy, and for a
    variable-RPM rotor with inertia the spin-up reaction ``spinup{i}`` (:func:`spinup_torque_per_N`).

    The spin-up actuator takes the same ctrl as the thrust actuator through the same delay line but without
    the lag: its force is the commanded thrust ``T_cmd``; with yaw gear ``+c`` on it and ``-c`` added to the
    thrust actuator's, the airframe gets ``c (T_cmd - T)`` (zero in steady state), all in MuJoCo's actuator
    pipeline (history buffer, exact filter) with no Python in the physics loop.
    """
    check_delay_steps(v, physics_dt_s)
    r = v.rotor
    aero = _aero_default(s)
    sp = r.spin[i - 1]
    c_spin = spinup_torque_per_N(v, i)
    gear_axial = [0, 0, 1, 0, 0, sp * r.torque_to_thrust_m]
    gear_thrust = [0, 0, 1, 0, 0, sp * (r.torque_to_thrust_m - c_spin)]
    a = s.add_actuator(name=f"{prefix}thrust{i}", target=f"{prefix}rotor{i}", trntype=mujoco.mjtTrn.mjTRN_SITE)
    a.gear = gear_thrust
    a.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
    a.dynprm[0] = r.lag_s[i - 1]
    a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    a.gainprm[0] = v.thrust_gain()
    a.biastype = mujoco.mjtBias.mjBIAS_NONE
    a.ctrllimited = False
    nsample = int(round(r.delay_s[i - 1] / physics_dt_s))
    if nsample > 0:
        a.nsample = nsample + 1
        # a quarter step short of the whole number: MuJoCo reads the zero-order-held history at
        # time - delay, and the accumulated float time would otherwise sometimes land just before the
        # wanted sample and add a whole extra physics step of delay (61 instead of 60 steps at t = 1 s)
        a.delay = (nsample - 0.25) * physics_dt_s
    if c_spin:
        b = s.add_actuator(name=f"{prefix}spinup{i}", target=f"{prefix}rotor{i}", trntype=mujoco.mjtTrn.mjTRN_SITE)
        b.gear = [0, 0, 0, 0, 0, sp * c_spin]
        b.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        b.gainprm[0] = v.thrust_gain()
        b.biastype = mujoco.mjtBias.mjBIAS_NONE
        b.ctrllimited = False
        b.nsample, b.delay = a.nsample, a.delay
    kw = r.axial_damping_N_per_mps
    a = s.add_actuator(name=f"{prefix}inflow{i}", target=f"{prefix}rotor{i}", default=aero)
    a.gear = gear_axial
    a.gainprm[0] = kw
    a.biasprm[2] = -kw
    kh, g = r.hforce_N_per_mps, r.flap_arm_m
    a = s.add_actuator(name=f"{prefix}hx{i}", target=f"{prefix}rotor{i}", default=aero)
    a.gear = [1, 0, 0, 0, g, 0]
    a.gainprm[0] = kh
    a.biasprm[2] = -kh
    a = s.add_actuator(name=f"{prefix}hy{i}", target=f"{prefix}rotor{i}", default=aero)
    a.gear = [0, 1, 0, -g, 0, 0]
    a.gainprm[0] = kh
    a.biasprm[2] = -kh
