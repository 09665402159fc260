"""The twin's true small-signal model about its hover trim, from ``mujoco.mjd_transitionFD``.

This is the ground truth identification is scored against: a discrete ``control.StateSpace`` at the
physics step, in flight-software units, from a named axis command (%, through the mixer and the rotor
command map) to a named sensor channel.
"""

from __future__ import annotations

import control as ct
import mujoco
import numpy as np

from rotorlab.errors import UnknownNameError
from rotorlab.lti import c2d_zoh, d2c_zoh
from rotorlab.scenes import PREFIX, Scene, build_scene
from rotorlab.sim.frames import RAD2DEG
from rotorlab.sim.simulator import CONTROL_DT_S, vehicle_mixer

__all__ = ["linearize", "truth_model", "INPUTS", "OUTPUTS", "UNITS"]

INPUTS = {"collective": 0, "roll": 1, "pitch": 2, "yaw": 3}
# sensor channel -> (sensor name, component, scale); FLU -> aerospace sign flips and rad -> deg folded in
OUTPUTS = {
    "gyro_roll": ("gyro", 0, RAD2DEG),
    "gyro_pitch": ("gyro", 1, -RAD2DEG),
    "gyro_yaw": ("gyro", 2, -RAD2DEG),
    # small-angle attitude from the IMU quaternion: angle = 2 * vector part
    "angle_roll": ("imu_quat", 1, 2 * RAD2DEG),
    "angle_pitch": ("imu_quat", 2, -2 * RAD2DEG),
    "angle_yaw": ("imu_quat", 3, -2 * RAD2DEG),
    "accel_x": ("accel", 0, 1.0),
    "accel_y": ("accel", 1, -1.0),
    "accel_z": ("accel", 2, -1.0),
}
UNITS = {"gyro": "deg/s", "angle": "deg", "accel": "m/s^2"}


def linearize(scene="pitch-rig", vehicle="anteos-p2a2", input="pitch", output="gyro_pitch", delay: bool = True,
              eps: float = 1e-6) -> ct.StateSpace:
    """Linearise the twin about its hover keyframe.

    Parameters
    ----------
    scene, vehicle : str or Scene / VehicleSpec
    input : str or sequence of str
        Axis command channel(s): ``collective``, ``roll``, ``pitch``, ``yaw`` (%).
    output : str or sequence of str
        Sensor channel(s): ``gyro_*`` (deg/s), ``angle_*`` (deg), ``accel_*`` (m/s^2) with * in roll/pitch/yaw
        (x/y/z for accel), aerospace signs.
    delay : bool
        Include the rotors' transport delay as exact shift registers (``False``: delay removed).
    eps : float
        Finite-difference step.

    Returns
    -------
    control.StateSpace
        Discrete, ``dt`` = physics step (s).
    """
    inputs = [input] if isinstance(input, str) else list(input)
    outputs = [output] if isinstance(output, str) else list(output)
    for i in inputs:
        if i not in INPUTS:
            raise UnknownNameError("input channel", i, INPUTS)
    for o in outputs:
        if o not in OUTPUTS:
            raise UnknownNameError("output channel", o, OUTPUTS)
    sc = scene if isinstance(scene, Scene) else build_scene(scene, vehicle)
    v = sc.vehicle
    dt = float(sc.model.opt.timestep)
    # Finite differences need the instantaneous path (mjd_transitionFD rejects history buffers); the
    # transport delay is put back exactly below as shift registers.
    saved_delay = sc.model.actuator_delay.copy()
    spec = sc.spec.copy()
    for act in spec.actuators:
        act.nsample = 0
        act.delay = 0.0
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "hover"))
    mujoco.mj_forward(m, d)
    nx = 2 * m.nv + m.na
    A = np.zeros((nx, nx))
    B = np.zeros((nx, m.nu))
    C = np.zeros((m.nsensordata, nx))
    D = np.zeros((m.nsensordata, m.nu))
    mujoco.mjd_transitionFD(m, d, eps, True, A, B, C, D)

    thrust = sc.thrust_actuators
    mix = vehicle_mixer(v).matrix[: len(thrust)] * v.dctrl_dcommand()  # d ctrl / d axis command, per rotor
    cols = [INPUTS[i] for i in inputs]
    Wrot = mix[:, cols]  # (n_rotors, n_inputs)

    rows, scales = [], []
    for o in outputs:
        sname, comp, scale = OUTPUTS[o]
        sid = -1
        for full in (f"{PREFIX}{sname}", sname):
            sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, full)
            if sid >= 0:
                break
        if sid < 0:
            raise UnknownNameError(f"sensor in the {sc.name} scene", sname, [])
        rows.append(m.sensor_adr[sid] + comp)
        scales.append(scale)
    Cy = C[rows] * np.asarray(scales)[:, None]
    Bt = B[:, thrust]
    Dt = D[rows][:, thrust] * np.asarray(scales)[:, None]
    if len(sc.spinup_actuators):
        # the rotor-inertia reaction actuators take each rotor's ctrl through the same delay line
        Bt = Bt + B[:, sc.spinup_actuators]
        Dt = Dt + D[rows][:, sc.spinup_actuators] * np.asarray(scales)[:, None]

    if not delay:
        return _named(ct.ss(A, Bt @ Wrot, Cy, Dt @ Wrot, dt), inputs, outputs)
    # one delay line per rotor that the inputs drive (per-rotor delays may differ, e.g. the TUHH twin)
    nd = [int(round(saved_delay[a] / dt)) for a in thrust]
    coupling = []  # (rotor index, offset of its delay line)
    off = nx
    for j, n in enumerate(nd):
        if n == 0 or not np.any(Wrot[j]):
            continue
        coupling.append((j, off, n))
        off += n
    ntot = off
    Aa = np.zeros((ntot, ntot))
    Aa[:nx, :nx] = A
    Ba = np.zeros((ntot, len(inputs)))
    Ca = np.zeros((len(outputs), ntot))
    Ca[:, :nx] = Cy
    Da = np.zeros((len(outputs), len(inputs)))
    direct = np.ones(len(thrust), dtype=bool)
    for j, o, n in coupling:
        direct[j] = False
        # shift register: state o holds u[k-1], ..., o+n-1 holds u[k-n], which drives rotor j
        Ba[o] = Wrot[j]
        for s in range(1, n):
            Aa[o + s, o + s - 1] = 1.0
        Aa[:nx, o + n - 1] = Bt[:, j]
        Ca[:, o + n - 1] = Dt[:, j]
    Ba[:nx] = Bt[:, direct] @ Wrot[direct]
    Da[:] = Dt[:, direct] @ Wrot[direct]
    return _named(ct.ss(Aa, Ba, Ca, Da, dt), inputs, outputs)


def _named(sys: ct.StateSpace, inputs, outputs) -> ct.StateSpace:
    sys.set_inputs(list(inputs))
    sys.set_outputs(list(outputs))
    return sys


def truth_model(vehicle: str, dt: float = CONTROL_DT_S, slow_rad_s: float = 0.05,
                scene: str = "pitch-rig") -> ct.StateSpace:
    """The twin's true pitch-rate model on the rig (or in ``scene``, e.g. ``free-flight``), delay removed,
    resampled to ``dt`` (s).

    The 1 ms linearisation is converted with the exact ZOH inverse, made minimal, then re-discretised (both
    conversions exact for a ZOH-held input). Pole/zero pairs both slower than ``slow_rad_s`` (rad/s) are
    dropped: the rig's free rotation is a pole at the origin that the rate output's zero at the origin
    cancels, but finite differences leave them a hair apart; left in, a pole on the unit circle decides every
    nu-gap through the winding-number condition alone, and a one-minute record cannot see it anyway.
    """
    Gc = ct.minreal(d2c_zoh(linearize(scene, vehicle, "pitch", "gyro_pitch", delay=False)), 1e-7,
                    verbose=False)
    poles, zeros = list(np.linalg.eigvals(np.asarray(Gc.A, float))), list(ct.zeros(Gc))
    dropped = 0
    for pz in [x for x in poles if abs(x) < slow_rad_s]:
        near = [z for z in zeros if abs(z) < slow_rad_s]
        if near:
            poles.remove(pz)
            zeros.remove(min(near, key=lambda z: abs(z - pz)))
            dropped += 1
    if dropped:
        # conjugate pairs give real polynomials; np.poly keeps a complex dtype, python-control refuses it
        G = ct.tf(np.real(np.poly(zeros)), np.real(np.poly(poles)))
        w_ref = 1.0  # match the gain at 1 rad/s, well inside the identification band
        k = ct.evalfr(Gc, 1j * w_ref) / ct.evalfr(G, 1j * w_ref)
        Gc = ct.ss(ct.tf(np.real(k) * G.num[0][0], G.den[0][0]))
    return c2d_zoh(Gc, dt)
