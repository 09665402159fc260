"""Vehicle specification: the TOML file of physical parameters, read and validated.

A vehicle TOML is the single source of truth for every physical number of a twin; the MJCF is generated
from it (``rotorlab.vehicles.build``) and nothing else in rotorlab restates these numbers.

Frames: MuJoCo's body frame is x forward, y left, z up (FLU). Flight-software angles follow the
aerospace convention (positive pitch = nose up, positive roll = right side down, positive yaw = nose
right), see ``rotorlab.sim.frames``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import numpy as np

from rotorlab.config import Table, read_toml
from rotorlab.errors import ConfigError

RHO_AIR = 1.225  # kg/m^3, ISA sea level
G0 = 9.81  # m/s^2

_S45, _C30 = math.sqrt(0.5), math.sqrt(3.0) / 2.0
#: ``[airframe] frame`` -> (hub directions, unit vectors in the body x-y plane FLU: x forward, y left; spins, +1
#: clockwise seen from above), in rotor order 1..n. ``quad-plus`` is rotorlab's own numbering (1 front, 2 right,
#: 3 rear, 4 left; front/rear clockwise by default). ``quad-x`` and ``hexa-x`` follow PX4's numbering and turning
#: directions: quad-x 1 front-right CCW, 2 rear-left CCW, 3 front-left CW, 4 rear-right CW (PX4-Autopilot
#: ROMFS/px4fmu_common/init.d-posix/airframes/4001_gz_x500, CA_ROTOR0..3, and PX4-gazebo-models
#: models/x500/model.sdf rotor_0..3); hexa-x 1 mid-right CW, 2 mid-left CCW, 3 front-left CW, 4 rear-right CCW,
#: 5 front-right CCW, 6 rear-left CW (PX4-Autopilot src/lib/mixer/MultirotorMixer/geometries/hex_x.toml).
FRAMES = {
    "quad-plus": (((1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.0, 1.0)), (1.0, -1.0, 1.0, -1.0)),
    "quad-x": (((_S45, -_S45), (-_S45, _S45), (_S45, _S45), (-_S45, -_S45)), (-1.0, -1.0, 1.0, 1.0)),
    "hexa-x": (((0.0, -1.0), (0.0, 1.0), (_C30, 0.5), (-_C30, -0.5), (_C30, -0.5), (-_C30, 0.5)),
               (1.0, -1.0, 1.0, -1.0, -1.0, 1.0)),
}
DEFAULT_FRAME = "quad-plus"


@dataclasses.dataclass(frozen=True)
class RotorSpec:
    radius_m: float
    spin: tuple  # +1: clockwise seen from above (its drag torque turns the body counter-clockwise)
    torque_to_thrust_m: float  # rotor drag torque per unit thrust, Q/T
    axial_damping_N_per_mps: float  # dT/dw: thrust lost per m/s of axial (climb) airspeed
    hforce_N_per_mps: float  # in-plane H-force per m/s of in-plane airspeed (flapping)
    flap_arm_m: float  # flapping moment per unit H-force (hub spring moment / thrust-tilt H-force)
    lag_s: tuple  # per rotor: servo (variable pitch) or motor (variable RPM) first-order time constant, s
    delay_s: tuple  # per rotor: transport delay from flight-software command to rotor, s
    # blade-element data for the theory derivatives (``rotorlab.vehicles.rotor_theory``); 0 = not given
    blades: int = 2
    solidity: float = 0.0
    lift_slope_per_rad: float = 0.0
    profile_drag_coefficient: float = 0.0
    lock_number: float = 0.0
    # hingeless hub: the disc tilts against the hub spring (stiffness, damping) and its tilt is damped by the air;
    # 0 stiffness = no flapping element (rigid propeller)
    hub_stiffness_Nm_per_rad: float = 0.0
    hub_spring_damping_Nms_per_rad: float = 0.0
    hub_damping_Nms_per_rad: float = 0.0
    # variable pitch
    thrust_slope_N_per_rad: float = 0.0
    blade_pitch_per_pct_rad: float = 0.0
    rotor_speed_rad_s: float = 0.0
    # variable RPM (TUHH: T = C_T rho A R^2 Omega^2, Omega(b) = a0 b^a1 + a2)
    thrust_coefficient: float = 0.0
    torque_coefficient: float = 0.0
    speed_map: tuple = (0.0, 1.0, 0.0)
    hover_command: float = 0.0
    inertia_kgm2: float = 0.0  # rotor + motor bell about the spin axis (variable RPM: the J_R dOmega/dt yaw reaction)

    @property
    def area_m2(self) -> float:
        return math.pi * self.radius_m**2

    @property
    def k_thrust(self) -> float:
        """Variable RPM: thrust per Omega^2, N/(rad/s)^2 (TUHH eq. 4: T = C_T rho A R^2 Omega^2)."""
        return self.thrust_coefficient * RHO_AIR * self.area_m2 * self.radius_m**2

    def speed(self, b):
        """Variable RPM: rotor speed (rad/s) for command b in [0, 1] (TUHH eq. 3)."""
        a0, a1, a2 = self.speed_map
        return a0 * np.power(np.clip(b, 0.0, 1.0), a1) + a2

    def dspeed_db(self, b):
        a0, a1, _ = self.speed_map
        return a0 * a1 * np.power(b, a1 - 1.0)


@dataclasses.dataclass(frozen=True)
class ImuSpec:
    mass_kg: float
    size_m: float
    offset_m: tuple
    mount_frequency_hz: float
    mount_damping_ratio: float
    gyro_noise_dps: float
    gyro_bias_dps: float
    angle_noise_deg: float
    accel_noise_mps2: float

    @property
    def inertia_kgm2(self) -> float:
        # a uniform cube of side size_m
        return self.mass_kg * self.size_m**2 / 6.0

    @property
    def mount_stiffness(self) -> float:
        return self.inertia_kgm2 * (2 * math.pi * self.mount_frequency_hz) ** 2

    @property
    def mount_damping(self) -> float:
        return 2 * self.mount_damping_ratio * self.inertia_kgm2 * 2 * math.pi * self.mount_frequency_hz


@dataclasses.dataclass(frozen=True)
class CommandLimits:
    """The flight software's saturations (``[commands]`` of the vehicle TOML): the one source of every command
    and rate-set-point limit the simulator, the flight software, the batch runner and the envs apply."""

    limit_pct: float  # roll/pitch axis command, +-%
    rate_limit_dps: float  # roll/pitch rate set-point, +-deg/s
    yaw_limit_pct: float  # yaw axis command, +-%
    yaw_rate_limit_dps: float  # yaw rate set-point, +-deg/s

    KEYS = ("limit_pct", "rate_limit_dps", "yaw_limit_pct", "yaw_rate_limit_dps")


@dataclasses.dataclass(frozen=True)
class RigSpec:
    """One-axis gimbal test-bed: light ring on a damped bearing, airframe on an elastic mount on the ring."""

    ring_inertia_kgm2: float
    bearing_damping_Nms_per_rad: float
    bearing_friction_Nm: float
    mount_stiffness_Nm_per_rad: float
    mount_damping_Nms_per_rad: float
    stop_deg: float


@dataclasses.dataclass(frozen=True)
class PublishedModel:
    """A published identified model of one channel, for calibration tests and documentation."""

    num: tuple
    den: tuple
    delay_s: float
    input: str
    output: str
    source: str


@dataclasses.dataclass(frozen=True)
class VehicleSpec:
    name: str
    description: str
    kind: str  # "variable-pitch" | "variable-rpm"
    path: Path
    mass_kg: float
    inertia_kgm2: tuple  # about the CG, body axes
    arm_m: float
    rotor_height_m: float
    body_size_m: tuple  # fuselage box half-sizes, for geometry and drag
    cp_offset_m: tuple  # centre of pressure relative to the CG (drag moment arm)
    rotor: RotorSpec
    imu: ImuSpec
    rigs: dict  # axis -> RigSpec
    commands: CommandLimits
    published: dict  # name -> PublishedModel
    sources: dict
    #: identification campaign: the band (rad/s) the PRBS is designed to excite (``[campaign]``); None: the
    #: vehicle has no open-loop PRBS campaign band of its own (rotorlab.excitation.ANTEOS_CAMPAIGN's is used)
    campaign_band_rad_s: tuple | None = None
    control_rate_hz: float = 50.0  # flight-software tick rate ([flight_software] rate_hz)
    frame: str = DEFAULT_FRAME  # rotor layout, a key of FRAMES ([airframe] frame)

    @property
    def control_dt_s(self) -> float:
        """Flight-software period, s."""
        return 1.0 / self.control_rate_hz

    @property
    def command_limit_pct(self) -> float:
        """Roll/pitch axis command saturation, % (``commands.limit_pct``)."""
        return self.commands.limit_pct

    @property
    def n_rotors(self) -> int:
        return len(self.rotor.spin)

    def rotor_positions(self) -> np.ndarray:
        """Rotor hub positions (n, 3) in the body frame (FLU): ``arm_m`` along each of the frame's hub directions,
        ``rotor_height_m`` above the CG, in rotor order (:data:`FRAMES`)."""
        l, h = self.arm_m, self.rotor_height_m
        return np.array([[l * x, l * y, h] for x, y in FRAMES[self.frame][0]], dtype=float)

    def axis_lever_m(self, axis: str) -> float:
        """Moment arm of one % of ``axis`` command (``roll`` or ``pitch``) per unit of rotor thrust change, m.

        The flight software's mixer gives rotor i the share ``0.5 |d_i| / max|d|`` of an axis command, d_i its
        hub's distance from the axis (``rotorlab.sim.control.mixer``), so the moment per unit thrust change is
        ``sum_i |d_i| 0.5 |d_i| / max|d|``: ``arm_m`` for the plus layout (the opposite pair, half each),
        ``sqrt(2) arm_m`` for quad-x (four rotors at ``arm/sqrt(2)``), ``1.5 arm_m`` (roll) and
        ``sqrt(3) arm_m`` (pitch) for hexa-x.

        Examples
        --------
        >>> from rotorlab.vehicles import load_vehicle
        >>> v = load_vehicle("tuhh-quad")
        >>> v.axis_lever_m("pitch") == v.arm_m
        True
        """
        d = np.abs(self.rotor_positions()[:, {"roll": 1, "pitch": 0}[axis]])
        return float(sum(di * (0.5 * di / d.max()) for di in d))

    @property
    def hover_thrust_N(self) -> float:
        return self.mass_kg * G0 / self.n_rotors

    # -- rotor command (%) -> MuJoCo ctrl and its derivative, the "ESC / servo" of the twin --
    def hover_ctrl(self) -> float:
        r = self.rotor
        if self.kind == "variable-pitch":
            return self.hover_thrust_N / r.thrust_slope_N_per_rad  # blade pitch, rad (zero-lift at 0)
        return float(r.speed(r.hover_command)) ** 2  # Omega^2, (rad/s)^2

    def command_to_ctrl(self, cmd_pct):
        """Rotor commands in % to actuator ctrl (blade pitch in rad, or Omega^2 in (rad/s)^2).

        Variable pitch: 1 % is ``blade_pitch_per_pct_rad`` of blade pitch (zero thrust at 0 %). Variable RPM:
        the ESC command is b = command / 100 (TUHH's b in [0, 1]).
        """
        cmd = np.asarray(cmd_pct, dtype=float)
        k = self.ctrl_per_pct
        if k is not None:
            return cmd * k
        return self.rotor.speed(cmd / 100.0) ** 2

    def command_to_ctrl_floats(self, cmd_pct, scratch=None) -> list:
        """:meth:`command_to_ctrl` of one simulation's rotor commands (a sequence of floats, %) as a list of floats,
        the same values bit for bit: the simulator writes them every tick, where numpy's per-call cost on four
        rotors is several times the arithmetic. The clip, the affine map and the square are the same IEEE
        operations in floats; the power stays numpy's (its SIMD kernel may round differently from libm's ``pow``),
        taken in the buffers of ``scratch`` (:meth:`ctrl_scratch` for as many commands) where the caller keeps
        them from tick to tick, so a tick builds no array.

        Examples
        --------
        >>> from rotorlab.vehicles import load_vehicle
        >>> v = load_vehicle("tuhh-quad")
        >>> v.command_to_ctrl_floats([50.0, 120.0]) == v.command_to_ctrl([50.0, 120.0]).tolist()
        True
        """
        k = self.ctrl_per_pct
        if k is not None:
            return [v * k for v in cmd_pct]
        a0, _, a2 = self.rotor.speed_map
        if scratch is None or len(scratch[2]) != len(cmd_pct):
            scratch = self.ctrl_scratch(len(cmd_pct))
        b, power, b_view, power_view, exponent = scratch
        # b = command / 100 clipped to [0, 1] as np.clip does (a NaN stays NaN)
        for i, v in enumerate(cmd_pct):
            x = v / 100.0
            b_view[i] = 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)
        np.power(b, exponent, power)
        out = []
        for x in power_view.tolist():
            w = a0 * x + a2
            out.append(w * w)
        return out

    def ctrl_scratch(self, n: int) -> tuple:
        """Buffers for :meth:`command_to_ctrl_floats` of ``n`` commands, one set per caller (a simulator): the
        clipped commands and their power as arrays and memoryviews, and the exponent as a numpy scalar."""
        b, power = np.zeros(n), np.zeros(n)
        return b, power, memoryview(b), memoryview(power), np.float64(self.rotor.speed_map[1])

    @functools.cached_property  # asked every control tick (command_to_ctrl_floats); the spec is frozen
    def ctrl_per_pct(self) -> float | None:
        """Slope of :meth:`command_to_ctrl` where the map is linear (variable pitch: blade pitch in rad per %),
        None where it is not (variable RPM)."""
        return self.rotor.blade_pitch_per_pct_rad if self.kind == "variable-pitch" else None

    def dctrl_dcommand(self) -> float:
        """d ctrl / d command at hover trim (per %)."""
        r = self.rotor
        if self.kind == "variable-pitch":
            return r.blade_pitch_per_pct_rad
        b = r.hover_command
        return 2.0 * float(r.speed(b)) * float(r.dspeed_db(b)) / 100.0

    @property
    def hover_collective_pct(self) -> float:
        """Collective at hover on the flight software's absolute scale: blade pitch in units of
        ``blade_pitch_per_pct_rad`` (variable pitch), or 100 b_H (variable RPM)."""
        if self.kind == "variable-pitch":
            return self.hover_ctrl() / self.rotor.blade_pitch_per_pct_rad
        return 100.0 * self.rotor.hover_command

    @property
    def thrust_exponent(self) -> float:
        """Local exponent n of thrust ~ collective^n at hover (1 for blade pitch, about 1.7 for TUHH RPM)."""
        if self.kind == "variable-pitch":
            return 1.0
        r = self.rotor
        b = r.hover_command
        return 2.0 * float(r.dspeed_db(b)) * b / float(r.speed(b))

    def thrust_gain(self) -> float:
        """Actuator gain: N per unit of ctrl."""
        r = self.rotor
        return r.thrust_slope_N_per_rad if self.kind == "variable-pitch" else r.k_thrust


# physical plausibility bounds: a gram-scale to a tonne-scale multirotor; anything outside is a typo (1e-12 kg,
# a missing exponent) that would otherwise reach MuJoCo's mass checks as a traceback
MASS_RANGE_KG = (1e-3, 1e3)
INERTIA_MIN_KGM2 = 1e-9
# servo/motor lags and transport delays of flying multirotors are tens of ms; a second is already no aircraft,
# and MuJoCo's delay buffer grows with delay / physics step
MAX_LAG_DELAY_S = 1.0
#: magnitude window of every non-zero number of a vehicle file (SI units): the shipped vehicles span 7e-5
#: (a rotor's inertia, kg m^2) to 701 (a speed map, rad/s); 1e300 or 1e-300 reached MuJoCo or overflowed
MAGNITUDE_RANGE = (1e-9, 1e6)


def _per_rotor(r: Table, key: str, n: int, lo_open: bool, hi: float | None = None) -> tuple:
    """A number shared by the frame's ``n`` rotors, or a list of ``n`` in rotor order (:data:`FRAMES`)."""
    if isinstance(r.data.get(key), list):
        return r.vec(key, n, lo=0.0, lo_open=lo_open, hi=hi)
    return (r.num(key, lo=0.0, lo_open=lo_open, hi=hi),) * n


def _published(rd: Table | None) -> dict:
    out = {}
    if rd is None:
        return out
    for key in rd.keys():
        t = rd.table(key)
        out[key] = PublishedModel(t.vec("num"), t.vec("den"), t.num("delay_s", lo=0.0),
                                  t.str("input"), t.str("output"), t.str("source"))
    return out


def _commands(c: Table) -> CommandLimits:
    return CommandLimits(**{k: c.num(k, lo=0.0, lo_open=True) for k in CommandLimits.KEYS})


def check_delay_steps(v: VehicleSpec, physics_dt_s: float) -> None:
    """Every rotor delay must be a whole number of physics steps: MuJoCo's actuator history realises it, and a
    rounded delay would silently change the plant."""
    for d in v.rotor.delay_s:
        k = d / physics_dt_s
        if abs(k - round(k)) > 1e-6:
            raise ConfigError("the transport delay is realised by MuJoCo's actuator history buffer",
                              file=v.path, field="rotor.delay_s",
                              expected=f"a multiple of the physics step {physics_dt_s} s", got=d)


def check_rate_steps(rate_hz: float, physics_dt_s: float, src) -> None:
    """The flight-software period ``1 / rate_hz`` must be a whole number (>= 1) of physics steps: the simulator
    steps whole physics steps per tick (``rate_hz = 333`` reached the simulator as a traceback)."""
    k = 1.0 / (rate_hz * physics_dt_s)
    if abs(k - round(k)) > 1e-6 or round(k) < 1:
        raise ConfigError("the simulator steps whole physics steps per flight-software tick", file=src,
                          field="flight_software.rate_hz",
                          expected=f"a rate whose period is a multiple of the physics step {physics_dt_s} s "
                                   f"(e.g. {1 / (max(1, round(k)) * physics_dt_s):g} Hz)", got=rate_hz)


def _check_hover(spec: VehicleSpec, a: Table, r: Table) -> None:
    """Variable pitch: the collective that carries the weight must lie within the command range (0, 100] %;
    checked here, on the file's fields, not later on the derived hover collective."""
    if spec.kind != "variable-pitch":
        return
    col = spec.hover_collective_pct
    if not 0 < col <= 100:
        raise a.error("mass_kg", "the rotors cannot carry this mass within the collective range: hover needs "
                      f"mass_kg * 9.81 / {spec.n_rotors} / rotor.thrust_slope_N_per_rad / rotor.blade_pitch_per_pct_rad "
                      f"= {col:.4g} % of collective",
                      expected=f"a mass of at most {spec.mass_kg * 100 / col:.4g} kg with these rotor.* values "
                               "(or a larger rotor.thrust_slope_N_per_rad or rotor.blade_pitch_per_pct_rad)",
                      got=spec.mass_kg)


def _check_inertia(a: Table, inertia: tuple) -> None:
    ixx, iyy, izz = inertia
    # principal moments of any rigid body obey the triangle inequality (I_a + I_b >= I_c)
    for i, (x, y, z) in enumerate(((iyy, izz, ixx), (ixx, izz, iyy), (ixx, iyy, izz))):
        if x + y < z * (1 - 1e-9):
            raise a.error("inertia_kgm2", "principal moments of a rigid body obey I_a + I_b >= I_c",
                          expected=f"I_{'xyz'[i]} <= sum of the other two", got=list(inertia))


def parse_vehicle(data: dict, src, physics_dt_s: float | None = None) -> VehicleSpec:
    rd = Table(src, data, magnitude=MAGNITUDE_RANGE)
    v = rd.table("vehicle")
    kind = v.str("kind", choices=("variable-pitch", "variable-rpm"))
    a = rd.table("airframe")
    frame = a.str("frame", DEFAULT_FRAME, choices=tuple(FRAMES))
    n = len(FRAMES[frame][1])
    r = rd.table("rotor")
    spin = r.vec("spin", n) if "spin" in r else FRAMES[frame][1]
    if any(s not in (-1.0, 1.0) for s in spin):
        raise r.error("spin", expected=f"{n} values, each +1 or -1", got=list(spin))
    common = dict(
        radius_m=r.num("radius_m", lo=0.0, lo_open=True),
        spin=spin,
        torque_to_thrust_m=r.num("torque_to_thrust_m", lo=0.0),
        axial_damping_N_per_mps=r.num("axial_damping_N_per_mps", lo=0.0),
        hforce_N_per_mps=r.num("hforce_N_per_mps", lo=0.0),
        flap_arm_m=r.num("flap_arm_m", lo=0.0),
        lag_s=_per_rotor(r, "lag_s", n, lo_open=True, hi=MAX_LAG_DELAY_S),
        delay_s=_per_rotor(r, "delay_s", n, lo_open=False, hi=MAX_LAG_DELAY_S),
        blades=r.num("blades", 2, lo=2),
        solidity=r.num("solidity", 0.0, lo=0.0, hi=1.0),
        lift_slope_per_rad=r.num("lift_slope_per_rad", 0.0, lo=0.0),
        profile_drag_coefficient=r.num("profile_drag_coefficient", 0.0, lo=0.0),
        lock_number=r.num("lock_number", 0.0, lo=0.0),
        hub_stiffness_Nm_per_rad=r.num("hub_stiffness_Nm_per_rad", 0.0, lo=0.0),
        hub_spring_damping_Nms_per_rad=r.num("hub_spring_damping_Nms_per_rad", 0.0, lo=0.0),
        hub_damping_Nms_per_rad=r.num("hub_damping_Nms_per_rad", 0.0, lo=0.0),
    )
    if common["blades"] != int(common["blades"]):
        raise ConfigError(file=src, field="rotor.blades", expected="a whole number of blades >= 2", got=r.data["blades"])
    common["blades"] = int(common["blades"])
    if common["hub_stiffness_Nm_per_rad"] > 0:
        for key in ("solidity", "lift_slope_per_rad", "lock_number"):
            if not common[key] > 0:
                raise ConfigError("a hingeless hub needs the blade data its disc inertia comes from", file=src,
                                  field=f"rotor.{key}", expected="a value > 0", got=r.data.get(key))
    if kind == "variable-pitch":
        rotor = RotorSpec(**common, thrust_slope_N_per_rad=r.num("thrust_slope_N_per_rad", lo=0.0, lo_open=True),
                          blade_pitch_per_pct_rad=r.num("blade_pitch_per_pct_rad", lo=0.0, lo_open=True),
                          rotor_speed_rad_s=r.num("rotor_speed_rad_s", lo=0.0, lo_open=True))
    else:
        rotor = RotorSpec(**common, thrust_coefficient=r.num("thrust_coefficient", lo=0.0, lo_open=True),
                          torque_coefficient=r.num("torque_coefficient", lo=0.0, lo_open=True),
                          speed_map=r.vec("speed_map", 3),
                          hover_command=r.num("hover_command", lo=0.0, lo_open=True, hi=1.0),
                          inertia_kgm2=r.num("inertia_kgm2", 0.0, lo=0.0))
    i = rd.table("imu")
    imu = ImuSpec(
        mass_kg=i.num("mass_kg", lo=0.0, lo_open=True), size_m=i.num("size_m", lo=0.0, lo_open=True),
        offset_m=i.vec("offset_m", 3), mount_frequency_hz=i.num("mount_frequency_hz", lo=0.0, lo_open=True),
        mount_damping_ratio=i.num("mount_damping_ratio", lo=0.0),
        gyro_noise_dps=i.num("gyro_noise_dps", lo=0.0), gyro_bias_dps=i.num("gyro_bias_dps", lo=0.0),
        angle_noise_deg=i.num("angle_noise_deg", lo=0.0), accel_noise_mps2=i.num("accel_noise_mps2", lo=0.0),
    )
    rigs = {}
    rg = rd.table("rig", required=False)
    if rg is not None:
        for axis in rg.keys():
            if axis not in ("pitch", "roll"):
                raise rg.error(axis, "unknown rig axis", expected="'pitch' or 'roll'", got=axis)
            t = rg.table(axis)
            rigs[axis] = RigSpec(
                ring_inertia_kgm2=t.num("ring_inertia_kgm2", lo=0.0, lo_open=True),
                bearing_damping_Nms_per_rad=t.num("bearing_damping_Nms_per_rad", lo=0.0),
                bearing_friction_Nm=t.num("bearing_friction_Nm", 0.0, lo=0.0),
                mount_stiffness_Nm_per_rad=t.num("mount_stiffness_Nm_per_rad", lo=0.0, lo_open=True),
                mount_damping_Nms_per_rad=t.num("mount_damping_Nms_per_rad", lo=0.0),
                stop_deg=t.num("stop_deg", lo=0.0, lo_open=True, hi=90.0),
            )
    fsw = rd.table("flight_software", required=False)
    rate_hz = fsw.num("rate_hz", 50.0, lo=0.0, lo_open=True) if fsw is not None else 50.0
    if physics_dt_s:
        check_rate_steps(rate_hz, physics_dt_s, src)
    srcs = rd.table("sources", required=False, free=True)
    inertia = a.vec("inertia_kgm2", 3, lo=INERTIA_MIN_KGM2)
    _check_inertia(a, inertia)
    spec = VehicleSpec(
        name=v.name("name"), description=v.str("description", ""), kind=kind, path=Path(src),
        mass_kg=a.num("mass_kg", lo=MASS_RANGE_KG[0], hi=MASS_RANGE_KG[1]), inertia_kgm2=inertia,
        arm_m=a.num("arm_m", lo=0.0, lo_open=True), rotor_height_m=a.num("rotor_height_m", 0.0),
        body_size_m=a.vec("body_size_m", 3, lo=0.0, lo_open=True), cp_offset_m=a.vec("cp_offset_m", 3, (0, 0, 0)),
        rotor=rotor, imu=imu, rigs=rigs,
        commands=_commands(rd.table("commands")),
        published=_published(rd.table("published", required=False)),
        sources=dict(srcs.data) if srcs is not None else {}, control_rate_hz=rate_hz,
        campaign_band_rad_s=_campaign_band(rd.table("campaign", required=False)), frame=frame,
    )
    rd.check_unknown()
    if kind == "variable-rpm":
        _check_rpm_thrust(spec, r)
    _check_hover(spec, a, r)
    if physics_dt_s:
        check_delay_steps(spec, physics_dt_s)
    return spec


#: a variable-RPM twin's hover command must give its weight: MuJoCo would otherwise start it climbing or sinking
HOVER_THRUST_TOLERANCE = 0.01


def _check_rpm_thrust(v: VehicleSpec, r: Table) -> None:
    """A variable-RPM vehicle must be able to fly: its speed map must rise, full command must lift more than the
    weight, and the hover command must hold it (within :data:`HOVER_THRUST_TOLERANCE`)."""
    rot = v.rotor
    weight_N = v.mass_kg * G0
    a0, a1, _ = rot.speed_map
    if not (a0 > 0 and a1 > 0 and float(rot.speed(rot.hover_command)) > 0):
        raise r.error("speed_map", "the rotor speed Omega(b) = a0 b^a1 + a2 must rise with b and be positive at hover",
                      expected="a0 > 0, a1 > 0, Omega(b_H) > 0", got=list(rot.speed_map))
    full_N = v.n_rotors * rot.k_thrust * float(rot.speed(1.0)) ** 2
    if full_N <= weight_N:
        raise r.error("speed_map", "the rotors cannot lift the vehicle: n k_T Omega(1)^2 must exceed m g",
                      expected=f"thrust at full command > weight {weight_N:.4g} N", got=f"{full_N:.4g} N")
    hover_N = v.n_rotors * rot.k_thrust * float(rot.speed(rot.hover_command)) ** 2
    if abs(hover_N / weight_N - 1.0) > HOVER_THRUST_TOLERANCE:
        x = (math.sqrt(weight_N / (v.n_rotors * rot.k_thrust)) - rot.speed_map[2]) / a0
        raise r.error("hover_command", "the hover command must hold the weight: n k_T Omega(b_H)^2 = m g",
                      expected=f"b_H = {x ** (1.0 / a1):.4f} (thrust {weight_N:.4g} N)" if x > 0 else
                      f"thrust {weight_N:.4g} N (no command gives it: the idle speed a2 is above hover)",
                      got=f"{rot.hover_command} (thrust {hover_N:.4g} N)")


def _campaign_band(c: Table | None) -> tuple | None:
    if c is None:
        return None
    band = c.vec("band_rad_s", 2, lo=0.0)
    if not band[0] < band[1]:
        raise c.error("band_rad_s", expected="[low, high] with low < high", got=list(band))
    return band


def load_vehicle_file(path, physics_dt_s: float | None = None) -> VehicleSpec:
    path = Path(path)
    return parse_vehicle(read_toml(path, "vehicle"), path, physics_dt_s)
