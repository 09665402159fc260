"""Position and altitude hold: the outer loops of free flight, on top of the attitude cascade.

Frames: world NED (x north, y east, z down, metres; altitude ``h = -z``), body FRD (see
:mod:`rotorlab.sim.control.mixer`), heading ``psi`` in deg, positive nose right (from north towards east).
A z-up simulator converts with ``(x, y, z)_NED = (x, -y, -z)_zup`` and the same for velocities.

Horizontal: position P -> velocity set-point (saturated), velocity PI -> acceleration set-point (world), rotated
into the heading frame and turned into attitude set-points by small-angle hover kinematics (to accelerate forward
pitch nose down: ``theta_ref = -atan(a_fwd / g)``; to accelerate right roll right: ``phi_ref = atan(a_right / g)``),
saturated at ``max_tilt_deg``.
Vertical: altitude P -> climb-rate set-point (saturated), climb-rate PI -> vertical acceleration, turned into a
collective command around hover, ``col = (hover + a_up * collective_per_mps2) / (cos(phi) cos(theta))``.
Heading hold is the outer loop of the yaw cascade (:class:`~rotorlab.sim.control.cascade.AttitudeController`).
"""

from __future__ import annotations

import dataclasses
import math

from rotorlab.errors import ConfigError
from rotorlab.gains import LoopGains
from rotorlab.sim.control.pid import DiscretePID
from rotorlab.sim.frames import RAD2DEG

G_MPS2 = 9.80665
_DEG = math.pi / 180.0
_REF_MASS_KG = 5.0  # the P2-A2 MTOW: the mass the default bandwidths are chosen for


@dataclasses.dataclass(frozen=True)
class PositionGains:
    """Outer-loop gains (all plain floats, so the table round-trips through TOML).

    Attributes
    ----------
    pos_kp : float
        Horizontal position error -> velocity set-point, 1/s.
    vel_kp, vel_ki : float
        Velocity error -> acceleration set-point, 1/s and 1/s^2.
    max_vel_mps, max_tilt_deg : float
        Horizontal velocity set-point and attitude set-point saturations.
    alt_kp : float
        Altitude error -> climb-rate set-point, 1/s.
    vz_kp, vz_ki : float
        Climb-rate error -> vertical acceleration, 1/s and 1/s^2.
    max_climb_mps, max_accel_up_mps2 : float
        Climb-rate and vertical-acceleration saturations.
    hover_collective_pct : float
        Collective at hover, %.
    collective_per_mps2 : float
        Collective change per vertical acceleration, % per m/s^2.
    """

    pos_kp: float = 0.8
    vel_kp: float = 2.0
    vel_ki: float = 0.4
    max_vel_mps: float = 3.0
    max_tilt_deg: float = 15.0
    alt_kp: float = 1.0
    vz_kp: float = 3.0
    vz_ki: float = 1.0
    max_climb_mps: float = 1.5
    max_accel_up_mps2: float = 4.0
    hover_collective_pct: float = 60.0
    collective_per_mps2: float = 60.0 / G_MPS2

    @classmethod
    def for_vehicle(cls, mass_kg: float, hover_collective_pct: float, thrust_exponent: float = 1.0,
                    **overrides) -> PositionGains:
        """Defaults scaled to a vehicle.

        Bandwidths scale with Froude similarity: size ~ mass^(1/3), time ~ sqrt(size / g) ~ mass^(1/6), so
        frequencies ~ mass^(-1/6), relative to the 5 kg P2-A2. The collective gain follows from hover trim:
        with thrust ~ command^n around hover (n = 1 for variable blade pitch near hover, n = 2 for variable
        RPM), dT/dcol = n m g / col_hover, so the command per m/s^2 is ``col_hover / (n g)``, independent of mass.
        """
        if not mass_kg > 0:
            raise ConfigError(field="mass_kg", expected="a mass > 0 kg", got=mass_kg)
        if not 0 < hover_collective_pct <= 100:
            raise ConfigError(field="hover_collective_pct", expected="a value in (0, 100] %", got=hover_collective_pct)
        if not thrust_exponent > 0:
            raise ConfigError(field="thrust_exponent", expected="a value > 0", got=thrust_exponent)
        s = (mass_kg / _REF_MASS_KG) ** (-1.0 / 6.0)
        base = cls()
        vals = dict(
            pos_kp=base.pos_kp * s, vel_kp=base.vel_kp * s, vel_ki=base.vel_ki * s * s,
            alt_kp=base.alt_kp * s, vz_kp=base.vz_kp * s, vz_ki=base.vz_ki * s * s,
            hover_collective_pct=float(hover_collective_pct),
            collective_per_mps2=float(hover_collective_pct) / (thrust_exponent * G_MPS2),
        )
        vals.update(overrides)
        return cls.from_dict(vals)

    @classmethod
    def from_dict(cls, data: dict, src="<position gains>") -> PositionGains:
        """Validate a TOML table; unknown keys and non-positive values are errors naming the field."""
        known = {f.name for f in dataclasses.fields(cls)}
        for k, v in data.items():
            if k not in known:
                raise ConfigError(file=src, field=k, expected=f"one of {sorted(known)}", got=k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(file=src, field=k, expected="a finite number >= 0", got=v)
        return cls(**{k: float(v) for k, v in data.items()})

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


class PositionHold:
    """Horizontal position hold -> roll/pitch set-points (deg).

    ``step(x_ref, y_ref, x, y, vx, vy, psi_deg) -> (phi_ref_deg, theta_ref_deg)`` with NED positions (m) and
    velocities (m/s).
    """

    def __init__(self, gains: PositionGains, dt: float):
        self.gains = gains
        amax = G_MPS2 * math.tan(math.radians(gains.max_tilt_deg))
        vel = LoopGains(kp=gains.vel_kp, ki=gains.vel_ki)
        # the velocity PIs saturate at the acceleration a max tilt can give; clamping anti-windup
        self.vx = DiscretePID(vel, dt, -amax, amax)
        self.vy = DiscretePID(vel, dt, -amax, amax)

    def reset(self) -> None:
        self.vx.reset()
        self.vy.reset()

    def step(self, x_ref: float, y_ref: float, x: float, y: float, vx: float, vy: float,
             psi_deg: float) -> tuple[float, float]:
        # saturations written out as comparisons: a helper call each costs more than the arithmetic, every tick
        g = self.gains
        kp, vmax, tilt_max = g.pos_kp, g.max_vel_mps, g.max_tilt_deg
        v = kp * (x_ref - x)
        vx_ref = vmax if v > vmax else (-vmax if v < -vmax else v)
        v = kp * (y_ref - y)
        vy_ref = vmax if v > vmax else (-vmax if v < -vmax else v)
        ax = self.vx.step(vx_ref, vx)
        ay = self.vy.step(vy_ref, vy)
        # math.radians/degrees are these very products (CPython multiplies by the same constants), without a call
        psi = psi_deg * _DEG
        c, s = math.cos(psi), math.sin(psi)
        a_fwd = c * ax + s * ay
        a_right = -s * ax + c * ay
        v = -(math.atan2(a_fwd, G_MPS2) * RAD2DEG)
        theta_ref = tilt_max if v > tilt_max else (-tilt_max if v < -tilt_max else v)
        v = math.atan2(a_right, G_MPS2) * RAD2DEG
        phi_ref = tilt_max if v > tilt_max else (-tilt_max if v < -tilt_max else v)
        return phi_ref, theta_ref


class AltitudeHold:
    """Altitude hold -> collective (%).

    ``step(h_ref, h, vh, phi_deg, theta_deg) -> collective_pct`` with altitude ``h = -z`` (m) and climb rate
    ``vh = -vz`` (m/s).
    """

    def __init__(self, gains: PositionGains, dt: float):
        self.gains = gains
        self.vz = DiscretePID(LoopGains(kp=gains.vz_kp, ki=gains.vz_ki), dt, -gains.max_accel_up_mps2,
                              gains.max_accel_up_mps2)

    def reset(self) -> None:
        self.vz.reset()

    def step(self, h_ref: float, h: float, vh: float, phi_deg: float, theta_deg: float) -> float:
        g = self.gains
        v, vmax = g.alt_kp * (h_ref - h), g.max_climb_mps
        vh_ref = vmax if v > vmax else (-vmax if v < -vmax else v)
        a_up = self.vz.step(vh_ref, vh)
        # tilt compensation, limited to 60 deg of tilt so a tumbling vehicle does not get a huge collective
        tilt = math.cos(phi_deg * _DEG) * math.cos(theta_deg * _DEG)
        tilt = 0.5 if tilt < 0.5 else tilt
        return (g.hover_collective_pct + g.collective_per_mps2 * a_up) / tilt
