"""An autopilot's loops closed around a plant model: the linear analysis of what the flight software flies."""

from __future__ import annotations

from collections.abc import Mapping

import control as ct
import numpy as np

from rotorlab.autopilots.registry import get

__all__ = ["closed_loop_lti"]


def closed_loop_lti(autopilot, params: Mapping[str, float], axis: str, plant: ct.StateSpace,
                    loop: str = "attitude", gyro_filter: bool = True) -> ct.StateSpace:
    """One axis of an autopilot's cascade closed around ``plant``, discrete at the plant's sample time.

    Parameters
    ----------
    autopilot : module or str
        An entry of :data:`rotorlab.autopilots.AUTOPILOTS` (or its name).
    params : mapping
        The autopilot's parameters (names and units of its table).
    axis : {"roll", "pitch", "yaw"}
    plant : control.StateSpace
        Discrete at the loop period; input the normalised torque of ``axis``; outputs ``[rate (rad/s),
        angle (rad)]`` (for ``loop="rate"`` the angle output may be left out).
    loop : {"attitude", "rate"}
        Close the attitude and rate loops (input the angle set-point, rad) or the rate loop alone (input the rate
        set-point, rad/s: the autopilot's acro mode).
    gyro_filter : bool
        The gyro low-pass in the loop (the plant's rate is the raw gyro).

    Returns
    -------
    control.StateSpace
        Input ``["angle_sp"]`` or ``["rate_sp"]``; outputs ``["rate", "angle", "torque"]`` (``"angle"`` only when
        the plant gives it).

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import autopilots
    >>> dt = 1 / 400
    >>> P = ct.ss([[1, 0], [dt, 1]], [[dt / 0.02], [0]], [[1, 0], [0, 1]], [[0], [0]], dt)  # J = 0.02 per unit torque
    >>> T = autopilots.closed_loop_lti("px4", autopilots.px4.TABLE.defaults(), "roll", P)
    >>> T.input_labels, T.output_labels
    (['angle_sp'], ['rate', 'angle', 'torque'])
    """
    ap = get(autopilot) if isinstance(autopilot, str) else autopilot
    dt = float(plant.dt)
    has_angle = plant.noutputs >= 2
    if loop == "attitude" and not has_angle:
        raise ValueError("the attitude loop needs a plant with outputs [rate, angle]")
    if loop not in ("attitude", "rate"):
        raise ValueError(f"loop must be 'attitude' or 'rate', got {loop!r}")
    outs = ["rate", "angle"][: plant.noutputs]
    P = ct.ss(plant.A, plant.B, plant.C, plant.D, dt, inputs=["torque"], outputs=outs)
    C = ap.rate_controller_lti(params, axis, dt, gyro_filter=gyro_filter)
    C = ct.ss(C.A, C.B, C.C, C.D, dt, inputs=["rate_sp", "rate"], outputs=["torque"])
    systems = [P, C]
    if loop == "attitude":
        K = ap.attitude_controller_lti(params, axis, dt)
        systems.append(ct.ss(K.A, K.B, K.C, K.D, dt, inputs=["angle_sp", "angle"], outputs=["rate_sp"]))
        inp = "angle_sp"
    else:
        inp = "rate_sp"
    T = ct.interconnect(systems, inplist=[inp], outlist=[*outs, "torque"])
    return ct.ss(np.asarray(T.A), np.asarray(T.B), np.asarray(T.C), np.asarray(T.D), dt, inputs=[inp],
                 outputs=[*outs, "torque"], name=f"{ap.NAME}_{axis}_{loop}_loop")
