"""Plug-ins: user code that runs inside the flight-software loop every tick.

A plug-in sees every named signal of the tick (measurements, set-points, commands: ``theta``, ``q``,
``q_ref``, ``u_lon``, ...) and returns a dict: names that already exist as commands override them
(``{'u_lon': ...}`` replaces the pitch command), new names are logged. Plug-ins run after the built-in
loops and before the final saturation and the mixer, in the order given.

Typical uses: a discrete H-inf controller from ``rotorlab.tune`` (:class:`StateSpacePlugin`), an on-line
estimator such as the LMS from ``rotorlab.ident`` (:class:`CallbackPlugin`). ``rotorlab.sim`` never imports
those packages: the caller builds the object and hands it in.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

from rotorlab.errors import ConfigError

# python-control (which loads matplotlib) is imported where a plug-in is built from a system: the flight
# software itself runs without it.


@runtime_checkable
class Plugin(Protocol):
    def reset(self) -> None:
        """Return to the initial state (called when the flight software resets)."""

    def step(self, t: float, signals: dict) -> dict:
        """One tick at time ``t`` (s); return overrides and extra log values by name."""


class StateSpacePlugin:
    """Runs a discrete ``control.StateSpace`` on named signals.

    ``x[k+1] = A x[k] + B u[k]``, ``y[k] = C x[k] + D u[k]`` with ``u[k] = [signals[n] for n in inputs]`` and
    the outputs returned under ``outputs``.

    Parameters
    ----------
    sys : control.StateSpace
        Discrete, ``sys.dt`` equal to the flight-software period (checked when ``dt`` is given).
    inputs, outputs : list of str
        Signal names, as many as the system has inputs and outputs.
    dt : float, optional
        Flight-software period, s, to check ``sys.dt`` against.
    x0 : array, optional
        Initial state (default zero).
    """

    def __init__(self, sys, inputs, outputs, dt: float | None = None, x0=None):
        import control as ct

        if not isinstance(sys, ct.StateSpace):
            raise ConfigError(field="sys", expected="a control.StateSpace", got=type(sys).__name__)
        if not (sys.dt is not None and sys.dt is not True and sys.dt > 0):
            raise ConfigError("the plug-in runs once per tick", field="sys.dt",
                              expected="a discrete system with dt > 0 s", got=sys.dt)
        if dt is not None and abs(float(sys.dt) - dt) > 1e-12:
            raise ConfigError(field="sys.dt", expected=f"the flight-software period {dt} s", got=sys.dt)
        inputs, outputs = list(inputs), list(outputs)
        if len(inputs) != sys.ninputs or len(outputs) != sys.noutputs:
            raise ConfigError(field="inputs/outputs", expected=f"{sys.ninputs} input and {sys.noutputs} output names",
                              got=(inputs, outputs))
        self.sys = sys
        self.inputs, self.outputs = inputs, outputs
        self.A, self.B, self.C, self.D = (np.array(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
        n = self.A.shape[0]
        self._x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).reshape(n)
        self.x = self._x0.copy()
        self._u = np.zeros(len(inputs))

    def reset(self) -> None:
        self.x = self._x0.copy()

    def step(self, t: float, signals: dict) -> dict:
        u = self._u
        try:
            for i, name in enumerate(self.inputs):
                u[i] = signals[name]
        except KeyError as exc:
            raise ConfigError("state-space plug-in input not among the tick's signals", field=str(exc.args[0]),
                              expected=f"one of {sorted(signals)}") from None
        y = self.C @ self.x + self.D @ u
        self.x = self.A @ self.x + self.B @ u
        return {name: float(v) for name, v in zip(self.outputs, y)}


class CallbackPlugin:
    """Wraps a function ``fn(t, signals) -> dict`` (and an optional ``reset_fn()``) as a plug-in."""

    def __init__(self, fn: Callable[[float, dict], dict], reset_fn: Callable[[], None] | None = None):
        if not callable(fn):
            raise ConfigError(field="fn", expected="a callable fn(t, signals) -> dict", got=fn)
        self.fn = fn
        self.reset_fn = reset_fn

    def reset(self) -> None:
        if self.reset_fn is not None:
            self.reset_fn()

    def step(self, t: float, signals: dict) -> dict:
        return self.fn(t, signals) or {}
