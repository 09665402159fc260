"""Mixer: axis commands (collective, roll, pitch, yaw) in % -> per-rotor commands in %.

Conventions (the physics follows these)
---------------------------------------
* Body frame FRD (standard aerospace): x forward, y right, z down. Rotor positions are given in the body
  x-y plane; pass ``frame='flu'`` for positions in x forward / y left (MuJoCo's usual z-up body frame), they
  are converted by ``y -> -y``.
* Thrust acts along -z (up). A rotor at ``(x, y)`` with thrust ``T`` gives the moment ``r x F = (-y T, x T, 0)``.
* Positive **roll** command -> positive moment about +x -> right side down: rotors on the left (``y < 0``) get
  more thrust.
* Positive **pitch** command -> positive moment about +y -> nose up: front rotors (``x > 0``) get more thrust.
* Positive **yaw** command -> positive moment about +z (down) -> nose right. ``spin_dirs[i] = +1`` means rotor i
  turns clockwise seen from above (angular velocity along +z body); its drag torque on the body is along -z, so
  a positive yaw command speeds up / pitches up the counter-clockwise rotors (``spin_dirs = -1``) and slows the
  clockwise ones.
* Per-rotor command = collective + 0.5 (roll * (-y_i / max|y|) + pitch * (x_i / max|x|) - yaw * spin_i).
  The 0.5 makes an axis command the difference between opposite rotors, as the published "pitch control
  variable" (% blade-pitch difference between opposite rotors, reference 000). E.g. a plus quad with a pitch
  command of 10 %: front +5 %, rear -5 %.

``kind`` sets the per-rotor command range: ``'variable-pitch'`` rotors (fixed RPM, collective blade pitch) can
produce reverse thrust, so commands are clipped to [-100, 100] %; ``'variable-rpm'`` motors to [0, 100] %.
"""

from __future__ import annotations

import math

import numpy as np

from rotorlab.errors import ConfigError

KINDS = {"variable-pitch": (-100.0, 100.0), "variable-rpm": (0.0, 100.0)}
FRAMES = ("frd", "flu")


class Mixer:
    """Linear mixer with per-rotor clipping.

    Parameters
    ----------
    rotor_positions_m : array (n, 2)
        Rotor hub positions in the body x-y plane, m (frame per ``frame``).
    spin_dirs : array (n,)
        +1 clockwise seen from above, -1 counter-clockwise.
    kind : {'variable-pitch', 'variable-rpm'}
    frame : {'frd', 'flu'}
        Frame of ``rotor_positions_m``.

    Attributes
    ----------
    matrix : ndarray (n, 4)
        Maps ``[collective, roll, pitch, yaw]`` (%) to rotor commands (%).
    """

    def __init__(self, rotor_positions_m, spin_dirs, kind: str = "variable-pitch", frame: str = "frd"):
        pos = np.asarray(rotor_positions_m, dtype=float)
        spin = np.asarray(spin_dirs, dtype=float).ravel()
        if pos.ndim != 2 or pos.shape[1] != 2 or pos.shape[0] < 4:
            raise ConfigError(field="rotor_positions_m", expected="an (n, 2) array with n >= 4", got=pos.shape)
        if spin.shape != (pos.shape[0],) or not np.all(np.isin(spin, (-1.0, 1.0))):
            raise ConfigError(field="spin_dirs", expected=f"{pos.shape[0]} values of +1 or -1", got=spin.tolist())
        if kind not in KINDS:
            raise ConfigError(field="kind", expected=f"one of {sorted(KINDS)}", got=kind)
        if frame not in FRAMES:
            raise ConfigError(field="frame", expected=f"one of {FRAMES}", got=frame)
        if frame == "flu":
            pos = pos * np.array([1.0, -1.0])
        x, y = pos[:, 0], pos[:, 1]
        if np.max(np.abs(x)) == 0 or np.max(np.abs(y)) == 0:
            raise ConfigError(field="rotor_positions_m", expected="rotors spread in both x and y", got=pos.tolist())
        self.kind = kind
        self.positions_frd_m = pos
        self.spin_dirs = spin
        self.out_min, self.out_max = KINDS[kind]
        self.matrix = np.column_stack([
            np.ones_like(x),
            0.5 * (-y / np.max(np.abs(y))),
            0.5 * (x / np.max(np.abs(x))),
            0.5 * (-spin),
        ])
        if np.linalg.matrix_rank(self.matrix) < 4:
            raise ConfigError("the rotor layout cannot produce independent collective/roll/pitch/yaw",
                              field="rotor_positions_m/spin_dirs", expected="a mixer matrix of rank 4",
                              got=np.linalg.matrix_rank(self.matrix))
        # least-squares inverse: exact for a quad, the minimum-norm allocation's left inverse for n > 4
        self.pinv = np.linalg.pinv(self.matrix)
        self._rows = tuple(tuple(float(v) for v in row) for row in self.matrix)

    @property
    def n_rotors(self) -> int:
        return self.matrix.shape[0]

    def mix(self, collective: float, roll: float, pitch: float, yaw: float, clip: bool = True) -> tuple:
        """Axis commands (%) -> rotor commands (%), a tuple of floats in rotor order, clipped to the kind's
        range unless ``clip=False``.

        Plain Python on purpose: for 4-8 rotors it is several times faster than building numpy arrays, and it
        runs every tick (one loop: a list comprehension is a function call of its own before Python 3.12).
        """
        lo, hi = (self.out_min, self.out_max) if clip else (-math.inf, math.inf)  # +-inf: no value is changed
        out = []
        for a, b, c, d in self._rows:
            v = collective * a + roll * b + pitch * c + yaw * d
            out.append(hi if v > hi else (lo if v < lo else v))
        return tuple(out)

    def mix_many(self, collective, roll, pitch, yaw) -> np.ndarray:
        """:meth:`mix` for many simulations: axis commands ``(n,)`` (or floats common to all) -> rotor commands
        ``(n, n_rotors)``, the same sums in the same order and the same clip, so each row equals :meth:`mix`."""
        raw = np.stack(np.broadcast_arrays(*[collective * a + roll * b + pitch * c + yaw * d
                                             for a, b, c, d in self._rows]), axis=-1)
        return np.clip(raw, self.out_min, self.out_max, out=raw)

    def unmix(self, rotor_cmds) -> np.ndarray:
        """Rotor commands (%) -> ``[collective, roll, pitch, yaw]`` (%) (exact inverse of unclipped :meth:`mix`)."""
        return self.pinv @ np.asarray(rotor_cmds, dtype=float)


def quad_x(arm_m: float, kind: str = "variable-pitch") -> Mixer:
    """Quadrotor in X layout (arms at +-45 deg), front-right rotor clockwise, as most flight stacks number them."""
    a = arm_m / np.sqrt(2.0)
    pos = [[a, a], [-a, -a], [a, -a], [-a, a]]  # FR, RL, FL, RR
    return Mixer(pos, [1, 1, -1, -1], kind=kind)


def quad_plus(arm_m: float, kind: str = "variable-pitch") -> Mixer:
    """Quadrotor in + layout (front, right, rear, left); front and rear clockwise."""
    pos = [[arm_m, 0.0], [0.0, arm_m], [-arm_m, 0.0], [0.0, -arm_m]]
    return Mixer(pos, [1, -1, 1, -1], kind=kind)
