"""The simulator: MuJoCo physics at 1 kHz under flight software at 50 Hz.

Between two control ticks the physics steps are batched in one ``mj_step(m, d, nstep)`` call; the rotor
commands are held (zero-order hold, like the real servo/ESC interface) and MuJoCo's actuator history buffers
realise the transport delay. Sensors are sampled at the tick, as the flight computer samples its IMU.
"""

from __future__ import annotations

import math
import operator

import mujoco
import numpy as np

from rotorlab.errors import ConfigError, RotorlabError
from rotorlab.scenes import PREFIX, Scene, build_scene
from rotorlab.sim.control.mixer import Mixer
from rotorlab.sim.disturbances.mean_wind import WindDisturbance
from rotorlab.sim.frames import FLU_TO_FRD, RAD2DEG, euler_deg
from rotorlab.sim.sensors import SENSORS, imu_suite

CONTROL_DT_S = 0.02  # the published ANTEOS cycle; a vehicle's own rate is VehicleSpec.control_dt_s
FREE_FLIGHT_TILT_LIMIT_DEG = 80.0
FLOOR_CLEARANCE_M = 0.05


def vehicle_mixer(vehicle) -> Mixer:
    """The flight software's mixer for a vehicle's rotor layout.

    Rotor commands are absolute % (see ``VehicleSpec.command_to_ctrl``); hover is at
    ``vehicle.hover_collective_pct``.
    """
    pos = vehicle.rotor_positions()[:, :2]
    return Mixer(pos, vehicle.rotor.spin, kind=vehicle.kind, frame="flu")


_STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)  # Simulator.tick's acceleration-only forward pass, looked up once
_STAGE_ACC = int(mujoco.mjtStage.mjSTAGE_ACC)
_SENSORS_OFF = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)

#: MuJoCo warnings that mean the run diverged: MuJoCo flags (and resets) NaN/inf states through them, so no
#: array scan is needed
DIVERGENCE_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL,
                       mujoco.mjtWarning.mjWARN_BADQPOS)


def body_wind(xmat, wind_world) -> np.ndarray:
    """Wind in the airframe's axes (FLU), m/s: what drives the rotors' H-force (x, y) and inflow (z) actuators,
    whose sites are aligned with the airframe.

    Parameters
    ----------
    xmat : (9,) or (n, 9)
        Airframe orientation (MuJoCo ``xmat`` row), one simulation or one row per simulation.
    wind_world : (3,) or (n, 3)
        Wind in the world (z up), m/s.
    """
    if xmat.ndim == 1:
        return xmat.reshape(3, 3).T @ wind_world
    return np.einsum("nji,nj->ni", np.reshape(xmat, (-1, 3, 3)), wind_world)


def diverged_reason(t: float, warning: str = "") -> str:
    name = f"{warning} " if warning else ""
    return f"MuJoCo warning {name}at t = {t:.3f} s (the simulation diverged: NaN/inf or huge state)"


def at_rig_stop(angle_deg, stop_deg: float):
    """Whether a rig angle (deg; scalar or array) reached the rig's stop, with the half-degree margin that keeps
    the run off the stop's contact."""
    return abs(angle_deg) >= stop_deg - 0.5


def rig_stop_reason(scene, angle_deg: float, t: float) -> str:
    return (f"{scene.rig_axis} angle {angle_deg:+.1f} deg reached the rig stop (+-{scene.stop_deg:g} deg) "
            f"at t = {t:.3f} s")


class StopCheck:
    """Why a run must stop, MuJoCo's divergence warnings aside: a rig at its stop, a flip or a crash in free
    flight. :class:`Simulator` asks every tick; :func:`rotorlab.sim.batch.run_batch` asks for each of its
    simulations with that simulation's row of the batch's state."""

    def __init__(self, model, scene):
        self.scene = scene
        bearing = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rig_bearing")
        mount = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rig_mount")
        self.rig_qadr = (int(model.jnt_qposadr[bearing]), int(model.jnt_qposadr[mount])) if bearing >= 0 else None
        self.free = scene.name == "free-flight"
        if self.rig_qadr is not None:
            self.stop_deg = float(scene.stop_deg)
        self.floor_z = FLOOR_CLEARANCE_M + scene.vehicle.body_size_m[2]
        self.cos_tilt_limit = math.cos(math.radians(FREE_FLIGHT_TILT_LIMIT_DEG))

    def rig_hits(self, qpos) -> np.ndarray:
        """Which rows of ``qpos`` (a row per simulation) hold a rig at its stop (:meth:`reason`'s rig test over
        a batch; the batched runner asks :meth:`reason` only for these rows)."""
        a, b = self.rig_qadr
        return at_rig_stop((qpos[:, a] + qpos[:, b]) * RAD2DEG, self.stop_deg)

    def reason(self, qpos, xmat, xpos, t: float) -> str | None:
        """Why to stop at time ``t`` (s), or None, from one simulation's ``qpos`` and its airframe's ``xmat``
        (9,) and ``xpos`` (3,) (read in free flight only): arrays or memoryviews of MjData's buffers."""
        if self.rig_qadr is not None:
            a, b = self.rig_qadr
            ang = math.degrees(qpos[a] + qpos[b])
            if at_rig_stop(ang, self.stop_deg):
                return rig_stop_reason(self.scene, ang, t)
        elif self.free:
            # tilt from the body z axis: R[2, 2] = cos(tilt), compared as a cosine (no acos on the good path)
            if xmat[8] < self.cos_tilt_limit:
                tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(xmat[8])))))
                return (f"tilt {tilt:.0f} deg beyond the divergence limit {FREE_FLIGHT_TILT_LIMIT_DEG:g} deg "
                        f"at t = {t:.3f} s")
            if xpos[2] < self.floor_z:
                return f"the vehicle hit the floor at t = {t:.3f} s"
        return None


def strided(ids):
    """Actuator ids as the equal-stride slice they are when they are one (a rotor's actuators repeat with the
    rotor: thrust at 0, 6, 12, 18), else unchanged: a slice of MjData's ``ctrl`` is a view, several times cheaper
    per tick than the copy and scatter of an index array."""
    ids = np.asarray(ids, dtype=int)
    if ids.size < 2:
        return slice(int(ids[0]), int(ids[0]) + 1) if ids.size else ids
    step = int(ids[1] - ids[0])
    if step > 0 and np.array_equal(ids, np.arange(ids[0], ids[-1] + 1, step)):
        return slice(int(ids[0]), int(ids[-1]) + 1, step)
    return ids


def set_rotor_ctrl(ctrl, rotor_pct, vehicle, thrust, spinup) -> None:
    """Rotor commands (%, one per thrust actuator) into MuJoCo's controls of the thrust actuators and their
    spin-up twins (same control; None: none), a row per simulation (``ctrl (n, nu)``, ``rotor_pct (n, n_rotors)``:
    the batched runner; one simulation writes its own, :meth:`Simulator.set_rotor_commands`). ``thrust``,
    ``spinup``: ids or :func:`strided` slices."""
    c = vehicle.command_to_ctrl(rotor_pct).T
    # indexed through the transposes (actuator index first): a leading-axis index ctrl[ids] is a plain row
    # selection, where ctrl[..., ids] goes through numpy's general fancy-indexing path on every tick
    ctrl.T[thrust] = c
    if spinup is not None:
        ctrl.T[spinup] = c


def set_wind(opt_wind, ctrl, xmat, wind_world, aero: dict) -> None:
    """Wind (m/s, world, z up) into the physics: fuselage drag through ``opt.wind``, rotor inflow and H-force
    through the controls of the rotor aero actuators ``aero`` (``Scene.aero_actuators``), which take the wind in
    the airframe's axes (:func:`body_wind`; ``xmat`` None: a scene without an airframe takes it unrotated).
    A row per simulation (``opt_wind, wind_world (n, 3)``, ``ctrl (n, nu)``, ``xmat (n, 9)``: the batched
    runner) or one simulation (1-D; the simulator's ticks with an airframe go through :func:`set_air_motion`)."""
    opt_wind[...] = wind_world
    wb = (wind_world if xmat is None else body_wind(xmat, wind_world)).T
    ct = ctrl.T  # actuator index first, as in set_rotor_ctrl
    ct[aero["hx"]], ct[aero["hy"]], ct[aero["inflow"]] = wb


#: the component of the body-axis wind (:func:`body_wind`) each rotor aero actuator group takes
_WIND_COMPONENT = {"hx": 0, "hy": 1, "inflow": 2}


def air_motion_map(model, data, airframe: int, aero: dict):
    """How the air's motion moves the rotor aero actuators (``Scene.aero_actuators``) of one simulation, for
    :func:`set_air_motion`. The inflow and in-plane actuators take the wind in the airframe's axes, one component
    each (:func:`set_wind`). The air's rigid rotation ``omega`` (rad/s, airframe axes) adds to what each actuator
    measures: a site actuator's velocity is ``gear . [v_site; omega_site]`` (site axes, which the hubs keep along
    the airframe's to the flap angle); air turning rigidly about the CG moves at ``omega x r_i`` with rotation
    ``omega`` at the site ``r_i``, so its row is ``J_i = r_i x gear_lin + gear_rot``. Taken at the state in
    ``data`` (the hover keyframe). Returns ``(rows_wind, rows_tilt)`` as Python numbers: ``(actuator id, wind
    component, J_i)`` for the inflow and in-plane actuators and ``(actuator id, J_i)`` for the disc-tilt dampers,
    whose reference only the air's rotation drives."""
    R = data.xmat[airframe].reshape(3, 3)
    rows_wind, rows_tilt = [], []
    for key, ids in aero.items():
        for i in np.arange(model.nu)[ids].reshape(-1):
            site = model.actuator_trnid[i, 0]
            r = R.T @ (data.site_xpos[site] - data.xpos[airframe])
            g = model.actuator_gear[i]
            J = (np.cross(r, g[:3]) + g[3:6]).tolist()
            if key.startswith("tilt"):
                rows_tilt.append((int(i), *J))
            else:
                rows_wind.append((int(i), _WIND_COMPONENT[key], *J))
    return rows_wind, rows_tilt


def set_air_motion(opt_wind, ctrl, xmat, wind_world, air_rate_world, motion_map) -> None:
    """The air's motion into one simulation with an airframe, every tick of a windy run: the wind (m/s, world,
    z up) into ``opt.wind`` and the rotor aero controls as :func:`set_wind` puts it, and the air's rotation
    (rad/s, world, z up; the turbulence's gust gradients; None: none) on top (``motion_map``,
    :func:`air_motion_map`): the hubs' inflow and in-plane air velocities differ by ``omega x r_i`` (the fore/aft
    thrust difference of a pitch gradient), and the disc-tilt dampers' reference becomes the air's rotation
    (their torque ``D (omega_air - omega_disc)``: the blades' angle of attack changes with the disc's rotation
    relative to the air, which is how gust gradients enter an aircraft's damping derivatives). ``ctrl (nu,)``
    and ``xmat (9,)`` of the airframe: arrays or memoryviews of MjData's."""
    # written out in floats, each control written once: numpy's per-call cost on 3-vectors and a dozen actuators
    # is several times the arithmetic (tests/test_sim_core.py: the same floats as set_wind and numpy's products)
    opt_wind[...] = wind_world
    a0, a1, a2 = wind_world.tolist()
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = xmat.tolist()
    # R^T a, R's rows being xmat's: the sums of numpy's 3x3 matrix-vector product in its order (body_wind)
    wind_body = (r0 * a0 + r3 * a1 + r6 * a2, r1 * a0 + r4 * a1 + r7 * a2, r2 * a0 + r5 * a1 + r8 * a2)
    rows_wind, rows_tilt = motion_map
    if air_rate_world is None:
        for i, k, _, _, _ in rows_wind:
            ctrl[i] = wind_body[k]
        return
    a0, a1, a2 = air_rate_world.tolist()
    w0, w1, w2 = (r0 * a0 + r3 * a1 + r6 * a2, r1 * a0 + r4 * a1 + r7 * a2, r2 * a0 + r5 * a1 + r8 * a2)
    for i, k, j0, j1, j2 in rows_wind:
        ctrl[i] = wind_body[k] + (j0 * w0 + j1 * w1 + j2 * w2)
    for i, j0, j1, j2 in rows_tilt:
        ctrl[i] = j0 * w0 + j1 * w1 + j2 * w2


class Diverged(RotorlabError):
    """The run left the physically meaningful region (NaN, MuJoCo warning, rig stop, crash)."""


class Simulator:
    """One vehicle in one scene.

    Parameters
    ----------
    scene : str or Scene
        ``pitch-rig``, ``roll-rig``, ``thrust-stand`` or ``free-flight`` (or an already built Scene).
    vehicle : str, path or VehicleSpec
    seed : int
        Seeds the IMU noise and bias and every disturbance (``numpy.random.Generator``).
    control_dt_s : float, optional
        Flight-software period, s; must be a whole number of physics steps. Default: the vehicle's
        (``[flight_software] rate_hz`` in its vehicle.toml; 50 Hz unless it says otherwise).
    sensor_noise : bool
        IMU noise and bias on or off.
    disturbances : sequence
        Objects following :class:`rotorlab.sim.disturbances.base.Disturbance`.
    """

    #: Python-side state a snapshot must keep besides MuJoCo's full physics state (see the gym envs)
    python_state_attrs = ("rng", "_noise", "commands_pct", "rotor_pct", "wind_world", "air_rate_world", "seed")

    def __init__(self, scene="pitch-rig", vehicle="anteos-p2a2", *, seed: int = 0, control_dt_s: float | None = None,
                 sensor_noise: bool = True, disturbances=()):
        self.disturbances = list(disturbances)
        self.wind_disturbances = [d for d in self.disturbances if isinstance(d, WindDisturbance)]
        #: the earliest MuJoCo stage the disturbances' updates change (Disturbance.stage; none: the acceleration
        #: stage, the only one the rotor commands reach), for the regrouped tick
        self._update_stage = min((int(d.stage) for d in self.disturbances), default=_STAGE_ACC)
        if isinstance(scene, Scene):
            self.scene = scene
        else:
            for dist in self.disturbances:
                dist.check_scene(scene)
            edits = [d for d in self.disturbances if hasattr(d, "edit")]

            def edit(spec, name, v):
                return any([bool(d.edit(spec, name, v)) for d in edits])

            self.scene = build_scene(scene, vehicle, edit=edit if edits else None)
        self.vehicle = self.scene.vehicle
        self.model = self.scene.model
        self.data = mujoco.MjData(self.model)
        if control_dt_s is None:
            control_dt_s = self.vehicle.control_dt_s
        n = control_dt_s / self.model.opt.timestep
        if abs(n - round(n)) > 1e-9 or round(n) < 1:
            raise ValueError(f"control period {control_dt_s} s is not a whole number of physics steps "
                             f"({self.model.opt.timestep} s)")
        self.n_substeps = int(round(n))
        self.control_dt_s = float(control_dt_s)
        self.sensor_noise = sensor_noise
        self.seed = seed
        m = self.model
        self._n_thrust = len(self.scene.thrust_actuators)
        #: where the rotor commands and the wind go in ``ctrl`` (:func:`set_rotor_ctrl`, :func:`set_wind`): the
        #: thrust actuators, their spin-up twins (same ctrl, the rotor-inertia reaction; None: none) and the
        #: rotor aero actuators, as :func:`strided` slices where they are
        self.thrust_ids = strided(self.scene.thrust_actuators)
        self.spinup_ids = strided(self.scene.spinup_actuators) if len(self.scene.spinup_actuators) else None
        self.aero_ids = {k: strided(v) for k, v in self.scene.aero_actuators.items()}
        # one simulation's (thrust, spin-up) actuator pair of each rotor, the thrust actuator twice without a
        # spin-up twin: set_rotor_commands stores each control through a memoryview, several times cheaper per
        # tick than numpy's conversion of a list into a slice of ctrl
        spinup = self.scene.spinup_actuators if len(self.scene.spinup_actuators) else self.scene.thrust_actuators
        self._rotor_slots = [(int(i), int(j)) for i, j in zip(self.scene.thrust_actuators, spinup)]
        self._ctrl_scratch = self.vehicle.ctrl_scratch(self._n_thrust)
        self.mixer = vehicle_mixer(self.vehicle)
        self._limit = self.vehicle.command_limit_pct
        self._airframe = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{PREFIX}airframe")
        self._key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "hover")
        # the sensors this model carries (an IMU on the vehicle, a load cell and a tachometer on the stand)
        self.sensors = {}
        for name, cls in SENSORS.items():
            try:
                self.sensors[name] = cls(m, self.vehicle)
            except LookupError:
                pass
        self.imu = imu_suite(m, self.vehicle)
        self.forces_at_tick = True
        imu_acc = [s for s in (self.imu.sensors if self.imu else ()) if s.acceleration_stage]
        #: the IMU channels measured in the acceleration stage (the accelerometer's)
        self.acc_channels = [c for s in imu_acc for c in s.channels]
        # another acceleration-stage MuJoCo sensor (a disturbance's force sensor) keeps the pass whatever the flag
        imu_adr = {s.slice.start for s in imu_acc}
        self._force_sensors = any(int(m.sensor_needstage[i]) == _STAGE_ACC and int(m.sensor_adr[i]) not in imu_adr
                                  for i in range(m.nsensor))
        self._bearing = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "rig_bearing")
        self._mount = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "rig_mount")
        #: why a run must stop (also asked by the batched runner for each of its simulations)
        self.stops = StopCheck(m, self.scene)
        self._free = self.scene.name == "free-flight"
        # views into MjData's buffers, made once: attribute access through the bindings costs microseconds
        d = self.data
        self._sd_v, self._ctrl_v, self._xfrc_v = d.sensordata, d.ctrl, d.xfrc_applied
        af = max(self._airframe, 0)
        self._opt = self.model.opt
        self._wind_v = self._opt.wind
        # memoryviews for the scalar reads of every tick: their tolist() and item access run a few lines of
        # CPython's core where numpy's indexing and pybind's attribute access run far more code, code MuJoCo's
        # physics steps evict from the caches between two ticks; the free joint's position, velocity and
        # angular velocity are read in free flight only
        self._sd_mv = memoryview(d.sensordata)
        self._qpos_mv, self._ctrl_mv = memoryview(d.qpos), memoryview(d.ctrl)
        self._pos_mv, self._vel_mv, self._omega_mv = (memoryview(v) for v in (d.qpos[0:3], d.qvel[0:3], d.qvel[3:6]))
        self._af_xquat_mv, self._af_xmat_mv, self._af_xpos_mv = (
            memoryview(v) for v in (d.xquat[af], d.xmat[af], d.xpos[af]))
        self._warn_mv = memoryview(d.warning.number)  # live counts, int32
        self._warn_ids = [(int(w), w.name) for w in DIVERGENCE_WARNINGS]
        self._warn_counts = operator.itemgetter(*(i for i, _ in self._warn_ids))
        self._gyro_scale = (FLU_TO_FRD * RAD2DEG).tolist()
        self.wind_world = np.zeros(3)
        #: the air's rotation (rad/s, world, z up) this tick: the turbulence's gust gradients (:func:`set_air_motion`)
        self.air_rate_world = np.zeros(3)
        self._rotates_air = any(dist.rotates_air for dist in self.disturbances)
        if self._rotates_air and self._airframe < 0:
            raise ConfigError(f"the air's rotation (turbulence gust gradients) acts on a vehicle's rotors; the "
                              f"{self.scene.name} scene has no airframe", field="disturbances",
                              expected="a rig or free flight", got=self.scene.name)
        self.reset(seed)
        self._air_map = (air_motion_map(m, self.data, self._airframe, self.scene.aero_actuators)
                         if self._airframe >= 0 else None)

    @property
    def forces_at_tick(self) -> bool:
        """The tick ends with the acceleration stage under the held controls, so the accelerometer, force sensors
        and actuator forces are current at the tick; :meth:`tick` says what turning it off saves and costs, and
        :meth:`measure` then reads the accelerometer as NaN without converting it."""
        return self._forces_at_tick

    @forces_at_tick.setter
    def forces_at_tick(self, on: bool) -> None:
        self._forces_at_tick = bool(on)
        if self.imu is not None:
            self.imu.set_current([s for s in self.imu.sensors if on or not s.acceleration_stage])

    # ------------------------------------------------------------------ state
    def reset(self, seed: int | None = None) -> None:
        """Back to the hover keyframe with settled actuator filters and delay lines; re-seeds noise."""
        if seed is not None:
            self.seed = seed
        m, d = self.model, self.data
        mujoco.mj_resetDataKeyframe(m, d, self._key)
        # history buffers start at zero (MuJoCo's default); fill them with the trim so the delay line
        # holds hover thrust, as on a vehicle that has been hovering
        for i in range(m.nu):
            if m.actuator_history[i, 0] > 0:
                vals = np.full((m.actuator_history[i, 0], 1), d.ctrl[i])
                mujoco.mj_initCtrlHistory(m, d, i, None, vals)
        self.rng = np.random.default_rng(self.seed)
        self._noise = None
        if self.imu is not None:
            bias = self.imu.draw_bias(self.rng) if self.sensor_noise else np.zeros(self.imu.n_noisy)
            self._noise = self.imu.noise(self.rng, bias)
        self.commands_pct = np.array([self.vehicle.hover_collective_pct, 0.0, 0.0, 0.0])
        self.rotor_pct = tuple(self.mixer.mix(*self.commands_pct)[: self._n_thrust])
        self.wind_world[:] = 0.0
        self.air_rate_world[:] = 0.0
        self._wind_v[:] = 0.0  # opt.wind lives in the model, which outlives a run
        for dist in self.disturbances:
            dist.reset(self, np.random.default_rng([self.seed, _stable_hash(dist.name)]))
        mujoco.mj_forward(m, d)

    @property
    def time(self) -> float:
        return float(self.data.time)

    # ------------------------------------------------------------------ actuation
    def set_commands(self, commands_pct) -> np.ndarray:
        """Axis commands [collective, roll, pitch, yaw] in %, roll/pitch/yaw saturated at the vehicle's command
        limit (the mixer clips each rotor to its range); returns the applied commands."""
        c = np.asarray(commands_pct, dtype=float).copy()
        c[1:] = np.clip(c[1:], -self._limit, self._limit)
        self.commands_pct = c
        self.set_rotor_commands(self.mixer.mix(*c))
        return c

    def set_rotor_commands(self, rotor_pct) -> None:
        """Per-rotor commands in % (a sequence, kept as :attr:`rotor_pct`), e.g. from the flight software's mixer or a
        thrust-stand test."""
        rotor = tuple(rotor_pct[: self._n_thrust])  # a copy the caller cannot change under the simulator
        self.rotor_pct = rotor
        ctrl = self._ctrl_mv
        # command_to_ctrl in floats (numpy costs several times more for four rotors), one store per actuator
        for (i, j), c in zip(self._rotor_slots, self.vehicle.command_to_ctrl_floats(rotor, self._ctrl_scratch)):
            ctrl[i] = ctrl[j] = c

    def add_axis_input(self, commands_pct) -> None:
        """Add axis commands ``[collective, roll, pitch, yaw]`` (%) to this tick's rotor commands at the
        actuators: an input disturbance at the plant input (ref. 002 fig. 4a), after the flight software's
        saturation and mixer, so it reaches the airframe through the motors' delay and lag like any command.
        The motors' own range (the mixer's per-rotor limits) clips the sum. Cleared by the next
        :meth:`set_rotor_commands`."""
        mx = self.mixer
        extra = np.asarray(mx.mix(*commands_pct, clip=False))[: self._n_thrust]
        self.set_rotor_commands(np.clip(np.add(self.rotor_pct, extra), mx.out_min, mx.out_max))

    # ------------------------------------------------------------------ stepping
    def tick(self, controls_only: bool = False) -> None:
        """Advance one control period: disturbances update at the tick, then the batched physics steps.

        The sensors are computed at the tick only, where they are read (the IMU is sampled at the tick):
        MuJoCo skips them in the physics steps between (``mjDSBL_SENSOR``), which also skips the accelerometer's
        extra recursive Newton-Euler pass there. No physics reads a sensor, so the state is the same bit for bit,
        and so are the sensors at the tick.

        ``controls_only``: the caller vouches that since the last tick or :meth:`reset` it changed nothing in
        MuJoCo's model or data but ``ctrl`` (the runner's loop). Then the first physics step reuses the position
        and velocity stages the last tick computed for this very state (``mj_step2``; they do not depend on the
        controls), unless a disturbance changes their inputs: from the earliest stage a disturbance changes
        (:attr:`Disturbance.stage <rotorlab.sim.disturbances.base.Disturbance.stage>`) on, the stages are
        recomputed (wind: the velocity stage, through ``opt.wind``; positions, e.g. a mocap anchor: the plain
        step). MuJoCo's state checks then run at the end of the tick (``mj_step1``) instead of at the start of
        the next: the same calls in another grouping, so the same floats, one forward pass fewer per tick. A
        state that went bad is then caught at the tick it went bad, before it is measured and logged.

        :attr:`forces_at_tick` off (the runner, when nothing of the run reads them): the regrouped tick skips
        the acceleration pass at its end, which only the acceleration-stage readings need (the next physics
        step computes that stage under the new controls anyway): one acceleration-stage pass fewer per tick. The
        state, the position- and velocity-stage sensors and the physics are the same bit for
        bit; :meth:`measure` gives NaN for the accelerometer's channels, and a model with another
        acceleration-stage sensor (a disturbance's force sensor) keeps the pass.
        """
        m, d = self.model, self.data
        regroup = controls_only
        if self.disturbances:
            # fill(): numpy's cheapest clear (a slice assignment costs up to 2.5x as much on a 3-vector)
            self._xfrc_v.fill(0.0)
            self.wind_world.fill(0.0)
            if self._rotates_air:
                self.air_rate_world.fill(0.0)
            t = self.time
            for dist in self.disturbances:
                dist.update(self, t)
            if self._air_map is not None:
                set_air_motion(self._wind_v, self._ctrl_mv, self._af_xmat_mv, self.wind_world,
                               self.air_rate_world if self._rotates_air else None, self._air_map)
            else:  # no airframe (the thrust stand): the wind unrotated, no air rotation (__init__)
                set_wind(self._wind_v, self._ctrl_v, None, self.wind_world, self.aero_ids)
            if regroup and self._update_stage < _STAGE_ACC:
                if self._update_stage == _STAGE_VEL:
                    mujoco.mj_fwdVelocity(m, d)  # the passive forces (fuselage drag) under the new wind
                else:
                    regroup = False
        opt = self._opt
        flags = opt.disableflags
        opt.disableflags = flags | _SENSORS_OFF
        try:
            if regroup:
                mujoco.mj_step2(m, d)
                if self.n_substeps > 1:
                    mujoco.mj_step(m, d, self.n_substeps - 1)  # nstep positional: pybind parses no keyword
            else:
                mujoco.mj_step(m, d, nstep=self.n_substeps)
        finally:
            opt.disableflags = flags
        if regroup:
            # the IMU is sampled at the tick: mj_step1's checks and position/velocity stages (and sensors), then
            # the acceleration stage (the accelerometer) under the controls held over the period, as mj_forward
            mujoco.mj_step1(m, d)
            if self._forces_at_tick or self._force_sensors:
                mujoco.mj_forwardSkip(m, d, _STAGE_VEL, 0)
        else:
            mujoco.mj_forward(m, d)  # the state's stages and sensors at the tick

    def check(self) -> str | None:
        """Why the run must stop, or None: NaN, a MuJoCo warning, the rig's stops, a crash or a flip."""
        counts = self._warn_mv
        if any(self._warn_counts(counts)):  # one C call on the good path, the loop only to name the warning
            for i, name in self._warn_ids:
                if counts[i] > 0:
                    return diverged_reason(self.time, name)
        return self.stops.reason(self._qpos_mv, self._af_xmat_mv, self._af_xpos_mv, self.data.time)

    # ------------------------------------------------------------------ sensing
    def measure(self, out: dict | None = None) -> dict:
        """IMU readings at this tick in flight-software units (:data:`rotorlab.sim.sensors.IMU`), with seeded noise
        and bias when enabled: ``phi, theta, psi`` (deg), ``p, q, r`` (deg/s), ``ax, ay, az`` (m/s^2, body FRD;
        NaN with :attr:`forces_at_tick` off), and for outer loops ``x, y, z`` (m, NED) and ``vx, vy, vz`` (m/s,
        NED) from the position sensor (truth, noise-free). Into ``out`` when given (the runner's signal dict), else
        into a new dict; returns it."""
        # one draw per tick for all noisy channels keeps the stream (and so the log) seed-determined
        out = self.imu.sample(self._sd_mv, self._noise if self.sensor_noise else None, out)
        if self._free:
            # the free joint's qpos/qvel are the airframe origin's world position and velocity (NED: y, z flip)
            x, y, z = self._pos_mv.tolist()
            vx, vy, vz = self._vel_mv.tolist()
            out["x"], out["y"], out["z"], out["vx"], out["vy"], out["vz"] = x, -y, -z, vx, -vy, -vz
        return out

    def true_attitude_deg(self) -> tuple[float, float, float]:
        """Airframe (not IMU) roll, pitch, yaw in degrees."""
        return euler_deg(*self._af_xquat_mv.tolist())

    def true_rates_dps(self) -> tuple[float, float, float]:
        """Airframe (not IMU) body rates p, q, r in deg/s (FRD)."""
        if self._free:  # the free joint's angular velocity is already in the airframe (FLU) frame
            (wx, wy, wz), (kx, ky, kz) = self._omega_mv.tolist(), self._gyro_scale
            return wx * kx, wy * ky, wz * kz
        v = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self._airframe, v, 1)
        p, q, r = v[:3].tolist()
        return p * RAD2DEG, -q * RAD2DEG, -r * RAD2DEG

    def load_cell(self) -> tuple[float, float]:
        """Thrust-stand readings: thrust (N, up) and rotor drag torque (N m, counter-clockwise from above)
        (:class:`rotorlab.sim.sensors.LoadCell`)."""
        thrust, torque = self.sensors["load-cell"].read(self._sd_v).tolist()
        return thrust, torque

    def rotor_speed_rad_s(self) -> np.ndarray:
        """Tachometer: rotor speed of each rotor, rad/s (:class:`rotorlab.sim.sensors.Tachometer`)."""
        return self.sensors["tachometer"].read(self.data.act)


def _stable_hash(name: str) -> int:
    # Python's hash() is salted per process; seeds must not be
    return int.from_bytes(name.encode()[:8].ljust(8, b"\0"), "little")
