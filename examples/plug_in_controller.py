"""
Plug in your own controller
===========================

A controller is data, not code: a discrete state-space system on named flight-software signals
(:class:`rotorlab.sim.control.statespace.ControllerSpec`), flown in place of the attitude cascade on the commands
it sets. Here a single-loop PID on the pitch angle with rate feedback, ``u = kp e + ki sum(e) dt - kd q`` with
``e = theta_ref - theta``, is written as a python-control system, saved as a controller file and flown in the
set-point scenario beside the published cascade.

The same file flies from the command line: ``rotorlab run setpoint --controller my-pid.json``.
"""

import tempfile
from pathlib import Path

import control as ct
import numpy as np

from rotorlab.sim.control.statespace import ControllerSpec, load_controller, save_controller
from rotorlab.sim.runner import run_scenario

DT_S = 0.02  # the P2-A2's flight-software period (50 Hz); a controller may run at a whole multiple of it
KP, KI, KD = 3.0, 1.5, 0.45  # %/deg, %/(deg s), %/(deg/s)

# %%
# The controller: one state, the forward-Euler integral of the angle error; inputs theta_ref, theta (deg) and
# q (deg/s), output the pitch command u_lon (%).
pid = ct.ss([[1.0]], [[DT_S, -DT_S, 0.0]], [[KI]], [[KP, -KP, -KD]], DT_S,
            inputs=["theta_ref", "theta", "q"], outputs=["u_lon"])
spec = ControllerSpec(name="angle-pid", dt_s=DT_S, inputs=tuple(pid.input_labels), outputs=tuple(pid.output_labels),
                      A=pid.A, B=pid.B, C=pid.C, D=pid.D, description="PID on the pitch angle with rate feedback")
path = save_controller(Path(tempfile.mkdtemp()) / "my-pid.json", spec)
spec = load_controller(path)  # what `rotorlab run --controller` reads

# %%
# Fly the set-point scenario (a 0.3 deg step with the IMU noise off, then back) with each controller.
cascade = run_scenario("setpoint", "anteos-p2a2", duration_s=6.0)
mine = run_scenario("setpoint", "anteos-p2a2", duration_s=6.0, controller=spec)
for name, run in (("published cascade", cascade), ("angle PID", mine)):
    step = run.metrics["linear_step"]
    print(f"{name:18s} rise {step['rise_time_s']:.3f} s, overshoot {step['overshoot_pct']:.1f} %, "
          f"error after 2.5 s {step['steady_state_error']:+.4f} deg")
assert mine.stopped is None and np.isfinite(mine.metrics["linear_step"]["rise_time_s"])
