"""Stage 4, tune: tuning to the vehicle's shipped spec, every gain set's goals, robust-stability limit
``h_lim`` and a Monte Carlo at ``h_lim``; the test-bed -> flight transfer; TUHH's H-inf design comparison."""

from __future__ import annotations

import dataclasses
import functools
import math

import control as ct
import numpy as np

from rotorlab.errors import DataError
from rotorlab.gains import save_gains
from rotorlab.lti import as_ss, is_stable
from rotorlab.pipeline.models import gains_table, mc_plant
from rotorlab.pipeline.runfolder import Stage, StageContext
from rotorlab.pipeline.settings import DT_S
from rotorlab.tune import evaluate, h_lim, hinf_mixed_sensitivity, load_spec, tune_cascade
from rotorlab.tune.cascade import cascade_mc, cascade_plant, closed_cascade, control_sensitivity_cascade
from rotorlab.tune.montecarlo import montecarlo, step_stats
from rotorlab.tune.spec import builtin_specs

__all__ = ["STAGE", "step_metrics", "HINF_DT_S"]

HINF_DT_S = 0.004  # TUHH H-inf design comparison rate (the design is unstable at 50 Hz, see _tuhh_designs)
STEP_T_FINAL_S = 3.0  # nominal and Monte Carlo step responses
MC_QUANTILES = (0.0, 0.05, 0.5, 0.95, 1.0)  # stored Monte Carlo bands: min, 5 %, median, 95 %, max
TUHH_STEP_DEG = 10.0  # ref. 002: 10 deg set-point step, 10 % command input disturbance


def step_metrics(model, axis_gains, t_final_s: float = STEP_T_FINAL_S) -> dict:
    """Nominal linear set-point step of the cascade on ``model``: IAE (deg s per deg), rise, overshoot."""
    cl = closed_cascade(model, axis_gains, ("theta_ref",), ("theta",), DT_S)
    if not is_stable(cl):
        return {"iae": math.inf, "rise_s": math.nan, "overshoot_pct": math.nan}
    t = np.arange(0.0, t_final_s + 1e-9, DT_S)
    _, y = ct.step_response(cl, T=t)
    y = np.ravel(y)
    st = step_stats(t, y)
    return {"iae": float(np.sum(np.abs(1.0 - y)) * DT_S), "rise_s": st["rise_s"],
            "overshoot_pct": st["overshoot_pct"]}


def run(ctx: StageContext) -> dict:
    """Tune to the vehicle's shipped spec from its standard gains (``rotorlab.tune.tune_cascade``), evaluate
    every gain set's goals, h_lim and a Monte Carlo at h_lim; TUHH (no shipped spec) compares its H-inf
    design with the standard cascade instead."""
    ident = ctx.run.result("identify")
    nominal = ctx.run.plant(ident["nominal"], "nominal")
    W = ctx.run.w_delta()
    G_mc = ctx.run.identified(ctx.run.result("bootstrap")["model"])
    res = {"nominal_model": ident["nominal"], "delay_s": nominal.delay_s}
    sets = ctx.run.gain_sets(tuned=False)
    if ctx.vehicle in builtin_specs():
        spec = load_spec(ctx.vehicle)
        tr = tune_cascade(spec, [nominal], sets["standard"], starts=ctx.settings["tune_starts"], seed=ctx.seed,
                          n_jobs=ctx.executor.workers)
        save_gains(tr.gains, ctx.work / "tuned.toml")
        hard_failed = [r.goal for r in tr.report if r.hard and not r.passed]
        res["tuning"] = {"status": "done" if not hard_failed else "hard goals failed", "spec": spec.name,
                         "objective": float(tr.objective), "starts": tr.starts,
                         "iterations": len(tr.history), "hard_failed": hard_failed}
        sets["tuned"] = tr.gains
        res["goals"] = {name: [dataclasses.asdict(r) for r in evaluate(spec, gs, [nominal])]
                        for name, gs in sets.items()}
    else:
        res["tuning"] = {"status": f"skipped: no shipped tuning spec for {ctx.vehicle} (rotorlab.tune specs: "
                                   f"{', '.join(builtin_specs())}); the report compares designs instead"}
        res["goals"] = {}
        res["designs"] = _tuhh_designs(nominal, sets["standard"]["pitch"])
    res["gains"] = {k: gains_table(gs) for k, gs in sets.items()}
    res["h_lim"], res["montecarlo"], res["step"] = {}, {}, {}
    mc_arrays = {}
    for k, (name, gs) in enumerate(ctx.progress(sets.items(), "h_lim + montecarlo", total=len(sets))):
        ax = gs["pitch"]
        res["step"][name] = step_metrics(nominal, ax)
        res["h_lim"][name] = float(h_lim(W, control_sensitivity_cascade(mc_plant(G_mc), ax, DT_S)))
        mc = montecarlo(G_mc.sys, W, functools.partial(cascade_mc, axis_gains=ax, delay_s=G_mc.delay * DT_S, dt=DT_S),
                        res["h_lim"][name], n=ctx.settings["n_mc"], seed=np.random.SeedSequence([ctx.seed, k]),
                        n_jobs=ctx.executor.workers, t_final_s=STEP_T_FINAL_S, progress=False)
        summ = mc.summary()
        res["montecarlo"][name] = {"n": ctx.settings["n_mc"], "h": res["h_lim"][name],
                                   "fraction_unstable": float(summ["fraction_unstable"]),
                                   **{k2: [float(x) for x in summ[k2]] for k2 in ("rise_s", "settling_s",
                                                                                  "overshoot_pct", "load_peak")}}
        mc_arrays[f"{name}__setpoint"] = mc.band("setpoint", MC_QUANTILES)
        mc_arrays[f"{name}__load"] = mc.band("load", MC_QUANTILES)
        mc_arrays["t"] = mc.t
    np.savez(ctx.work / "montecarlo.npz", **mc_arrays)
    res["transfer"], res["h_lim_flight"] = _transfer(ctx, sets, nominal, W)
    return res


def _transfer(ctx: StageContext, sets, nominal, W):
    """Test-bed gains on the in-flight model: nominal tracking IAE on each model and h_lim with the flight
    model (the paper's 'test-bed tuning transfers to flight' claim)."""
    if not ctx.run.model_path("pbsid-flight").exists():
        return {}, {}
    flight = ctx.run.plant("pbsid-flight", "flight")
    Wf = W  # the test-bed W_delta: the paper gives flight h_lim with its own W_delta, not published
    transfer, hl = {}, {}
    for name, gs in sets.items():
        a, b = step_metrics(nominal, gs["pitch"])["iae"], step_metrics(flight, gs["pitch"])["iae"]
        transfer[name] = {"iae_testbed": a, "iae_flight": b,
                          "loss_pct": 100.0 * (b - a) / a if math.isfinite(a) and math.isfinite(b) else None}
        try:
            hl[name] = float(h_lim(Wf, control_sensitivity_cascade(flight, gs["pitch"], DT_S)))
        except DataError as exc:  # the set does not stabilise the flight model: no robustness to speak of
            hl[name] = None
            transfer[name]["flight_loop"] = str(exc)
    return transfer, hl


def _tuhh_designs(nominal, std_axis) -> dict:
    """TUHH (ref. 002): H-inf mixed-sensitivity design (``rotorlab.tune.hinf_mixed_sensitivity``, on the
    published axis model) vs the standard cascade, both closed around the identified model (50 Hz): rise time
    of a 10 deg step and peak angle deviation under a step input disturbance of 10 % command (published:
    about 200 ms; 4 deg for H-inf vs 15 deg for a modified PID)."""
    K, gamma = hinf_mixed_sensitivity("pitch")
    # K: [r - angle (rad), -rate (rad/s)] -> b (unit command); the twin: deg, deg/s, % (u = 100 b)
    K = as_ss(K) * (100.0 * math.pi / 180.0)

    def hinf_loop(dt):
        Kd = ct.c2d(K, dt, method="tustin")
        Gp = cascade_plant(nominal, dt)  # u -> [q; theta], delay included
        Gs = ct.ss(Gp.A, Gp.B, Gp.C[::-1], Gp.D[::-1], dt)  # u -> [theta; q], the order K reads
        # u = Kd ([r; 0] - [theta; q]) + d
        return {"r->theta": ct.feedback(Gs * Kd, np.eye(2))[0, 0], "d->theta": ct.feedback(Gs, Kd)[0, 0],
                "r->u": ct.feedback(Kd, Gs)[0, 0]}

    # the design has a lightly damped controller mode near 87 rad/s: at the twin's 50 Hz it destabilises the
    # loop, so the comparison runs it at 250 Hz (and reports the 50 Hz verdict)
    stable_50hz = all(is_stable(c) for c in hinf_loop(DT_S).values())
    h = hinf_loop(HINF_DT_S)
    cl_s = closed_cascade(nominal, std_axis, ("theta_ref", "d_u"), ("theta", "u"), DT_S)
    std = {"r->theta": cl_s[0, 0], "d->theta": cl_s[0, 1], "r->u": cl_s[1, 0]}
    out = {"hinf_gamma": float(gamma), "hinf_order": int(K.nstates), "hinf_stable_at_50hz": bool(stable_50hz),
           "hinf_dt_s": HINF_DT_S}
    for name, ch, dt in (("hinf-mixed-sensitivity", h, HINF_DT_S), ("standard", std, DT_S)):
        t = np.arange(0.0, STEP_T_FINAL_S + 1e-9, dt)
        stable = all(is_stable(c) for c in ch.values())
        entry = {"stable": bool(stable), "rate_hz": round(1.0 / dt)}
        if stable:
            # 10 deg step / 10 % input disturbance
            y = {k: TUHH_STEP_DEG * np.ravel(ct.step_response(c, T=t).outputs) for k, c in ch.items()}
            st = step_stats(t, y["r->theta"])
            entry.update(rise_s=st["rise_s"], overshoot_pct=st["overshoot_pct"],
                         disturbance_peak_deg=float(np.max(np.abs(y["d->theta"]))),
                         step_u_peak_pct=float(np.max(np.abs(y["r->u"]))))
        out[name] = entry
    out["published"] = {"rise_s": 0.2, "disturbance_peak_deg": {"hinf": 4.0, "modified-pid": 15.0}}
    return out


STAGE = Stage("tune", upstream=("identify", "bootstrap"), settings=("n_mc", "tune_starts"), run=run)
