"""``prbs-periodic``: ref. 002's closed-loop identification experiment (sec. 4, fig. 2).

A known, hand-tuned stabilising PD closes the loop of one axis (``u = kp (r - angle) - kd rate``, flown as a
state-space controller in place of the cascade) and a full-length pseudo-random binary sequence (a maximum-length
sequence, ``scipy.signal.max_len_seq``) repeated period after period drives its angle set-point, so the
response can be averaged over the periods (TUHH: ten) to raise the signal-to-noise ratio. Roll and pitch run on
their one-axis rigs; yaw runs in free flight (TUHH had no yaw rig) with the position hold flying roll and pitch.

Options
-------
``order`` : int          MLS register length: period ``2**order - 1`` bits (default 7: 127 bits)
``bit_s`` : float        bit time, s (default 0.04)
``amplitude_deg`` : float  set-point level, +-deg (default 3)
``kp``, ``kd`` : float   PD gains, % per deg and % per deg/s (default per axis: roll/pitch 0.6 / 0.14, yaw 3 / 1)

The run is as many whole periods as fit in its duration (default 11: one to settle, ten to average).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import max_len_seq

from rotorlab.errors import ConfigError
from rotorlab.sim.control.statespace import ControllerSpec
from rotorlab.sim.scenarios import Context, Setup, _metrics, merged_options

NAME = "prbs-periodic"
DESCRIPTION = "periodic full-length PRBS on one axis' set-point with a known PD closed (TUHH grey-box protocol)"
SCENES = ("pitch-rig", "roll-rig", "free-flight")
DEFAULTS = {"order": 7, "bit_s": 0.04, "amplitude_deg": 3.0, "kp": None, "kd": None}
DURATION_S = 11 * (2 ** 7 - 1) * 0.04
#: axis -> (set-point, angle, rate, command) and the hand-tuned PD (% per deg, % per deg/s): about 6 rad/s
#: closed-loop bandwidth on roll/pitch (57 deg/s^2 per %), about 3 rad/s on yaw (4.3 deg/s^2 per % below its zero)
AXES = {"roll": ("phi_ref", "phi", "p", "u_lat", 0.6, 0.14), "pitch": ("theta_ref", "theta", "q", "u_lon", 0.6, 0.14),
        "yaw": ("psi_ref", "psi", "r", "u_yaw", 3.0, 1.0)}


def axis_of(scene: str) -> str:
    return "yaw" if scene == "free-flight" else _metrics.channels(scene)[0]


def sequence(options: dict, dt_s: float) -> tuple[np.ndarray, int]:
    """One period of the set-point PRBS sampled at ``dt_s`` (deg) and its length in samples."""
    o = {**DEFAULTS, **options}
    order = o["order"]
    if not (isinstance(order, int) and 3 <= order <= 16):
        raise ConfigError(field="options.order", expected="an integer register length in 3..16", got=order)
    per_bit = o["bit_s"] / dt_s
    if not (o["bit_s"] > 0 and abs(per_bit - round(per_bit)) < 1e-6 and round(per_bit) >= 1):
        raise ConfigError(field="options.bit_s", expected=f"a whole multiple of the flight-software period {dt_s} s",
                          got=o["bit_s"])
    bits = max_len_seq(order)[0].astype(float) * 2.0 - 1.0
    r = np.repeat(bits, int(round(per_bit))) * float(o["amplitude_deg"])
    return r, r.size


def pd_controller(axis: str, kp: float, kd: float, dt_s: float) -> ControllerSpec:
    """The identification PD on ``[set-point, angle, rate]`` -> axis command (no states)."""
    ref, ang, rate, cmd = AXES[axis][:4]
    return ControllerSpec(name=f"pd-{axis}", dt_s=dt_s, inputs=(ref, ang, rate), outputs=(cmd,), A=np.zeros((0, 0)),
                          B=np.zeros((0, 3)), C=np.zeros((1, 0)), D=np.array([[kp, -kp, -kd]]),
                          description=f"ref. 002 identification PD on {axis}: kp {kp} %/deg, kd {kd} %/(deg/s)")


def pd_gains(axis: str, options: dict) -> tuple[float, float]:
    """The identification PD's ``(kp, kd)`` on ``axis``: the options' (merged with :data:`DEFAULTS`), else the
    axis default of :data:`AXES`."""
    o = {**DEFAULTS, **options}
    _, _, _, _, kp0, kd0 = AXES[axis]
    kp = float(o["kp"] if o["kp"] is not None else kp0)
    kd = float(o["kd"] if o["kd"] is not None else kd0)
    if not (kp > 0 and kd >= 0):
        raise ConfigError(field="options.kp/kd", expected="a stabilising PD: kp > 0, kd >= 0", got=(kp, kd))
    return kp, kd


def setup(ctx: Context) -> Setup:
    o = merged_options(ctx, DEFAULTS)
    axis = axis_of(ctx.scene)
    ref = AXES[axis][0]
    kp, kd = pd_gains(axis, o)
    r, n = sequence(o, ctx.dt_s)
    periods = int(round(ctx.duration_s / ctx.dt_s)) // n
    if periods < 2:
        raise ConfigError(field="duration", expected=f"at least two periods of {n * ctx.dt_s:g} s", got=ctx.duration_s)
    # psi_ref is latched to the heading at the start and the excitation added to it (flight software). On a rig
    # the locked axes' loops are opened (zero command): closed, their integrators would wind up on the gyro
    # bias against the rig's lock and shift the rotors' operating point, hence the identified axis' torque gain
    if axis == "yaw":
        mode, opened = "position", ()
    else:
        mode, opened = "open-loop", tuple(a for a in ("roll", "pitch", "yaw") if a != axis)
    return Setup(mode=mode, open_loop_axes=opened or ("roll", "pitch", "yaw"), excitation={ref: np.tile(r, periods)},
                 controller=[pd_controller(axis, kp, kd, ctx.dt_s)],
                 extra_columns={"psi_ref": "deg"} if axis == "yaw" else {},
                 notes={"axis": axis, "period_samples": n, "periods": periods, "kp": kp, "kd": kd,
                        "bit_s": float(o["bit_s"]), "amplitude_deg": float(o["amplitude_deg"])})
