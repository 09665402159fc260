"""Grey-box structures of a multirotor's rate plant per axis (normalised rate-loop output -> logged rate), the
shapes the indirect route (:func:`rotorlab.ident.flightlogs.identify.identify_plant_indirect`) fits through the
autopilot's known controller.

Registry :data:`STRUCTURES`: axis -> constructor; :func:`plant_structure` picks by axis and adds the autopilot's
gyro low-pass (known from the log's parameters) as an output filter, the motors' lag and delay fitted on other axes
(yaw: one motor path per rotor group, :data:`SHARES_MOTORS`), and the IMU's elastic mount where the vehicle's
description gives it (:func:`with_imu_mount`).

Roll and pitch (:func:`rate_plant_structure`): a differential thrust command ``u`` moves each rotor's speed through
the motor's lag ``tau_s`` after the transport delay ``delay_s``; the thrust difference times the arm is a torque,
and the body integrates torque / inertia to rate: ``K e^(-s delay_s) / (s (tau_s s + 1))``. The rotors' rate
damping (their H-forces at the hub, about 0.01 1/s on these axes) is below what a rate-loop record resolves.

Yaw (:func:`yaw_rate_plant_structure`), derived below. Rotor ``i`` of spin sense ``s_i = +-1`` runs at speed
``W_i``; the airframe feels the reaction of its drag torque ``k_q W_i^2`` and of spinning it up, ``J_r dW_i/dt``
(the motor's stator pushes back on the airframe with the torque that accelerates the rotor, rotor and motor bell
inertia ``J_r``), and each rotor, carried around the yaw axis at ``l r`` in its plane, meets an in-plane drag
force ``k_h l r`` at the arm ``l``:

    J_zz dr/dt = sum_i s_i (k_q W_i^2 + J_r dW_i/dt) - 4 k_h l^2 r

About hover (``W_i = W_H + w_i``) with the yaw command ``u`` spread as ``w_i = s_i c u`` (``c`` the speed per unit
command of the mixer and the speed map) through the motor's lag and delay,
``w_i(s) = s_i c e^(-s d) / (tau s + 1) u(s)``, so with ``q = 2 k_q W_H`` (the drag torque's slope):

    r(s) / u(s) = K (1 + s / z) e^(-s delay_s) / ((tau_s s + 1) (s + a))

    K = 4 c q / J_zz    (rad/s^2 per unit output: the drag-torque channel)
    z = q / J_r         (1/s: the spin-up reaction's zero, the lead it adds through the motor lag)
    a = 4 k_h l^2 / J_zz  (1/s: the in-plane drag's damping pole)

Ref. 002 (the TUHH quadrotor, reference [002] of the top-level README) writes the reaction ``J_R dW/dt`` in its
eq. 1 and identifies the zero in its table 1 (2.434 1/s); the twin's numbers (``vehicles/tuhh-quad/README.md``):
``q = 1.641e-4 N m s``, ``J_r = 6.742e-5 kg m^2``, ``z = 2.43 1/s``; ``4 k_h l^2 = 0.0111 N m s`` over
``J_zz = 0.0273 kg m^2``, ``a = 0.41 1/s``; the motor lag 0.037 s and the delay 24-28 ms are those of roll and
pitch (every rotor drives yaw). Unlike roll and pitch, the yaw plant's gain stays near ``K / z`` from ``z`` up to
the motor pole (about 3 rad/s per unit on the twin) and falls only as ``1/w`` beyond it, so its response at
50-300 rad/s, where the log's gyro low-pass shapes it, weighs in the nu-gap: the gyro filter goes into the
structure as the exact discrete filter after the ZOH plant (:func:`plant_structure`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import control as ct
import numpy as np

from ..greybox import GreyBoxModel, Param

__all__ = ["STRUCTURES", "MOTOR_PARAMS", "SHARES_MOTORS", "plant_structure", "rate_plant_structure", "with_imu_mount",
           "rate_angle_plant_structure", "fitted_plant", "file_plant", "yaw_rate_plant_structure"]


def rate_plant_structure(K: float = 100.0, tau_s: float = 0.03, delay_s: float = 0.005) -> GreyBoxModel:
    """Rate plant of a roll or pitch axis: ``K e^(-s delay_s) / (s (tau_s s + 1))``.

    The normalised rate-loop output commands a torque through the motors' lag ``tau_s``; the body integrates
    torque / inertia to rate. ``K`` in (rad/s^2) per unit output.

    Examples
    --------
    >>> rate_plant_structure().names
    ['K', 'tau_s', 'delay_s']
    """
    params = [Param("K", K, 1e-3, 1e6, "rad/s^2"), Param("tau_s", tau_s, 1e-3, 1.0, "s"),
              Param("delay_s", delay_s, 0.0, 0.1, "s")]

    def build(th):
        return ct.ss(ct.tf([th["K"]], [th["tau_s"], 1.0, 0.0]))

    return GreyBoxModel("rate-plant", params, build, delay_s="delay_s", inputs=["rate_out"], outputs=["rate"])


def yaw_rate_plant_structure(K: float = 10.0, z_rad_s: float = 2.5, a_rad_s: float = 0.5, tau_s: float = 0.03,
                             delay_s: float = 0.005, paths: int = 1) -> GreyBoxModel:
    """Yaw rate plant: ``K (1 + s / z_rad_s) e^(-s delay_s) / ((tau_s s + 1) (s + a_rad_s))`` (module docstring:
    the drag-torque channel ``K``, the rotors' spin-up reaction zero ``z_rad_s = q / J_r``, the in-plane drag pole
    ``a_rad_s = 4 k_h l^2 / J_zz``, the motors' lag and delay).

    With ``paths`` > 1 the rotors form that many groups of equal share, each with its own lag and delay
    (``tau_s``/``delay_s``, ``tau2_s``/``delay2_s``, ...; the vehicle whose roll and pitch are driven by different
    rotor pairs): ``K (1 + s / z_rad_s) / (s + a_rad_s) * mean_i e^(-s delay_i) / (tau_i s + 1)``, each path's
    delay exact in the discrete model (:class:`~rotorlab.ident.greybox.GreyBoxModel` with a delay per path).

    Examples
    --------
    >>> yaw_rate_plant_structure().names
    ['K', 'z_rad_s', 'a_rad_s', 'tau_s', 'delay_s']
    >>> yaw_rate_plant_structure(paths=2).names[-2:]
    ['tau2_s', 'delay2_s']
    """
    lags, delays = _path_names(paths)
    params = [Param("K", K, 1e-3, 1e6, "rad/s^2"), Param("z_rad_s", z_rad_s, 0.05, 200.0, "1/s"),
              Param("a_rad_s", a_rad_s, 0.0, 20.0, "1/s")]
    for lag, delay in zip(lags, delays):
        params += [Param(lag, tau_s, 1e-3, 1.0, "s"), Param(delay, delay_s, 0.0, 0.1, "s")]

    def build(th):
        # written as state space rather than a product of transfer functions: the realisation is the same for
        # every theta, so the fit's finite-difference Jacobian sees no change of basis between nearby points.
        # States: each path's rotor speed w_i (w_i' = (u_i - w_i) / tau_i), then the body rate x with
        # x' = -a x + K (w + w' / z), w the paths' mean
        n = len(lags)
        tau = np.array([th[k] for k in lags])
        K, z, a = th["K"], th["z_rad_s"], th["a_rad_s"]
        A = np.zeros((n + 1, n + 1))
        A[np.arange(n), np.arange(n)] = -1.0 / tau
        A[n, :n] = K / n * (1.0 - 1.0 / (z * tau))
        A[n, n] = -a
        B = np.zeros((n + 1, n))
        B[np.arange(n), np.arange(n)] = 1.0 / tau
        B[n, :] = K / (n * z * tau)
        C = np.zeros((1, n + 1))
        C[0, n] = 1.0
        return ct.ss(A, B, C, np.zeros((1, n)))

    return GreyBoxModel("yaw-rate-plant", params, build, delay_s=tuple(delays) if paths > 1 else delays[0],
                        inputs=["rate_out"], outputs=["rate"])


def _path_names(paths: int) -> tuple[list[str], list[str]]:
    """The lag and delay parameters of each motor path: ``tau_s``, ``delay_s``, then ``tau2_s``, ``delay2_s``, ..."""
    if paths < 1:
        raise ValueError(f"a plant needs at least one motor path, got {paths}")
    suffix = [""] + [str(i) for i in range(2, paths + 1)]
    return [f"tau{x}_s" for x in suffix], [f"delay{x}_s" for x in suffix]


def with_imu_mount(m: GreyBoxModel, frequency_hz: float, damping_ratio: float) -> GreyBoxModel:
    """``m`` with the IMU's elastic mount at its output, known and fixed: the IMU follows the airframe through
    the base-excited spring-damper ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)``, ``w = 2 pi frequency_hz``,
    one mount for every axis. Parameters ``mount_hz`` and ``mount_zeta``.

    Examples
    --------
    >>> with_imu_mount(rate_plant_structure(), 60.0, 0.15).names[-2:]
    ['mount_hz', 'mount_zeta']
    """
    params = list(m.params) + [Param("mount_hz", float(frequency_hz), 1.0, 1e4, "Hz", fixed=True),
                               Param("mount_zeta", float(damping_ratio), 0.0, 10.0, "1", fixed=True)]
    base = m.build

    def build(th):
        w, z = 2.0 * math.pi * th["mount_hz"], th["mount_zeta"]
        # states: the IMU's deflection q and its rate; the gyro reads w^2 q + 2 zeta w q'
        M = ct.ss([[0.0, 1.0], [-w * w, -2.0 * z * w]], [[0.0], [1.0]], [[w * w, 2.0 * z * w]], [[0.0]])
        return ct.series(base(th), M)

    return GreyBoxModel(m.name, params, build, m.delay, m.inputs, m.outputs, m.output_filter)


def rate_angle_plant_structure(K: float = 100.0, tau_s: float = 0.03, delay_s: float = 0.005,
                               gyro_filter: Callable[[float], ct.StateSpace] | None = None) -> GreyBoxModel:
    """:func:`rate_plant_structure` with the attitude as a second output: ``[rate, att]`` from ``rate_out``, the
    attitude the rate integrated (rad), for a loop closed through the angle controller.

    ``gyro_filter`` (as in :func:`plant_structure`) filters the rate output only: the rate controller and the
    logged rate see the gyro through the autopilot's low-pass, while the attitude comes from the estimator,
    which integrates the unfiltered gyro (PX4's EKF2 and ArduPilot's EKF3 take the IMU's delta angles). Left out,
    the filter's lag would be fitted into the motors' lag and delay, and counted again wherever the fitted plant
    is closed with the autopilot's filter (the twin check and the tuning).

    Examples
    --------
    >>> rate_angle_plant_structure().outputs
    ['rate', 'att']
    """
    params = [Param("K", K, 1e-3, 1e6, "rad/s^2"), Param("tau_s", tau_s, 1e-3, 1.0, "s"),
              Param("delay_s", delay_s, 0.0, 0.1, "s")]

    def build(th):
        # states: angular acceleration (the motors' lag), rate, attitude
        A = [[-1.0 / th["tau_s"], 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        return ct.ss(A, [[th["K"] / th["tau_s"]], [0.0], [0.0]], [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], [[0.0], [0.0]])

    def output_filter(dt):
        return ct.append(gyro_filter(dt), ct.ss([], [], [], [[1.0]], dt))

    return GreyBoxModel("rate-angle-plant", params, build, delay_s="delay_s", inputs=["rate_out"],
                        outputs=["rate", "att"], output_filter=output_filter if gyro_filter else None)


#: axis -> the constructor of its rate plant's structure
STRUCTURES: dict[str, Callable[[], GreyBoxModel]] = {
    "roll": rate_plant_structure, "pitch": rate_plant_structure, "yaw": yaw_rate_plant_structure}


#: the parameters of the rotors' motors (lag and delay), the same in every axis's structure (the first path's)
MOTOR_PARAMS = ("tau_s", "delay_s")
#: axes whose motor parameters are taken, fixed, from the axes that determine them, one motor path per axis: a yaw
#: record does not separate the motor lag from the delay (its rate-loop output passes the autopilot's yaw torque
#: low-pass, PX4's MC_YAW_TQ_CUTOFF 2 Hz, and the yaw loop crosses over near 5 rad/s, far below the motor pole at
#: 27 rad/s), while roll and pitch, driven by the same rotors, do. Every rotor drives yaw, with an equal share:
#: on a plus frame roll's pair and pitch's pair are the two halves of the rotors, each with its own lag and delay
#: (tuhh-quad: 24 and 28 ms, whose mean path differs from one path at the mean delay by 23 % in gain at 55 Hz);
#: on an X frame every axis is driven by all rotors and the two paths are the same
SHARES_MOTORS = {"yaw": ("roll", "pitch")}


def plant_structure(axis: str, gyro_filter: Callable[[float], ct.StateSpace] | None = None,
                    motors: dict | list | None = None, imu_mount: tuple | None = None) -> GreyBoxModel:
    """The rate plant structure of ``axis`` (:data:`STRUCTURES`), its output through ``gyro_filter``, with the
    motor parameters ``motors`` (:data:`MOTOR_PARAMS`) known and fixed where given, and the IMU's mount where
    known.

    Parameters
    ----------
    axis : {"roll", "pitch", "yaw"}
    gyro_filter : callable, optional
        ``gyro_filter(dt) -> control.StateSpace``: the autopilot's gyro low-pass at sample time ``dt`` (the logged
        rate is the filtered one), from the log's parameters; none when the log's rate is unfiltered or the
        filter unknown.
    motors : dict or list of dict, optional
        ``{"tau_s": ..., "delay_s": ...}``: the motors' lag and delay, s, identified on the axes of
        :data:`SHARES_MOTORS` (the same rotors), fixed in this structure; a list (yaw): one per motor path, the
        rotors split into that many equal groups (:func:`yaw_rate_plant_structure`).
    imu_mount : (float, float), optional
        The IMU mount's natural frequency, Hz, and damping ratio, from the vehicle's description
        (:func:`with_imu_mount`). A flight log's rate-loop record leaves them undetermined (their 95 % intervals
        span 270-470 rad/s and damping 0-0.3 on the twin's roll and pitch, from starts that end at 215 or
        614 rad/s), so they are given, not fitted.

    Examples
    --------
    >>> plant_structure("yaw").name
    'yaw-rate-plant'
    >>> plant_structure("yaw", motors=[{"tau_s": 0.036, "delay_s": 0.024}, {"tau_s": 0.037, "delay_s": 0.028}]).free
    ['K', 'z_rad_s', 'a_rad_s']
    """
    if axis not in STRUCTURES:
        raise KeyError(f"no rate plant structure for axis {axis!r}; axes: {sorted(STRUCTURES)}")
    paths = motors if isinstance(motors, list) else [motors] if motors else []
    m = STRUCTURES[axis](paths=len(paths)) if len(paths) > 1 else STRUCTURES[axis]()
    m = GreyBoxModel(m.name, m.params, m.build, m.delay, m.inputs, m.outputs, gyro_filter)
    if paths:
        lags, delays = _path_names(len(paths))
        fixed = {}
        for p, lag, delay in zip(paths, lags, delays):
            fixed.update({lag: float(p["tau_s"]), delay: float(p["delay_s"])})
        m = m.replace(**{k: {"value": v, "fixed": True} for k, v in fixed.items()})
    if imu_mount is not None:
        m = with_imu_mount(m, *imu_mount)
    return m


def fitted_plant(name: str, params: dict) -> tuple | None:
    """The continuous plant of a fit of the structure ``name`` (as a model file records it; ``rate-angle-plant``:
    its rate output) with its fitted ``params``, as ``(G, delay_s)``: one input, without the gyro filter and the IMU mount the fit saw the rate
    through; None when no structure of :data:`STRUCTURES` has that name or the parameters are not all there.

    Motor paths are counted from the parameters (``tau_s``, ``tau2_s``, ...); several paths share the input,
    their delays replaced by their mean: two paths ``d +- e`` apart differ from it by the factor ``cos(w e)`` in
    gain and nothing in phase (0.005 dB at 30 rad/s for tuhh-quad's 24 and 28 ms).

    Examples
    --------
    >>> G, d = fitted_plant("rate-plant", {"K": 400.0, "tau_s": 0.03, "delay_s": 0.006})
    >>> round(d, 3), G.ninputs
    (0.006, 1)
    >>> fitted_plant("rate-angle-plant", {"K": 400.0, "tau_s": 0.03, "delay_s": 0.006})[0].noutputs
    1
    """
    # the rate output of the rate-angle structure (fitted through an angle loop) is the roll/pitch rate plant
    make = rate_plant_structure if name == "rate-angle-plant" else next(
        (f for f in STRUCTURES.values() if f().name == name), None)
    if make is None:
        return None
    paths = 1
    while f"tau{paths + 1}_s" in params:
        paths += 1
    m = make(paths=paths) if paths > 1 else make()
    if not set(m.names) <= set(params):
        return None
    G = ct.ss(m.build(params))
    delays = [m.delay] if isinstance(m.delay, str) else list(m.delay)
    if G.ninputs > 1:
        G = ct.series(ct.ss([], [], [], np.ones((G.ninputs, 1))), G)
    return G, float(np.mean([params[d] for d in delays]))



def file_plant(G, delay_s: float, meta: dict) -> tuple:
    """The plant a model file holds, as ``(G, delay_s)``: where the file records a structure of
    :data:`STRUCTURES` and its fitted parameters (``settings.structure``, ``settings.extra.params``: what
    ``rotorlab ident`` writes for a plant through the controller), the structure's own continuous plant
    (:func:`fitted_plant`), so a delay that is not a whole number of the log's samples stays exact (the discrete
    form holds it as a state at z = 0, which has no continuous equivalent); otherwise ``G`` and ``delay_s`` as
    loaded (``rotorlab.ident.modelio.load_model``).

    Examples
    --------
    >>> G, d, meta = load_model("roll-plant-indirect.json", whole_samples=False)  # doctest: +SKIP
    >>> G, d = file_plant(G, d, meta)  # doctest: +SKIP
    """
    settings = meta.get("settings") or {}
    th = (settings.get("extra") or {}).get("params")
    fitted = fitted_plant(settings.get("structure"), th) if th else None
    return fitted if fitted is not None else (G, float(delay_s))
