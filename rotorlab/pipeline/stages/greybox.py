"""Stage greybox: ref. 002's closed-loop grey-box identification of all three attitude axes on the twin
(:func:`rotorlab.greybox_axes.identify_axis`: known PD, periodic full-length PRBS averaged over the periods,
roll and pitch on their rigs, yaw in free flight), against the twin's truth and the published table 1.
Vehicles without the TUHH axis model (the ANTEOS twins) skip it."""

from __future__ import annotations

from rotorlab.executor import task_seeds
from rotorlab.greybox_axes import AXES, identify_axis
from rotorlab.pipeline.runfolder import Stage, StageContext, jsonable

__all__ = ["STAGE", "identify_task"]

#: the vehicles whose axes follow ref. 002's model (variable RPM, rotor inertia in the yaw reaction)
VEHICLES = ("tuhh-quad",)


def identify_task(task: dict) -> dict:
    """One axis (picklable task for the executors)."""
    return {"axis": task["axis"], **identify_axis(task["vehicle"], task["axis"], seed=task["seed"],
                                                   periods=task["periods"], restarts=task["restarts"])}


def run(ctx: StageContext) -> dict:
    if ctx.vehicle not in VEHICLES:
        return {"skipped": f"skipped: the three-axis grey-box route is ref. 002's (vehicles {list(VEHICLES)})"}
    s = ctx.settings
    tasks = [{"vehicle": ctx.vehicle, "axis": ax, "seed": sd, "periods": s["greybox_periods"],
              "restarts": s["greybox_restarts"]} for ax, sd in zip(AXES, task_seeds(ctx.seed + 2, len(AXES)))]
    out = ctx.executor.map(identify_task, tasks, desc="grey-box axes", progress=ctx.opts.progress)
    return {"axes": {r.pop("axis"): jsonable(r) for r in out}}


STAGE = Stage("greybox", upstream=(), settings=("greybox_periods", "greybox_restarts"), run=run)
