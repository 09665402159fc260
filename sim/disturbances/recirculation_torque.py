"""Rotor-wake recirculation: a slow random moment disturbance of an indoor test-bed.

Physical reading: in a closed room the rotors' downwash hits the floor and walls and comes back into the rotor
disks as an unsteady, uneven inflow. Each rotor's thrust then wanders slowly and differently, which the vehicle
feels as random roll/pitch/yaw moments with most of their power below a couple of hertz (reference 000 lists
"aerodynamic disturbances due to rotors wake recirculation in closed indoor test area" on the test-bed results).
The model is what such a disturbance looks like to the loop, not a flow simulation: independent Gaussian
white noise per axis through a Butterworth low-pass (default 4th order, 1.5 Hz), scaled so the stationary RMS
is the stated one.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from rotorlab.errors import ConfigError


class RecirculationTorque:
    """Seeded low-frequency moment disturbance.

    Parameters
    ----------
    rms_Nm : float or (n_axes,)
        Stationary RMS per axis, N m.
    cutoff_hz : float
        Low-pass corner, Hz (power above about ``2 cutoff_hz`` is negligible).
    order : int
        Butterworth order.
    n_axes : int
        Number of independent axes (3: roll, pitch, yaw).
    seed, rng : int or numpy.random.Generator
    """

    def __init__(self, rms_Nm, cutoff_hz: float = 1.5, order: int = 4, n_axes: int = 3, seed=None,
                 rng: np.random.Generator | None = None):
        rms = np.broadcast_to(np.asarray(rms_Nm, dtype=float), (n_axes,)).copy()
        if np.any(rms < 0):
            raise ConfigError(field="rms_Nm", expected="values >= 0 N m", got=rms.tolist())
        if not cutoff_hz > 0 or order < 1:
            raise ConfigError(field="cutoff_hz/order", expected="cutoff_hz > 0 and order >= 1", got=(cutoff_hz, order))
        self.rms_Nm = rms
        self.cutoff_hz = float(cutoff_hz)
        self.order = int(order)
        self.rng = rng if rng is not None else np.random.default_rng(seed)

    def filter_sos(self, dt: float) -> np.ndarray:
        """The discrete low-pass (second-order sections) used at sample time ``dt``."""
        nyq = 0.5 / dt
        if not self.cutoff_hz < nyq:
            raise ConfigError(field="cutoff_hz", expected=f"below the Nyquist frequency {nyq} Hz", got=self.cutoff_hz)
        return signal.butter(self.order, self.cutoff_hz, btype="low", fs=1.0 / dt, output="sos")

    def generate(self, n: int, dt: float) -> np.ndarray:
        """``n`` samples every ``dt`` s, shape ``(n, n_axes)``, N m."""
        n = int(n)
        if n < 1 or not dt > 0:
            raise ConfigError(field="n/dt", expected="n >= 1 and dt > 0", got=(n, dt))
        sos = self.filter_sos(dt)
        # the filter's white-noise gain sqrt(sum h^2) from a long impulse response (it decays within
        # ~order / cutoff_hz seconds), so the scale gives exactly the stated stationary RMS
        n_imp = int(math.ceil(50.0 * self.order / self.cutoff_hz / dt))
        imp = np.zeros(n_imp)
        imp[0] = 1.0
        gain = math.sqrt(float(np.sum(signal.sosfilt(sos, imp) ** 2)))
        n_burn = n_imp // 5
        e = self.rng.standard_normal((n + n_burn, self.rms_Nm.size))
        y = signal.sosfilt(sos, e, axis=0)[n_burn:]
        return y * (self.rms_Nm / gain)
