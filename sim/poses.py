"""Per-tick body poses and rotor forces of a run, kept for visual logs (:mod:`rotorlab.sim.rerun_log`).

Filled by ``run_scenario(..., record_poses=True)`` at the same instants as the log rows, into preallocated
arrays (a few array copies per tick), so a recording never needs to re-simulate.
"""

from __future__ import annotations

import mujoco
import numpy as np


class PoseTrack:
    """Poses of every body, rotor thrust, wind and tendon paths, one row per control tick.

    Attributes (``n`` rows filled)
    ------------------------------
    model : mujoco.MjModel
        The compiled model the run used (geometry for the recording).
    t : (n,) s; xpos : (n, nbody, 3) m, world; xquat : (n, nbody, 4) w-x-y-z
    rotor_pos : (n, nrotor, 3) m; rotor_axis : (n, nrotor, 3) unit thrust axes; thrust_N : (n, nrotor)
    wind : (n, 3) m/s, world z-up
    tendon_path : (n, ntendon, maxwrap, 3) m, padded with NaN; tendon_wrapnum : (n, ntendon)
    """

    def __init__(self, sim, capacity: int):
        m = sim.model
        self.model = m
        self.body_names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i) or f"body{i}" for i in range(m.nbody)]
        self._thrust = np.asarray(sim.scene.thrust_actuators, dtype=int)
        self._sites = np.asarray(m.actuator_trnid[self._thrust, 0], dtype=int) if len(self._thrust) else np.zeros(0, int)
        nr = len(self._thrust)
        self._maxwrap = 2 * int(m.nwrap) if m.ntendon else 0
        self.t = np.full(capacity, np.nan)
        self.xpos = np.zeros((capacity, m.nbody, 3))
        self.xquat = np.zeros((capacity, m.nbody, 4))
        self.rotor_pos = np.zeros((capacity, nr, 3))
        self.rotor_axis = np.zeros((capacity, nr, 3))
        self.thrust_N = np.zeros((capacity, nr))
        self.wind = np.zeros((capacity, 3))
        self.tendon_path = np.full((capacity, m.ntendon, max(self._maxwrap, 1), 3), np.nan)
        self.tendon_wrapnum = np.zeros((capacity, m.ntendon), dtype=int)
        self.n = 0
        # views into MjData's buffers, taken once: every attribute access through the bindings builds a new
    # numpy view, which the per-tick recording would otherwise pay for each array
        d = sim.data
        self._d_xpos, self._d_xquat, self._d_site_xpos, self._d_site_xmat = d.xpos, d.xquat, d.site_xpos, d.site_xmat
        self._d_force = d.actuator_force

    def record(self, sim) -> None:
        k = self.n
        d = sim.data
        self.t[k] = d.time
        self.xpos[k] = self._d_xpos
        self.xquat[k] = self._d_xquat
        if len(self._thrust):
            self.rotor_pos[k] = self._d_site_xpos[self._sites]
            self.rotor_axis[k] = self._d_site_xmat[self._sites].reshape(-1, 3, 3)[:, :, 2]
            # thrust actuators act along +z of their site; actuator_force is that force, N
            self.thrust_N[k] = self._d_force[self._thrust]
        self.wind[k] = sim.wind_world
        if self.model.ntendon:
            # wrap_xpos holds the path points of every tendon, 3 numbers each (MuJoCo stores it as nwrap x 6)
            pts = d.wrap_xpos.reshape(-1, 3)
            for i in range(self.model.ntendon):
                adr, num = d.ten_wrapadr[i], d.ten_wrapnum[i]
                self.tendon_wrapnum[k, i] = num
                self.tendon_path[k, i, :num] = pts[adr:adr + num]
        self.n = k + 1

    def trimmed(self) -> PoseTrack:
        """The same track with the arrays cut to the filled rows."""
        for name in ("t", "xpos", "xquat", "rotor_pos", "rotor_axis", "thrust_N", "wind", "tendon_path",
                     "tendon_wrapnum"):
            setattr(self, name, getattr(self, name)[: self.n])
        return self


__all__ = ["PoseTrack"]
