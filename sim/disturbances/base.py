"""The disturbance protocol: one file per disturbance, composable in any scenario.

A disturbance acts physically through the simulator at every control tick (before the batched physics
steps): it may add to ``sim.wind_world`` (m/s, world z-up; drives fuselage drag through ``opt.wind`` and the
rotors' inflow/H-force actuators) and, declaring ``rotates_air``, to ``sim.air_rate_world`` (rad/s), write
wrenches into ``sim.data.xfrc_applied`` (cleared every tick), or move mocap bodies it added to the model in
:meth:`edit`. Its ground truth is logged through :meth:`values`.
"""

from __future__ import annotations

import mujoco

from rotorlab.errors import ConfigError


class Disturbance:
    """Base class; subclasses override what they need."""

    #: unique name, also seeds the disturbance's own random stream
    name: str = "disturbance"
    #: logged ground-truth columns, name -> unit
    columns: dict = {}
    #: scenes that can host it (None: all)
    scenes: tuple | None = None
    #: the earliest stage of MuJoCo's forward pass whose inputs :meth:`update` changes: ``mjSTAGE_POS``
    #: (positions, mocap bodies, the model; the safe default), ``mjSTAGE_VEL`` (``opt.wind``: anything added to
    #: ``sim.wind_world``), ``mjSTAGE_ACC`` (controls, ``xfrc_applied``). The simulator's regrouped tick
    #: recomputes the stages from there on (:meth:`rotorlab.sim.simulator.Simulator.tick`); an understated stage
    #: would leave stale forces in the first physics step of a tick.
    stage: mujoco.mjtStage = mujoco.mjtStage.mjSTAGE_POS
    #: it adds the air's rotation (rad/s, world) to ``sim.air_rate_world`` (turbulence gust gradients)
    rotates_air: bool = False

    def check_scene(self, scene: str) -> None:
        """Raise a clear error when the scene cannot host this disturbance."""
        if self.scenes is not None and scene not in self.scenes:
            raise ConfigError(f"the '{self.name}' disturbance cannot be hosted by the {scene} scene "
                              f"(it needs one of {list(self.scenes)})", field="disturbances",
                              expected=list(self.scenes), got=scene)

    def edit(self, spec, scene: str, vehicle) -> bool:
        """Add model elements before compilation (tendons, anchors). Return True if an anchor was added."""
        return False

    def reset(self, sim, rng) -> None:
        """Start of a run; ``rng`` is this disturbance's own seeded ``numpy.random.Generator``."""

    def update(self, sim, t: float) -> None:
        """Act on the simulator for the coming control period starting at ``t`` (s)."""

    def values(self, sim) -> dict:
        """Ground-truth values of :attr:`columns` at the current tick."""
        return {}
