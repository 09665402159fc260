"""A simulated rate loop that writes its own flight logs (no MuJoCo): per axis a plant ``K/(s (tau s + 1))``
with a one-sample input delay, a hand-written discrete PID (derivative on the filtered measured rate,
feed-forward) at 250 Hz, the gyro sampled at 500 Hz, and autotune-like excitation (a high-passed square wave on
one axis's rate set-point at a time). The truth every identification test compares with is the plant here."""

from dataclasses import dataclass

import control as ct
import numpy as np
from scipy import signal as sig

AXES = ("roll", "pitch", "yaw")
LOOP_HZ = 250.0
GYRO_HZ = 500.0
DELAY_SAMPLES = 1
# (K rad/s^2 per unit output, tau s): a 250 mm quad's roll/pitch and its slower yaw
PLANTS = {"roll": (400.0, 0.03), "pitch": (350.0, 0.035), "yaw": (60.0, 0.08)}
# (kp, ki, kd, kff, derivative filter pole a): PX4-like rate gains (yaw without D)
GAINS = {"roll": (0.15, 0.2, 0.003, 0.0, 0.6), "pitch": (0.15, 0.2, 0.003, 0.0, 0.6),
         "yaw": (0.3, 0.1, 0.0, 0.05, 0.6)}


def plant_tf(axis):
    K, tau = PLANTS[axis]
    return ct.tf([K], [tau, 1.0, 0.0])


def true_plant_d(axis, dt=1 / LOOP_HZ) -> ct.StateSpace:
    """The truth: ZOH plant at ``dt`` with its input delay, as one discrete system."""
    from rotorlab.lti import with_io_delay

    return with_io_delay(ct.c2d(ct.ss(plant_tf(axis)), dt), DELAY_SAMPLES * dt)


class PID:
    """Discrete PID, written by hand: ``u = kp e + ki sum(e) dt + kff r - kd d``, ``d`` the measured rate's
    derivative through a first-order filter ``d_k = a d_(k-1) + (1 - a) (y_k - y_(k-1)) / dt``; the integral
    is forward Euler (this step's error enters the next step's sum)."""

    def __init__(self, kp, ki, kd, kff, a, dt):
        self.kp, self.ki, self.kd, self.kff, self.a, self.dt = kp, ki, kd, kff, a, dt
        self.xi = self.d = self.yprev = 0.0

    def step(self, r, y):
        e = r - y
        self.d = self.a * self.d + (1 - self.a) * (y - self.yprev) / self.dt
        u = self.kp * e + self.ki * self.xi + self.kff * r - self.kd * self.d
        self.xi += self.dt * e
        self.yprev = y
        return u

    def lti(self) -> ct.StateSpace:
        """The same law as a (r, y) -> u state space, state [integral, d_(k-1), y_(k-1)], derived by hand from
        ``step``."""
        a, dt, c = self.a, self.dt, (1 - self.a) / self.dt
        A = [[1, 0, 0], [0, a, -c], [0, 0, 0]]
        B = [[dt, -dt], [0, c], [0, 1]]
        C = [[self.ki, -self.kd * a, self.kd * c]]
        D = [[self.kp + self.kff, -self.kp - self.kd * c]]
        return ct.ss(A, B, C, D, dt)


def controller(axis) -> PID:
    return PID(*GAINS[axis], 1 / LOOP_HZ)


def excitation(n, rng, amp=1.0, hp_hz=1.0):
    """Autotune-like set-point: a square wave of random half-periods (0.05-0.3 s), high-passed (first order at
    ``hp_hz``) as PX4's autotune high-passes its steps."""
    out = np.empty(n)
    k = 0
    level = amp
    while k < n:
        m = int(rng.integers(int(0.05 * LOOP_HZ), int(0.3 * LOOP_HZ)))
        out[k:k + m] = level
        level = -level
        k += m
    b, a = sig.butter(1, hp_hz, btype="high", fs=LOOP_HZ)
    return sig.lfilter(b, a, out)


@dataclass
class Flight:
    t_loop_s: np.ndarray
    t_gyro_s: np.ndarray
    rate_sp: dict
    rate_out: dict
    rate_gyro: dict
    landed: np.ndarray
    armed: np.ndarray
    autotune_state: np.ndarray
    thrust: np.ndarray
    excite_s: dict


def pilot_input(n, rng, amp=0.5, lp_hz=2.0):
    """Pilot-like stick set-point: bursts (3-6 s) of held levels (0.2-1.2 s each, uniform in +-``amp``) between
    quiet stretches (3-10 s), smoothed by a second-order low-pass at ``lp_hz`` as a hand on a stick is."""
    out = np.zeros(n)
    k = int(rng.integers(int(1 * LOOP_HZ), int(3 * LOOP_HZ)))
    while k < n:
        end = min(n, k + int(rng.uniform(3.0, 6.0) * LOOP_HZ))
        while k < end:
            m = int(rng.uniform(0.2, 1.2) * LOOP_HZ)
            out[k:min(k + m, end)] = rng.uniform(-amp, amp)
            k += m
        k = end + int(rng.uniform(3.0, 10.0) * LOOP_HZ)
    b, a = sig.butter(2, lp_hz, fs=LOOP_HZ)
    return sig.lfilter(b, a, out)


def fly(seed=0, excite_s=15.0, pause_s=2.0, noise=0.01, excite=True, pilot=False, heading_hold_p=0.0,
        disturbance=0.0) -> Flight:
    """Fly: 2 s on the ground, then roll, pitch, yaw excitation in turn (``excite_s`` each), 2 s to land.
    ``pilot``: no autotune; every axis flown by :func:`pilot_input` over the whole airborne time instead.
    ``heading_hold_p`` (1/s): where positive, the yaw rate set-point is ``P (heading set-point - heading)`` (an
    angle mode's heading hold), the set-point integrating the yaw set-point otherwise flown, the heading the
    measured rate, so the rate set-point is fed back from the measurement. ``disturbance``: RMS (rate-loop output
    units) of a torque disturbance, white noise low-passed at 1 Hz, added to every axis's plant input (drawn from
    its own generator, so the set-points and sensor noise of a seed stay as without it)."""
    rng = np.random.default_rng(seed)
    t_ground = 2.0
    total = t_ground + 3 * (excite_s + pause_s) + 2.0
    n = int(total * LOOP_HZ)
    t = np.arange(n) / LOOP_HZ
    state = np.zeros(n, np.uint8)
    sp, spans = {}, {}
    for i, axis in enumerate(AXES):
        t0 = t_ground + i * (excite_s + pause_s)
        m = (t >= t0) & (t < t0 + excite_s)
        spans[axis] = (t0, t0 + excite_s)
        sp[axis] = np.zeros(n)
        if pilot:
            sp[axis] = pilot_input(n, rng)
            state[:] = 0
            continue
        if excite:
            sp[axis][m] = excitation(int(m.sum()), rng, amp=1.0 if axis != "yaw" else 0.5)
        state[m] = 2 + 2 * i  # autotune legacy layout: 2 roll, 4 pitch, 6 yaw; pauses 3, 5, 7
        state[(t >= t0 + excite_s) & (t < t0 + excite_s + pause_s)] = 3 + 2 * i
    landed = (t < t_ground) | (t >= total - 1.0)
    armed = t >= 0.5
    thrust = np.where(landed, 0.1, 0.5)
    sub = int(GYRO_HZ / LOOP_HZ)
    out, gyro = {}, {}
    drng = np.random.default_rng([seed, 1])
    for axis in AXES:
        dist = np.zeros(n)
        if disturbance > 0:
            dist = sig.lfilter(*sig.butter(1, 1.0, fs=LOOP_HZ), drng.standard_normal(n))
            dist *= disturbance / dist.std()
        hold = axis == "yaw" and heading_hold_p > 0
        heading_sp, heading = np.cumsum(sp[axis]) / LOOP_HZ, 0.0
        Pd = ct.c2d(ct.ss(plant_tf(axis)), 1 / GYRO_HZ)
        A, B, C = (np.asarray(M, float) for M in (Pd.A, Pd.B, Pd.C))
        C = C[0]
        x = np.zeros(A.shape[0])
        pid = controller(axis)
        u_hist = [0.0] * (DELAY_SAMPLES + 1)
        ys, us = np.empty(n * sub), np.empty(n)
        for k in range(n):
            y_meas = float(C @ x) + noise * rng.standard_normal()
            ys[k * sub] = y_meas
            if hold:
                sp[axis][k] = heading_hold_p * (heading_sp[k] - heading)
                heading += y_meas / LOOP_HZ
            us[k] = pid.step(sp[axis][k], y_meas)
            u_hist.append(us[k])
            u_applied = u_hist[-1 - DELAY_SAMPLES] + dist[k]
            for j in range(sub):
                x = A @ x + B[:, 0] * u_applied
                if j < sub - 1:
                    ys[k * sub + j + 1] = float(C @ x) + noise * rng.standard_normal()
        out[axis], gyro[axis] = us, ys
    return Flight(t, np.arange(n * sub) / GYRO_HZ, sp, out, gyro, landed, armed, state, thrust, spans)


def px4_topics(f: Flight, layout="v1.14", t0_us=1_000_000):
    """The flight as PX4 topics (names from rotorlab.ident.flightlogs.names)."""
    us = lambda t: (t0_us + np.round(t * 1e6)).astype(np.uint64)
    f32 = lambda x: np.asarray(x, np.float32)
    tl, tg = us(f.t_loop_s), us(f.t_gyro_s)
    topics = {
        "vehicle_rates_setpoint": {"timestamp": tl, **{a: f32(f.rate_sp[a]) for a in AXES}},
        "vehicle_angular_velocity": {"timestamp": tg, **{f"xyz[{i}]": f32(f.rate_gyro[a]) for i, a in enumerate(AXES)}},
        "vehicle_land_detected": {"timestamp": tl[::25], "landed": f.landed[::25].astype(np.uint8)},
        "vehicle_status": {"timestamp": tl[::25], "arming_state": np.where(f.armed[::25], 2, 1).astype(np.uint8),
                           "nav_state": np.full(len(tl[::25]), 10, np.uint8)},
        "autotune_attitude_control_status": {"timestamp": tl[::5], "state": f.autotune_state[::5]},
        "vehicle_thrust_setpoint": {"timestamp": tl, "xyz[0]": f32(0 * f.thrust), "xyz[1]": f32(0 * f.thrust),
                                    "xyz[2]": f32(-f.thrust)},
    }
    if layout == "v1.14":
        topics["vehicle_torque_setpoint"] = {"timestamp": tl, **{f"xyz[{i}]": f32(f.rate_out[a])
                                                                for i, a in enumerate(AXES)}}
    else:
        topics["actuator_controls_0"] = {"timestamp": tl, **{f"control[{i}]": f32(f.rate_out[a])
                                                            for i, a in enumerate(AXES)},
                                         "control[3]": f32(f.thrust)}
    return topics


# the simulated gyro is logged unfiltered: the autopilots' gyro low-pass parameters say so (0 = off), or the
# reader would take their defaults (PX4 40 Hz, ArduPilot 20 Hz) and identify through a filter the flight never had
ARDUPILOT_UNFILTERED = {"INS_GYRO_FILTER": 0.0}


def px4_params():
    p = {"IMU_GYRO_CUTOFF": 0.0}
    for axis, pre in zip(AXES, ("MC_ROLLRATE", "MC_PITCHRATE", "MC_YAWRATE")):
        kp, ki, kd, kff, _ = GAINS[axis]
        p.update({f"{pre}_P": kp, f"{pre}_I": ki, f"{pre}_D": kd, f"{pre}_FF": kff})
    return p


def dataflash_messages(f: Flight, t0_us=1_000_000, rate_every=1, sysid=True):
    """The flight as ArduCopter messages: RATE at the loop rate over ``rate_every`` (deg/s), EV arm/takeoff/land,
    MODE, and where ``sysid`` SIDS/SIDD for each axis's excitation."""
    deg = 180 / np.pi
    idx = np.arange(0, len(f.t_loop_s), rate_every)
    g = f.rate_gyro
    sub = int(GYRO_HZ / LOOP_HZ)
    rows = [(int(t0_us + round(f.t_loop_s[k] * 1e6)),
             *(v for a in AXES for v in (f.rate_sp[a][k] * deg, g[a][k * sub] * deg, f.rate_out[a][k])))
            for k in idx]
    t_air = f.t_loop_s[np.flatnonzero(~f.landed)]
    ev = [(t0_us + 500_000, 10), (int(t0_us + t_air[0] * 1e6), 28), (int(t0_us + t_air[-1] * 1e6), 18)]
    sids, sidd = [], []
    for i, axis in enumerate(AXES):
        r0, r1 = f.excite_s[axis]
        sids.append((int(t0_us + r0 * 1e6), 7 + i))  # SID_AXIS 7, 8, 9: rate roll, pitch, yaw
        sidd += [(int(t0_us + round(t * 1e6)), float(t - r0)) for t in f.t_loop_s[(f.t_loop_s >= r0) & (f.t_loop_s < r1)]]
    msgs = {
        "RATE": ("Qfffffffff", ["TimeUS", "RDes", "R", "ROut", "PDes", "P", "POut", "YDes", "Y", "YOut"], rows),
        "EV": ("QB", ["TimeUS", "Id"], ev),
        "MODE": ("QMBB", ["TimeUS", "Mode", "ModeNum", "Rsn"], [(t0_us, 1, 1, 0)]),
    }
    if sysid:
        msgs |= {"SIDS": ("QB", ["TimeUS", "Ax"], sids), "SIDD": ("Qf", ["TimeUS", "Time"], sidd)}
    return msgs


def true_closed_loop_d(axis, dt=1 / LOOP_HZ) -> ct.StateSpace:
    """The truth of the rate loop: rate set-point -> rate, the plant (:func:`true_plant_d`) closed with the PID's
    ``(r, y) -> u`` law, at the loop rate."""
    K = controller(axis).lti()
    return ct.feedback(true_plant_d(axis, dt), K[0, 1], sign=1) * K[0, 0]
