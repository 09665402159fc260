"""The rigid bodies a vehicle is built from (airframe, rotor hub discs, IMU board): their masses and principal
inertias, computed once here for the MJCF builder (:mod:`rotorlab.vehicles.build`), the parameter draws
(:mod:`rotorlab.sim.randomize`) and the checks that keep a vehicle physical.

The vehicle TOML gives the *whole* vehicle's mass and inertia about its CG; the airframe body is what remains
after the IMU board's mass and the rotor discs' share (their parallel-axis terms plus their own tilt/spin
inertia) come off. A whole vehicle can satisfy the triangle inequality ``A + B >= C`` while its airframe body,
with the discs' share removed, does not: MuJoCo then refuses to compile the model ("inertia must satisfy
A + B >= C"). :func:`unphysical` says so before a model is built.

No MuJoCo import: the draws and the vehicle checks run without it.

Examples
--------
>>> from rotorlab.vehicles import load_vehicle
>>> from rotorlab.vehicles.bodies import airframe_inertial, unphysical
>>> v = load_vehicle("anteos-p2a2")
>>> mass_kg, inertia_kgm2 = airframe_inertial(v)
>>> bool(inertia_kgm2[2] < v.inertia_kgm2[2]), unphysical(v)
(True, None)
"""

from __future__ import annotations

import numpy as np

from .rotor_theory import hover
from .spec import VehicleSpec

__all__ = ["hub_inertia", "airframe_inertial", "unphysical"]


def hub_inertia(v: VehicleSpec):
    """(blade mass of one rotor kg, disc tilt inertia kg m^2, spin-axis inertia kg m^2), or None for a rigid rotor.

    Uniform blades: ``I_b = m_b R^2 / 3`` with ``I_b = rho a c R^4 / gamma`` (the Lock number's definition); the
    disc of N blades has the tilt inertia ``(N/2) I_b`` about any diameter and ``N I_b`` about the shaft.
    """
    r = v.rotor
    if r.hub_stiffness_Nm_per_rad <= 0.0:
        return None
    i_b = hover(v).blade_flap_inertia_kgm2
    return r.blades * 3.0 * i_b / r.radius_m**2, r.blades / 2.0 * i_b, r.blades * i_b


def airframe_inertial(v: VehicleSpec) -> tuple[float, tuple]:
    """Mass (kg) and principal inertia (kg m^2, body axes, about the vehicle CG) of the airframe body: the
    whole vehicle's less the IMU board's mass and the rotor discs' mass and inertia share."""
    hub = hub_inertia(v)
    disc_mass = hub[0] if hub else 0.0
    mass_kg = v.mass_kg - v.imu.mass_kg - disc_mass * v.n_rotors
    disc_inertia = np.zeros(3)
    if hub:
        for p in v.rotor_positions():
            disc_inertia += disc_mass * (p @ p - p**2) + np.array([hub[1], hub[1], hub[2]])
    return float(mass_kg), tuple(float(j) for j in np.asarray(v.inertia_kgm2, float) - disc_inertia)


def unphysical(v: VehicleSpec) -> tuple[str, str] | None:
    """``(field, why)`` when the airframe body of ``v`` is no rigid body, None when it is one: a mass or principal
    moment that is not positive, or moments that break the triangle inequality ``A + B >= C``. ``field`` is the
    vehicle file's field to change (``airframe.mass_kg`` or ``airframe.inertia_kgm2``). The comparison is exact,
    as MuJoCo's compiler makes it (the hub discs and the IMU board are rigid by construction)."""
    mass_kg, inertia = airframe_inertial(v)
    if not mass_kg > 0.0:
        return "airframe.mass_kg", (f"airframe body mass {mass_kg:.6g} kg <= 0 (vehicle {v.mass_kg:.6g} kg less "
                                    "IMU board and rotor discs)")
    if not min(inertia) > 0.0:
        return "airframe.inertia_kgm2", f"airframe body inertia {_fmt(inertia)} kg m^2 has a moment <= 0"
    a, b, c = sorted(inertia)
    if a + b < c:
        return "airframe.inertia_kgm2", (f"airframe body inertia {_fmt(inertia)} kg m^2 (the vehicle's less the "
                                         "rotor discs') breaks A + B >= C")
    return None


def _fmt(x) -> list:
    return [float(f"{j:.6g}") for j in x]
