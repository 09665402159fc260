"""Stage 1, experiments: the identification campaign flown on the twin (one Parquet log per run)."""

from __future__ import annotations

import sys

import numpy as np

from rotorlab.excitation import spectrum_check
from rotorlab.executor import task_seeds
from rotorlab.pipeline.runfolder import Stage, StageContext, read_log, write_log
from rotorlab.pipeline.settings import DT_S
from rotorlab.sim.runner import run_scenario
from rotorlab.sim.scenarios.prbs import campaign_band
from rotorlab.vehicles import load_vehicle

__all__ = ["STAGE", "experiment_plan", "run_experiment", "decimation"]

MIN_BAND_FRACTION = 0.3  # below this share of input power in the target band the campaign misses its aim


def experiment_plan(vehicle: str, s: dict, seed: int) -> list[dict]:
    """The campaign as scenario runs (``rotorlab.sim.scenarios``), one seed per run.

    Variable-pitch vehicles (ref. 000): the quasi-open-loop ``prbs`` campaign (three segments, 7/9/11 %,
    hold ranges designed for the vehicle's ``[campaign] band_rad_s``), a separate ``prbs`` cross-validation run, a closed-loop
    ``prbs-closed`` validation run (PRBS set-point changes with the standard cascade, as the published
    validation data) and the in-flight ``prbs-flight`` run. TUHH (ref. 002): its published route is
    closed-loop (a double integrator cannot fly a quasi-open-loop PRBS), so all three rig runs are
    ``prbs-closed`` with the standard gains and there is no flight run.
    """
    closed = load_vehicle(vehicle).kind != "variable-pitch"
    seeds = task_seeds(seed, 4)
    if closed:
        plan = [{"name": n, "scenario": "prbs-closed", "duration_s": d, "options": {}}
                for n, d in (("id", s["id_s"]), ("cv", s["cv_s"]), ("val", s["val_s"]))]
    else:
        plan = [{"name": "id", "scenario": "prbs", "duration_s": s["id_s"], "options": {}},
                {"name": "cv", "scenario": "prbs", "duration_s": s["cv_s"],
                 "options": {"holds": [1], "amplitudes_pct": [9.0]}},
                {"name": "val", "scenario": "prbs-closed", "duration_s": s["val_s"], "options": {}},
                {"name": "flight", "scenario": "prbs-flight", "duration_s": s["flight_s"], "options": {}}]
    for p, sd in zip(plan, seeds):
        p.update(vehicle=vehicle, seed=sd)
    return plan


def run_experiment(task: dict) -> dict:
    """Fly one campaign run on the twin with :func:`rotorlab.sim.runner.run_scenario` (picklable task for
    the executors, standard gains). Returns the log columns, units and why the run stopped early (or None)."""
    r = run_scenario(task["scenario"], task["vehicle"], gains="standard", seed=task["seed"],
                     duration_s=task["duration_s"], options=task["options"])
    return {"name": task["name"], "columns": {k: r.log[k].copy() for k in r.log.columns}, "units": r.log.units,
            "stopped": r.stopped, "kind": task["scenario"], "scene": r.info["scene"], "seed": task["seed"]}


def decimation(vehicle: str) -> int:
    """Flight-software ticks per identification sample (``DT_S``): 1 for the ANTEOS twins, 5 for the TUHH twin
    whose attitude loop runs at 250 Hz."""
    k = DT_S / load_vehicle(vehicle).control_dt_s
    if abs(k - round(k)) > 1e-9 or round(k) < 1:
        raise ValueError(f"the identification sample time {DT_S} s is not a whole number of {vehicle}'s ticks")
    return int(round(k))


def run(ctx: StageContext) -> dict:
    plan = experiment_plan(ctx.vehicle, ctx.settings, ctx.seed)
    runs = ctx.executor.map(run_experiment, plan, desc="experiments", progress=ctx.opts.progress)
    res = {"runs": {}}
    k = decimation(ctx.vehicle)
    for r in runs:
        meta = {"kind": r["kind"], "scene": r["scene"], "seed": r["seed"], "stopped": r["stopped"]}
        if k > 1:
            # the black-box methods and the bootstrap work at the published 50 Hz: every k-th sample of the
            # flight computer's log; the closed-loop grey-box fit needs the loop's own rate (``{name}-full``)
            write_log(ctx.work / f"{r['name']}-full.parquet", r["columns"], r["units"], meta)
            r["columns"] = {n: v[::k] for n, v in r["columns"].items()}
        write_log(ctx.work / f"{r['name']}.parquet", r["columns"], r["units"], meta)
        c = r["columns"]
        res["runs"][r["name"]] = {"kind": r["kind"], "scene": r["scene"], "seed": r["seed"], "stopped": r["stopped"],
                                  "samples": int(len(c["t"])), "duration_s": float(len(c["t"]) * DT_S),
                                  "u_std_pct": float(np.std(c["u_lon"])), "q_std_dps": float(np.std(c["q"])),
                                  "theta_max_abs_deg": float(np.max(np.abs(c["theta"])))}
    res["excitation"] = excitation_check(read_log(ctx.work / "id.parquet")["u_lon"], load_vehicle(ctx.vehicle))
    if res["excitation"]["warning"]:
        print(f"  WARNING (experiments): {res['excitation']['warning']}", file=sys.stderr)
    return res


def excitation_check(u, vehicle) -> dict:
    """How much of the identification input's power lies in the vehicle's campaign band (ref. 000 aimed the
    PRBS at the dominant attitude dynamics); ``warning`` says so plainly when it is below
    :data:`MIN_BAND_FRACTION`: the bootstrap band is then narrowest elsewhere and h_lim ranks poorly."""
    band = campaign_band(vehicle)
    chk = spectrum_check(u, DT_S, band_rad_s=band)
    out = {"band_rad_s": list(band), "band_fraction": float(chk.band_fraction), "band_min_db": float(chk.band_min_db),
           "min_band_fraction": MIN_BAND_FRACTION, "warning": None}
    if chk.band_fraction < MIN_BAND_FRACTION:
        out["warning"] = (f"only {chk.band_fraction:.0%} of the identification input's power lies in the "
                          f"{band[0]:g}-{band[1]:g} rad/s campaign band (below {MIN_BAND_FRACTION:.0%}): the model "
                          "is least certain where the loops cross over")
    return out


STAGE = Stage("experiments", upstream=(), settings=("id_s", "cv_s", "val_s", "flight_s"), run=run)
