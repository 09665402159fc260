"""Cascade axis, attitude controller, mixer, position hold, plug-ins and FlightSoftware against linear ground truth."""

import math

import control as ct
import numpy as np
import pytest
from helpers import p2a2_testbed_angle_rate

from rotorlab.errors import ConfigError, UnknownNameError
from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.lti import delay_ss, pid2_ss
from rotorlab.sim.control import (
    AttitudeController,
    CallbackPlugin,
    CascadeAxis,
    FlightSoftware,
    Mixer,
    PositionGains,
    StateSpacePlugin,
    quad_plus,
    quad_x,
)
from rotorlab.vehicles import load_vehicle

DT = 0.02
LIMITS = load_vehicle("anteos-p2a2").commands  # the P2-A2's [commands]: +-30 %, +-150 deg/s, yaw +-20 %, +-90 deg/s
STD = AxisGains(outer=LoopGains(kp=9.26, kd=1.11, tf=0.03),
                inner=LoopGains(kp=0.257, ki=0.643, kd=0.0231, tf=0.0225))
OPT_TB = AxisGains(outer=LoopGains(kp=5.4631, kd=0.9376, tf=0.0380),
                   inner=LoopGains(kp=0.3539, ki=1.8562, kd=0.0084, tf=0.0430))
MINI_OPT = AxisGains(outer=LoopGains(kp=19.8566, kd=1.5331, tf=0.0723, b=0.9986, c=0.0),
                     inner=LoopGains(kp=0.5253, ki=1.7525, kd=0.0144, tf=0.0206, b=0.5787, c=1.0))


def _gs(name, ax):
    return GainSet(name, {"pitch": ax, "roll": ax})


class _Plant:
    def __init__(self):
        P = p2a2_testbed_angle_rate(DT)  # the 3-sample input delay: the shift register below
        self.A, self.B, self.C = (np.asarray(M) for M in (P.A, P.B, P.C))
        self.x = np.zeros(3)
        self.buf = [0.0, 0.0, 0.0]

    def out(self):
        theta, q = self.C @ self.x
        return float(theta), float(q)

    def step(self, u):
        self.buf.append(u)
        self.x = self.A @ self.x + self.B[:, 0] * self.buf.pop(0)


# ---------------------------------------------------------------------------------------------- cascade
@pytest.mark.parametrize("ax", [STD, MINI_OPT], ids=["standard", "A2-MINI-2dof"])
def test_cascade_axis_equals_series_of_pid2_ss(ax):
    rng = np.random.default_rng(0)
    n = 300
    th_ref = np.repeat(rng.normal(0, 3, n // 30), 30)
    th = np.cumsum(rng.normal(0, 0.05, n))
    q = rng.normal(0, 2, n)
    t = np.arange(n) * DT
    o, i = ax.outer, ax.inner
    q_ref = ct.forced_response(pid2_ss(o.kp, o.ki, o.kd, o.tf, o.b, o.c, DT), t, np.vstack([th_ref, th])).outputs
    q_ref = np.ravel(q_ref)
    u_ref = ct.forced_response(pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, DT), t, np.vstack([q_ref, q])).outputs
    u_ref = np.ravel(u_ref)
    axis = CascadeAxis(o, i, DT, rate_limit_dps=1e9, u_limit_pct=1e9)
    out = np.array([axis.step(a, b, c) for a, b, c in zip(th_ref, th, q)])
    np.testing.assert_allclose(out[:, 1], q_ref, atol=1e-10)
    np.testing.assert_allclose(out[:, 0], u_ref, atol=1e-10)


def test_cascade_saturations():
    axis = CascadeAxis(STD.outer, STD.inner, DT, rate_limit_dps=150.0, u_limit_pct=30.0)
    u, q_ref = axis.step(60.0, 0.0, 0.0)  # 60 deg step: kp alone asks for 555 deg/s
    assert q_ref == 150.0 and u == 30.0
    u, q_ref = axis.step(-60.0, 0.0, 0.0)
    assert q_ref == -150.0 and u == -30.0


def _closed_loop_step(gains: AxisGains, n=150, amp=10.0, **limits):
    limits = {"rate_limit_dps": LIMITS.rate_limit_dps, "u_limit_pct": LIMITS.limit_pct, **limits}
    plant, axis = _Plant(), CascadeAxis(gains.outer, gains.inner, DT, **limits)
    th, us = np.empty(n), np.empty(n)
    for k in range(n):
        theta, q = plant.out()
        th[k] = theta
        us[k], _ = axis.step(amp, theta, q)
        plant.step(us[k])
    return th, us


def _linear_closed_loop(gains: AxisGains, n=150, amp=10.0):
    """Same loop as a linear interconnection (python-control), valid while nothing saturates."""
    P = ct.series(delay_ss(3, DT), p2a2_testbed_angle_rate(DT))
    P = ct.ss(P.A, P.B, P.C, P.D, DT, inputs=["u"], outputs=["theta", "q"])
    o, i = gains.outer, gains.inner
    Co = ct.ss(pid2_ss(o.kp, o.ki, o.kd, o.tf, o.b, o.c, DT), inputs=["r", "theta"], outputs=["q_ref"])
    Ci = ct.ss(pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, DT), inputs=["q_ref", "q"], outputs=["u"])
    T = ct.interconnect([P, Co, Ci], inplist=["r"], outlist=["theta"])
    return np.ravel(ct.forced_response(T, np.arange(n) * DT, amp * np.ones(n)).outputs)


@pytest.mark.parametrize("ax", [STD, OPT_TB], ids=["standard", "optimal-testbed"])
def test_closed_loop_on_p2a2_model_equals_linear_interconnection(ax):
    th, _ = _closed_loop_step(ax, rate_limit_dps=1e9, u_limit_pct=1e9)
    np.testing.assert_allclose(th, _linear_closed_loop(ax), atol=1e-9)


@pytest.mark.parametrize("ax", [STD, OPT_TB], ids=["standard", "optimal-testbed"])
def test_saturated_10deg_step_settles_without_error(ax):
    # the derivative kick of the inner PID saturates the +-30 % command on a 10 deg step (as on the rig)
    th, us = _closed_loop_step(ax, n=250)
    assert np.max(np.abs(us)) == 30.0
    assert abs(th[-1] - 10.0) < 0.02 * 10.0
    assert np.max(th) < 1.3 * 10.0
    assert np.argmax(th > 9.0) * DT < 1.0


def test_heading_wrap_takes_the_short_way():
    yaw = CascadeAxis(LoopGains(kp=2.0), LoopGains(kp=0.4, ki=0.8), DT, rate_limit_dps=1e9, u_limit_pct=1e9,
                      wrap=True)
    ref = CascadeAxis(LoopGains(kp=2.0), LoopGains(kp=0.4, ki=0.8), DT, rate_limit_dps=1e9, u_limit_pct=1e9)
    # heading crossing +-180 (179 -> -179 is +2 deg), set-point 170 while at -175: 15 deg to the left
    for psi, psi_unwrapped in [(179.0, 179.0), (-179.0, 181.0), (-175.0, 185.0)]:
        u, r_ref = yaw.step(170.0, psi, 0.0)
        u0, r_ref0 = ref.step(170.0, psi_unwrapped, 0.0)
        assert r_ref == pytest.approx(r_ref0, abs=1e-9) and u == pytest.approx(u0, abs=1e-9)
    assert r_ref == pytest.approx(2.0 * -15.0)


def test_attitude_schedule_switches_gains_bumplessly_through_the_rate_loop():
    att = AttitudeController(_gs("standard", STD), DT, LIMITS, schedule=[(1.0, _gs("optimal", OPT_TB))])
    us, q_refs = [], []
    for k in range(100):
        out = att.step(k * DT, 0.0, 3.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0)  # held inputs, pitch error 2 deg
        us.append(out[1])
        q_refs.append(out[4])
    assert att.gains.name == "optimal"
    assert att.pitch.inner.gains == OPT_TB.inner
    # the outer PD has no integral to hold the difference: its proportional term switches with the gains
    assert q_refs[50] - q_refs[49] == pytest.approx((OPT_TB.outer.kp - STD.outer.kp) * 2.0, abs=1e-9)
    # the rate loop integrates: for held inputs it continues exactly (the old PID carrying on: its integral's
    # slope), so the command moves by that plus the new rate loop's answer to the rate set-point step only
    i = OPT_TB.inner
    old_next = us[49] + STD.inner.ki * DT * q_refs[49]  # rate 0: the error is the rate set-point
    assert us[50] - old_next == pytest.approx((i.kp * i.b + i.kd / i.tf * i.c) * (q_refs[50] - q_refs[49]),
                                              abs=1e-9)


def test_in_flight_gain_switch_leaves_no_angle_offset():
    # pitch test-bed model under a constant input disturbance, a 2 deg set-point step and the switch in the
    # middle of the transient: the inner PID's integral removes the disturbance whichever gains fly, so the
    # angle must settle on the set-point after the switch as before it. A switch that parked the outer PD's
    # proportional difference in a constant offset would hold (kp_old - kp_new) / kp_new x the error at the
    # switch (0.70 x 1.5 deg here: 1.04 deg) for ever.
    att = AttitudeController(_gs("standard", STD), DT, LIMITS, schedule=[(0.3, _gs("optimal", OPT_TB))])
    plant, err_at_switch = _Plant(), None
    for k in range(3000):
        theta, q = plant.out()
        if k == 15:
            err_at_switch = 2.0 - theta
        u = att.step(k * DT, 0.0, 2.0, 0.0, 0.0, theta, 0.0, 0.0, q, 0.0)[1]
        plant.step(u + 1.5)
    assert abs(err_at_switch) > 0.2, err_at_switch
    assert plant.out()[0] == pytest.approx(2.0, abs=1e-6)


# ---------------------------------------------------------------------------------------------- mixer
def test_mixer_signs_follow_aerospace_convention():
    m = quad_plus(0.415)  # front, right, rear, left; front/rear clockwise
    front, right, rear, left = range(4)
    r = m.mix(50.0, 0.0, 10.0, 0.0)
    assert r[front] == 55.0 and r[rear] == 45.0 and r[right] == r[left] == 50.0  # nose up, difference = 10 %
    r = m.mix(50.0, 10.0, 0.0, 0.0)
    assert r[left] == 55.0 and r[right] == 45.0  # right side down: left rotors push up
    r = m.mix(50.0, 0.0, 0.0, 10.0)
    assert r[right] == r[left] == 55.0 and r[front] == r[rear] == 45.0  # nose right: CCW rotors up
    # moments from the physics formula M = sum r_i x F_i with F = (0, 0, -T) and drag torque -spin Q e_z
    T = np.array(m.mix(50.0, 3.0, -4.0, 2.0, clip=False))
    x, y = m.positions_frd_m.T
    L, M, N = np.sum(-y * T), np.sum(x * T), np.sum(-m.spin_dirs * T)
    assert L > 0 and M < 0 and N > 0


@pytest.mark.parametrize("mixer", [quad_x(0.629), quad_plus(0.415),
                                   Mixer([[1, 0], [0.5, 0.8], [-0.5, 0.8], [-1, 0], [-0.5, -0.8], [0.5, -0.8]],
                                         [1, -1, 1, -1, 1, -1])], ids=["quad-x", "quad-plus", "hexa"])
def test_mixer_round_trip(mixer):
    cmd = np.array([55.0, 4.0, -6.0, 3.0])
    np.testing.assert_allclose(mixer.unmix(mixer.mix(*cmd)), cmd, atol=1e-12)
    if mixer.n_rotors == 4:
        assert abs(np.linalg.det(mixer.matrix)) > 1e-6


def test_mixer_flu_frame_and_kind_ranges():
    frd = quad_x(0.3)
    flu = Mixer(frd.positions_frd_m * [1, -1], frd.spin_dirs, frame="flu")
    np.testing.assert_array_equal(flu.matrix, frd.matrix)
    rpm = quad_x(0.3, kind="variable-rpm")
    assert min(rpm.mix(5.0, 0.0, 30.0, 0.0)) == 0.0
    assert min(quad_x(0.3).mix(5.0, 0.0, 30.0, 0.0)) == -10.0  # variable pitch: reverse thrust allowed
    with pytest.raises(ConfigError, match="rank"):
        Mixer([[1, 1], [-1, -1], [1, -1], [-1, 1]], [1, 1, 1, 1])  # all rotors the same way: no yaw


# ---------------------------------------------------------------------------------------------- flight software
def _meas(theta=0.0, q=0.0, **kw):
    m = {"phi": 0.0, "theta": theta, "psi": 0.0, "p": 0.0, "q": q, "r": 0.0,
         "x": 0.0, "y": 0.0, "z": -5.0, "vx": 0.0, "vy": 0.0, "vz": 0.0}
    m.update(kw)
    return m


def test_flight_software_cascade_matches_cascade_axis_and_mixes():
    fs = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS)
    fs.set_reference(theta_ref=2.0, u_col=60.0)
    plant_a, plant_b = _Plant(), _Plant()
    axis = CascadeAxis(STD.outer, STD.inner, DT, LIMITS.rate_limit_dps, LIMITS.limit_pct)
    for k in range(100):
        th, q = plant_a.out()
        out = fs.step(k * DT, _meas(th, q))
        plant_a.step(out["u_lon"])
        th_b, q_b = plant_b.out()
        u_b, q_ref_b = axis.step(2.0, th_b, q_b)
        plant_b.step(u_b)
        assert out["u_lon"] == pytest.approx(u_b, abs=1e-12) and out["q_ref"] == pytest.approx(q_ref_b, abs=1e-12)
    front, _, rear, _ = out["rotor_pct"]
    assert front - rear == pytest.approx(out["u_lon"], abs=1e-12) and out["u_col"] == 60.0


def test_state_space_plugin_reproduces_builtin_inner_loop():
    i = STD.inner
    K = ct.ss(pid2_ss(i.kp, i.ki, i.kd, i.tf, i.b, i.c, DT))
    plug = StateSpacePlugin(K, inputs=["q_ref", "q"], outputs=["u_lon"], dt=DT)
    seen = []
    spy = CallbackPlugin(lambda t, s: seen.append(s["u_lon"]) or {"spy": 1.0})
    fs_builtin = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS)
    fs_plugin = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS, plugins=[plug, spy])
    rng = np.random.default_rng(4)
    for k in range(200):
        m = _meas(theta=rng.normal(0, 0.05), q=rng.normal(0, 0.3))  # stays clear of +-30 %
        a = fs_builtin.step(k * DT, m)
        b = fs_plugin.step(k * DT, m)
        assert b["u_lon"] == pytest.approx(a["u_lon"], abs=1e-10) and b["spy"] == 1.0
    assert seen[-1] == b["u_lon"]  # the callback saw the plug-in's override (plug-ins run in order)


def test_open_loop_mode_excitation_and_supervisor():
    exc = np.array([7.0, -7.0, 9.0])
    fs = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS, mode="open-loop",
                        excitation={"u_lon": exc, "theta_ref": lambda t: 0.5})
    fs.set_reference(u_lon=1.0)
    outs = [fs.step(k * DT, _meas(theta=2.0)) for k in range(4)]
    np.testing.assert_array_equal([o["u_lon"] for o in outs], [8.0, -6.0, 10.0, 1.0])
    assert all(o["sup_lon"] == 0.0 for o in outs)
    out = fs.step(4 * DT, _meas(theta=18.0, q=10.0))  # beyond 0.75 * 20 deg: supervisor pulls back
    assert out["sup_lon"] < 0.0 and out["u_lon"] == pytest.approx(1.0 + out["sup_lon"])
    assert out["theta_ref"] == 0.5


def test_mode_switch_to_cascade_is_bumpless():
    fs = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS, mode="open-loop")
    fs.set_reference(u_lon=4.0, theta_ref=3.0)
    fs.step(0.0, _meas(theta=3.0, q=0.0))
    fs.set_mode("cascade")
    out = fs.step(DT, _meas(theta=3.0, q=0.0))
    assert out["u_lon"] == pytest.approx(4.0, abs=1e-12)


def test_position_mode_flies_a_point_mass_to_the_set_point():
    """Perfect attitude tracking, NED point mass: checks the signs and that the loops converge."""
    g = 9.80665
    pg = PositionGains.for_vehicle(mass_kg=5.0, hover_collective_pct=60.0)
    fs = FlightSoftware(_gs("standard", STD), quad_plus(0.415), DT, limits=LIMITS, mode="position", position_gains=pg)
    fs.set_reference(x_ref=2.0, y_ref=-1.0, z_ref=-6.0, psi_ref=30.0)
    pos, vel, att = np.array([0.0, 0.0, -5.0]), np.zeros(3), {"phi": 0.0, "theta": 0.0}
    for k in range(int(20.0 / DT)):
        out = fs.step(k * DT, _meas(phi=att["phi"], theta=att["theta"], psi=30.0, x=pos[0], y=pos[1], z=pos[2],
                                    vx=vel[0], vy=vel[1], vz=vel[2]))
        att = {"phi": out["phi_ref"], "theta": out["theta_ref"]}
        ph, th, ps = (math.radians(v) for v in (att["phi"], att["theta"], 30.0))
        # thrust direction -z_body in NED for yaw-pitch-roll Euler angles
        f = np.array([-(math.cos(ph) * math.sin(th) * math.cos(ps) + math.sin(ph) * math.sin(ps)),
                      -(math.cos(ph) * math.sin(th) * math.sin(ps) - math.sin(ph) * math.cos(ps)),
                      -math.cos(ph) * math.cos(th)])
        acc = g * out["u_col"] / pg.hover_collective_pct * f + np.array([0.0, 0.0, g])
        vel = vel + DT * acc
        pos = pos + DT * vel
    np.testing.assert_allclose(pos, [2.0, -1.0, -6.0], atol=0.05)


def test_flight_software_input_errors():
    with pytest.raises(UnknownNameError, match="mode"):
        FlightSoftware(_gs("s", STD), quad_plus(0.4), DT, limits=LIMITS, mode="acro")
    with pytest.raises(UnknownNameError, match="excitation"):
        FlightSoftware(_gs("s", STD), quad_plus(0.4), DT, limits=LIMITS, excitation={"u_pitch": [1.0]})
    fs = FlightSoftware(_gs("s", STD), quad_plus(0.4), DT, limits=LIMITS)
    with pytest.raises(UnknownNameError, match="reference"):
        fs.set_reference(theta=1.0)
    with pytest.raises(ConfigError, match="dt"):
        StateSpacePlugin(ct.ss([[0.5]], [[1]], [[1]], [[0]], 0.01), ["q"], ["u_lon"], dt=DT)
