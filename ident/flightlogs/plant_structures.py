"""Grey-box structures of a multirotor's rate plant per axis (normalised rate-loop output -> logged rate), the
shapes the indirect route (:func:`rotorlab.ident.flightlogs.identify.identify_plant_indirect`) fits through the
autopilot's known controller.

Registry :data:`STRUCTURES`: axis -> constructor; :func:`plant_structure` picks by axis and adds the autopilot's
gyro low-pass (known from the log's parameters) as an output filter.

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

from collections.abc import Callable

import control as ct

from ..greybox import GreyBoxModel, Param

__all__ = ["STRUCTURES", "MOTOR_PARAMS", "SHARES_MOTORS", "plant_structure", "rate_plant_structure",
           "rate_angle_plant_structure",
           "yaw_rate_plant_structure"]


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
                             delay_s: float = 0.005) -> GreyBoxModel:
    """Yaw rate plant: ``K (1 + s / z_rad_s) e^(-s delay_s) / ((tau_s s + 1) (s + a_rad_s))`` (module docstring:
    the drag-torque channel ``K``, the rotors' spin-up reaction zero ``z_rad_s = q / J_r``, the in-plane drag pole
    ``a_rad_s = 4 k_h l^2 / J_zz``, the motors' lag and delay).

    Examples
    --------
    >>> yaw_rate_plant_structure().names
    ['K', 'z_rad_s', 'a_rad_s', 'tau_s', 'delay_s']
    """
    params = [Param("K", K, 1e-3, 1e6, "rad/s^2"), Param("z_rad_s", z_rad_s, 0.05, 200.0, "1/s"),
              Param("a_rad_s", a_rad_s, 0.0, 20.0, "1/s"), Param("tau_s", tau_s, 1e-3, 1.0, "s"),
              Param("delay_s", delay_s, 0.0, 0.1, "s")]

    def build(th):
        return ct.ss(ct.tf([th["K"] / th["z_rad_s"], th["K"]], [th["tau_s"], 1.0 + th["tau_s"] * th["a_rad_s"],
                                                                 th["a_rad_s"]]))

    return GreyBoxModel("yaw-rate-plant", params, build, delay_s="delay_s", inputs=["rate_out"], outputs=["rate"])


#: axis -> the constructor of its rate plant's structure
def rate_angle_plant_structure(K: float = 100.0, tau_s: float = 0.03, delay_s: float = 0.005) -> GreyBoxModel:
    """:func:`rate_plant_structure` with the attitude as a second output: ``[rate, att]`` from ``rate_out``, the
    attitude the rate integrated (rad), for a loop closed through the angle controller.

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

    return GreyBoxModel("rate-angle-plant", params, build, delay_s="delay_s", inputs=["rate_out"],
                        outputs=["rate", "att"])


STRUCTURES: dict[str, Callable[[], GreyBoxModel]] = {
    "roll": rate_plant_structure, "pitch": rate_plant_structure, "yaw": yaw_rate_plant_structure}


#: the parameters of the rotors' motors (lag and delay), the same in every axis's structure
MOTOR_PARAMS = ("tau_s", "delay_s")
#: axes whose motor parameters are taken, fixed, from the axes that determine them: a yaw record does not separate
#: the motor lag from the delay (its rate-loop output passes the autopilot's yaw torque low-pass, PX4's
#: MC_YAW_TQ_CUTOFF 2 Hz, and the yaw loop crosses over near 5 rad/s, far below the motor pole at 27 rad/s), while
#: roll and pitch, driven by the same rotors, do
SHARES_MOTORS = {"yaw": ("roll", "pitch")}


def plant_structure(axis: str, gyro_filter: Callable[[float], ct.StateSpace] | None = None,
                    motors: dict | None = None) -> GreyBoxModel:
    """The rate plant structure of ``axis`` (:data:`STRUCTURES`), its output through ``gyro_filter``, with the
    motor parameters ``motors`` (:data:`MOTOR_PARAMS`) known and fixed where given.

    Parameters
    ----------
    axis : {"roll", "pitch", "yaw"}
    gyro_filter : callable, optional
        ``gyro_filter(dt) -> control.StateSpace``: the autopilot's gyro low-pass at sample time ``dt`` (the logged
        rate is the filtered one), from the log's parameters; none when the log's rate is unfiltered or the
        filter unknown.
    motors : dict, optional
        ``{"tau_s": ..., "delay_s": ...}``: the motors' lag and delay, s, identified on the axes of
        :data:`SHARES_MOTORS` (the same rotors), fixed in this structure.

    Examples
    --------
    >>> plant_structure("yaw").name
    'yaw-rate-plant'
    """
    if axis not in STRUCTURES:
        raise KeyError(f"no rate plant structure for axis {axis!r}; axes: {sorted(STRUCTURES)}")
    m = STRUCTURES[axis]()
    m = GreyBoxModel(m.name, m.params, m.build, m.delay, m.inputs, m.outputs, gyro_filter)
    if motors:
        m = m.replace(**{k: {"value": float(motors[k]), "fixed": True} for k in MOTOR_PARAMS})
    return m
