"""The end-to-end twin experiment: identification campaign -> identification -> bootstrap -> tuning ->
re-injection of the gains into the validation scenarios -> report (rotorlab issue 6).

Run folder layout (``OUT``)::

    manifest.json                 format version, rotorlab version, vehicle, seed, per-stage hashes and times
    stages/<stage>/               one folder per stage, committed whole (rename) when the stage finishes
        stage.json                the stage's input hash and its result (every number it produced)
        ...                       its files: logs (Parquet), models (JSON, rotorlab.ident.modelio), gains (TOML)
    report/                       the report stage: report.md, report.html, summary.json, figures/*.png, models/, gains/

Caching and resume: a stage is skipped when ``stages/<stage>/stage.json`` holds the same input hash, computed
from the vehicle TOML and gain-file bytes, the effective settings (``--quick``/``--tiny`` grids and sizes),
the seed, the upstream stages' output hashes, the rotorlab version and :data:`FORMAT_VERSION`. A stage
builds its files in ``stages/.<stage>.partial`` and is renamed into place only when complete, so Ctrl-C, a
crash or a full disk loses nothing already done and never leaves a half stage that looks finished.
The executor is not part of the hash: every executor gives the same numbers (seeds per task).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from rotorlab import atomic
from rotorlab.errors import RotorlabError

__all__ = ["FORMAT_VERSION", "STAGES", "PipelineError", "PipelineOptions", "settings_for", "run_pipeline",
           "cascade_loop", "read_manifest", "stage_result", "stage_dir"]

FORMAT_VERSION = 1
STAGES = ("experiments", "identify", "bootstrap", "tune", "validate", "report")
DT_S = 0.02  # published flight-software and identification sample time
VALIDATION_SCENARIOS = ("setpoint", "gust", "rope-pull", "hover")


class PipelineError(RotorlabError):
    """The pipeline cannot run as asked (incompatible run folder, bad option)."""


@dataclasses.dataclass
class PipelineOptions:
    """What ``rotorlab pipeline`` was asked. ``level``: 'full', 'quick' or 'tiny' (tests)."""

    vehicle: str = "anteos-p2a2"
    out: Path = Path("pipeline-run")
    level: str = "full"
    seed: int = 0
    executor: str = "local"
    workers: int | None = None
    progress: bool = True
    n_boot: int | None = None
    n_mc: int | None = None


def settings_for(level: str, n_boot: int | None = None, n_mc: int | None = None) -> dict:
    """Effective sizes and grids of a run; part of every stage hash.

    ``full`` follows the published campaign and grids; ``quick`` keeps the grids tiny but includes the
    published best settings; ``tiny`` is for tests (seconds per stage, every stage exercised).
    """
    base = {
        # (hold_range_s, amplitude_pct, duration_s) per concatenated PRBS segment (ref. 000)
        "full": dict(segments=[[[0.05, 0.1], 7.0, 40.0], [[0.1, 0.2], 9.0, 40.0], [[0.2, 0.4], 11.0, 40.0]],
                     cv_s=40.0, val_s=30.0, flight_s=60.0, moesp_orders=[2, 3, 4, 5, 6], moesp_horizons=[20, 30, 40],
                     pbsid_orders=[2, 3, 4, 5, 6], pbsid_horizons=[[11, 7], [15, 10], [20, 10]],
                     lms_orders=[2, 3, 4, 5], lms_taps=60, n_boot=1000, n_mc=1000, validation_s={}, record_runs=None,
                     hinf_restarts=3, oe_restarts=2),
        "quick": dict(segments=[[[0.05, 0.1], 7.0, 20.0], [[0.1, 0.2], 9.0, 20.0], [[0.2, 0.4], 11.0, 20.0]],
                      cv_s=20.0, val_s=20.0, flight_s=30.0, moesp_orders=[2, 4], moesp_horizons=[20, 40],
                      pbsid_orders=[2, 5], pbsid_horizons=[[11, 7]], lms_orders=[2, 4], lms_taps=50, n_boot=50,
                      n_mc=100, validation_s={}, record_runs=None, hinf_restarts=1, oe_restarts=0),
        "tiny": dict(segments=[[[0.05, 0.1], 7.0, 8.0], [[0.1, 0.2], 9.0, 8.0], [[0.2, 0.4], 11.0, 8.0]],
                     cv_s=10.0, val_s=8.0, flight_s=12.0, moesp_orders=[4], moesp_horizons=[20],
                     pbsid_orders=[2], pbsid_horizons=[[11, 7]], lms_orders=[2], lms_taps=40, n_boot=8, n_mc=20,
                     validation_s={"setpoint": 7.0, "gust": 5.0, "rope-pull": 6.0, "hover": 6.0}, record_runs=1,
                     hinf_restarts=0, oe_restarts=0),
    }
    if level not in base:
        raise PipelineError(f"unknown level '{level}'; valid: full, quick, tiny")
    s = dict(base[level], level=level)
    if n_boot is not None:
        s["n_boot"] = int(n_boot)
    if n_mc is not None:
        s["n_mc"] = int(n_mc)
    return s


# ----------------------------------------------------------------------------------------------------------
# hashing, manifest, stage commit


def _sha(obj) -> str:
    data = obj if isinstance(obj, bytes) else json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha256(data).hexdigest()


def _vehicle_fingerprint(vehicle: str) -> dict:
    from rotorlab.vehicles import vehicle_path

    p = vehicle_path(vehicle)
    files = [p] + sorted((p.parent / "gains").glob("*.toml"))
    return {f.name if f == p else f"gains/{f.name}": _sha(f.read_bytes()) for f in files}


def _dir_hash(path: Path) -> str:
    """Hash of a committed stage: its result numbers and every file's bytes (not stage.json's timing)."""
    h = hashlib.sha256()
    for f in sorted(p for p in path.rglob("*") if p.is_file()):
        rel = f.relative_to(path).as_posix()
        h.update(rel.encode())
        if rel == "stage.json":
            doc = json.loads(f.read_text())
            h.update(json.dumps(doc.get("result"), sort_keys=True).encode())
        else:
            h.update(f.read_bytes())
    return h.hexdigest()


def read_manifest(out) -> dict | None:
    p = Path(out) / "manifest.json"
    if not p.exists():
        return None
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise PipelineError(f"{p} is not valid JSON ({exc}); delete the run folder or use a new --out") from None


def _check_folder(out: Path, vehicle: str) -> dict:
    from rotorlab import __version__

    man = read_manifest(out)
    if man is None:
        if out.exists() and any(out.iterdir()):
            raise PipelineError(f"{out} exists and is not a rotorlab pipeline run folder (no manifest.json); "
                                "choose an empty or new --out folder")
        return {"format": "rotorlab-pipeline", "format_version": FORMAT_VERSION, "rotorlab_version": __version__,
                "vehicle": vehicle, "stages": {}}
    fv = man.get("format_version")
    if man.get("format") != "rotorlab-pipeline" or fv != FORMAT_VERSION:
        raise PipelineError(
            f"{out} was written by pipeline format {fv} (rotorlab {man.get('rotorlab_version')}); this rotorlab "
            f"{__version__} writes format {FORMAT_VERSION} and will not mix the two: use a new --out folder or "
            "delete the old one")
    if man.get("vehicle") != vehicle:
        raise PipelineError(f"{out} holds a pipeline run of vehicle '{man.get('vehicle')}', not '{vehicle}'; "
                            "use another --out folder")
    man["rotorlab_version"] = __version__
    return man


def stage_dir(out, stage: str) -> Path:
    """Committed folder of a stage: ``OUT/report`` for the report, ``OUT/stages/<stage>`` otherwise."""
    return Path(out) / ("report" if stage == "report" else f"stages/{stage}")


def stage_result(out, stage: str) -> dict:
    """The result dict a committed stage stored (raises PipelineError when the stage has not run)."""
    p = stage_dir(out, stage) / "stage.json"
    if not p.exists():
        raise PipelineError(f"stage '{stage}' has not completed in {out}")
    return json.loads(p.read_text())["result"]


class _Ctx:
    """What a stage function gets: options, settings, its work folder and the committed upstream folders."""

    def __init__(self, opts: PipelineOptions, settings: dict, out: Path, work: Path, executor):
        self.opts, self.s, self.out, self.work, self.executor = opts, settings, out, work, executor
        self.vehicle = opts.vehicle
        self.seed = int(opts.seed)

    def upstream(self, stage: str) -> Path:
        return stage_dir(self.out, stage)

    def result(self, stage: str) -> dict:
        return stage_result(self.out, stage)

    def progress(self, it, desc: str, total=None):
        from tqdm import tqdm

        return tqdm(it, desc=f"  {desc}", total=total, disable=not self.opts.progress, leave=False)


# ----------------------------------------------------------------------------------------------------------
# stage 1: experiments


def _experiment_plan(vehicle: str, s: dict, seed: int) -> list[dict]:
    from rotorlab.executor import task_seeds
    from rotorlab.vehicles import load_vehicle

    v = load_vehicle(vehicle)
    seeds = task_seeds(seed, 4)
    closed = v.kind != "variable-pitch"  # TUHH: closed-loop set-point PRBS (its published route)
    plan = [
        {"name": "id", "kind": "prbs-closed" if closed else "prbs", "scene": "pitch-rig", "seed": seeds[0],
         "segments": s["segments"]},
        {"name": "cv", "kind": "prbs-closed" if closed else "prbs", "scene": "pitch-rig", "seed": seeds[1],
         "segments": [[[0.1, 0.2], 9.0, s["cv_s"]]]},
        {"name": "val", "kind": "steps", "scene": "pitch-rig", "seed": seeds[2], "duration_s": s["val_s"]},
    ]
    if not closed:
        plan.append({"name": "flight", "kind": "prbs-flight", "scene": "free-flight", "seed": seeds[3],
                     "segments": [[[0.1, 0.2], 7.0, s["flight_s"]]]})
    for p in plan:
        p["vehicle"] = vehicle
    return plan


def _step_reference(duration_s: float):
    """Set-point changes of the closed-loop validation run: +-10 deg steps every quarter of the run."""
    q = duration_s / 4

    def ref(t):
        return {"theta_ref": 0.0 if t < 0.5 else (10.0 if int((t - 0.5) // q) % 2 == 0 else -10.0)}

    return ref


def run_experiment(task: dict) -> dict:
    """Fly one identification experiment on the twin (picklable top-level task for the executors).

    The excitation is designed here from the published campaign (:func:`rotorlab.excitation.campaign`) and
    flown with the runner's flight software: quasi-open loop with the supervisor on the rig ('prbs'),
    PRBS added to the rate set-point with the cascade closed ('prbs-closed'), PRBS added to the pitch command
    with position hold in free flight ('prbs-flight'), or set-point steps ('steps').
    Returns the log columns as arrays and the reason the run stopped early (None when it did not).
    """
    from rotorlab.excitation import campaign
    from rotorlab.sim.log import RunLog
    from rotorlab.sim.runner import BASE_COLUMNS, FLIGHT_COLUMNS, make_flight_software, resolve_gains
    from rotorlab.sim.scenarios import Setup
    from rotorlab.sim.simulator import Simulator
    from rotorlab.vehicles import load_vehicle

    v = load_vehicle(task["vehicle"])
    gs = resolve_gains(v, task.get("gains"))
    kind = task["kind"]
    if kind == "steps":
        n = int(round(task["duration_s"] / DT_S))
        setup = Setup(mode="cascade", reference=_step_reference(task["duration_s"]))
    else:
        u, _ = campaign([(tuple(h), a, d) for h, a, d in task["segments"]], dt=DT_S, seed=task["seed"])
        n = len(u)
        if kind == "prbs":
            setup = Setup(mode="open-loop", excitation={"u_lon": u})
        elif kind == "prbs-closed":
            setup = Setup(mode="cascade", excitation={"theta_ref": u})
        elif kind == "prbs-flight":
            setup = Setup(mode="position", excitation={"u_lon": u})
        else:
            raise PipelineError(f"unknown experiment kind '{kind}'")
    sim = Simulator(task["scene"], v, seed=task["seed"], sensor_noise=True, disturbances=setup.disturbances)
    fs = make_flight_software(v, gs, setup)
    cols = dict(BASE_COLUMNS, **(FLIGHT_COLUMNS if task["scene"] == "free-flight" else {}))
    log = RunLog(cols, n)
    stopped = None
    for _ in range(n):
        t = sim.time
        out = fs.step(t, sim.measure())
        sim.set_rotor_commands(out["rotor_pct"])
        log.append(t, out)
        sim.tick()
        stopped = sim.check()
        if stopped:
            break
    return {"name": task["name"], "columns": {k: log[k].copy() for k in log.columns}, "units": log.units,
            "stopped": stopped, "kind": kind, "scene": task["scene"], "seed": task["seed"]}


def _write_log(path: Path, columns: dict, units: dict, meta: dict) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    tbl = pa.table({k: np.asarray(v, float) for k, v in columns.items()})
    tbl = tbl.replace_schema_metadata({b"rotorlab.units": json.dumps(units).encode(),
                                       b"rotorlab": json.dumps(meta, default=str).encode()})
    with atomic.atomic_path(path) as tmp:
        pq.write_table(tbl, tmp)


def _read_log(path: Path) -> dict:
    import pyarrow.parquet as pq

    tbl = pq.read_table(path)
    return {k: tbl.column(k).to_numpy() for k in tbl.column_names}


def stage_experiments(ctx: _Ctx) -> dict:
    plan = _experiment_plan(ctx.vehicle, ctx.s, ctx.seed)
    runs = ctx.executor.map(run_experiment, plan, desc="experiments", progress=ctx.opts.progress)
    res = {"runs": {}}
    for r in runs:
        _write_log(ctx.work / f"{r['name']}.parquet", r["columns"], r["units"],
                   {"kind": r["kind"], "scene": r["scene"], "seed": r["seed"], "stopped": r["stopped"]})
        c = r["columns"]
        res["runs"][r["name"]] = {"kind": r["kind"], "scene": r["scene"], "seed": r["seed"], "stopped": r["stopped"],
                                  "samples": int(len(c["t"])), "duration_s": float(len(c["t"]) * DT_S),
                                  "u_std_pct": float(np.std(c["u_lon"])), "q_std_dps": float(np.std(c["q"])),
                                  "theta_max_abs_deg": float(np.max(np.abs(c["theta"])))}
    from rotorlab.excitation import spectrum_check

    u = _read_log(ctx.work / "id.parquet")["u_lon"]
    try:
        chk = spectrum_check(u, DT_S, band_rad_s=(4.0, 8.0))
        res["spectrum_band_fraction"] = float(getattr(chk, "fraction", getattr(chk, "band_fraction", math.nan)))
    except TypeError:
        res["spectrum_band_fraction"] = None
    return res


# ----------------------------------------------------------------------------------------------------------
# stage 2: identification


def truth_model(vehicle: str, dt: float = DT_S, slow_rad_s: float = 0.05):
    """The twin's true pitch-rate model on the rig, delay removed, resampled to ``dt``.

    The 1 ms linearisation is converted with the exact ZOH inverse, made minimal, then re-discretised (both
    conversions exact for a ZOH-held input). Pole/zero pairs both slower than ``slow_rad_s`` are dropped: the
    rig's rate output has a zero at the origin that nearly cancels a slow drift pole (about +0.01 1/s from
    the finite-difference linearisation); a one-minute record cannot see it and, being unstable, it would
    make every nu-gap 1 by the winding-number condition alone.
    """
    import control as ct
    from rotorlab.lti import c2d_zoh, d2c_zoh
    from rotorlab.sim.linearize import linearize

    Gc = ct.minreal(d2c_zoh(linearize("pitch-rig", vehicle, "pitch", "gyro_pitch", delay=False)), 1e-7,
                    verbose=False)
    poles, zeros = list(np.linalg.eigvals(np.asarray(Gc.A, float))), list(ct.zeros(Gc))
    dropped = 0
    for pz in [x for x in poles if abs(x) < slow_rad_s]:
        near = [z for z in zeros if abs(z) < slow_rad_s]
        if near:
            poles.remove(pz)
            zeros.remove(min(near, key=lambda z: abs(z - pz)))
            dropped += 1
    if dropped:
        G = ct.zpk(zeros, poles, 1.0)
        w_ref = 1.0  # match the gain at 1 rad/s, well inside the identification band
        k = ct.evalfr(Gc, 1j * w_ref) / ct.evalfr(G, 1j * w_ref)
        Gc = ct.ss(ct.tf(np.real(k) * G.num[0][0], G.den[0][0]))
    return c2d_zoh(Gc, dt)


def _vaf_of(model, u, y) -> float:
    from rotorlab.ident.metrics import simulate, vaf

    return float(vaf(y, simulate(model, u, x0="estimate", y=y))[0])


def _discrete_model(sys_c, delay_s: float, method: str, settings: dict):
    """IdentifiedModel of a continuous grey-box result: ZOH at 50 Hz with the delay as whole samples."""
    from rotorlab.ident.model import IdentifiedModel
    from rotorlab.lti import c2d_zoh

    return IdentifiedModel(sys=c2d_zoh(sys_c, DT_S), delay=int(round(delay_s / DT_S)), method=method,
                           settings=settings)


def stage_identify(ctx: _Ctx) -> dict:
    import control as ct
    from rotorlab.ident.crossval import select_order
    from rotorlab.ident.delay import estimate_delay
    from rotorlab.ident.lms import kung, lms_batch
    from rotorlab.ident.modelio import save_model
    from rotorlab.ident.nugap import nugap
    from rotorlab.ident.subspace import pbsid

    s = ctx.s
    logs = {n: _read_log(ctx.upstream("experiments") / f"{n}.parquet")
            for n in ("id", "cv", "val", "flight") if (ctx.upstream("experiments") / f"{n}.parquet").exists()}
    u_id, y_id = logs["id"]["u_lon"], logs["id"]["q"]
    u_cv, y_cv = logs["cv"]["u_lon"], logs["cv"]["q"]
    u_val, y_val = logs["val"]["u_lon"], logs["val"]["q"]
    d = int(estimate_delay(u_id, y_id, max_delay=8))
    truth = truth_model(ctx.vehicle)
    (ctx.work / "models").mkdir()
    models, res, skipped = {}, {"delay_samples": d, "delay_s": d * DT_S, "models": {}}, {}

    def record(name, m, table=None):
        models[name] = m
        entry = {"method": m.method, "order": int(m.order), "settings": _jsonable(m.settings),
                 "vaf_cv": _vaf_of(m, u_cv, y_cv), "vaf_val": _vaf_of(m, u_val, y_val),
                 "nugap_truth": float(nugap(m.sys, truth))}
        if table is not None:
            entry["grid"] = [{"settings": _jsonable(r["settings"]), "vaf_cv": float(r["vaf_cv_mean"])} for r in table]
        res["models"][name] = entry
        save_model(ctx.work / "models" / f"{name}.json", m, vaf=[entry["vaf_cv"]], input=["u_lon"], output=["q"],
                   units={"u_lon": "%", "q": "deg/s"})

    steps = ["pi-moesp", "pbsid", "lms-kung", "oe-greybox", "hinf-match"]
    for name in ctx.progress(steps, "identify"):
        try:
            if name == "pi-moesp":
                m, table = select_order(u_id, y_id, u_cv, y_cv, "moesp", s["moesp_orders"], s["moesp_horizons"],
                                        delay=d, dt=DT_S, instruments="u")
                record(name, m, table)
            elif name == "pbsid":
                m, table = select_order(u_id, y_id, u_cv, y_cv, "pbsid", s["pbsid_orders"],
                                        [tuple(h) for h in s["pbsid_horizons"]], delay=d, dt=DT_S)
                record(name, m, table)
            elif name == "lms-kung":
                h, _ = lms_batch(u_id, y_id, taps=s["lms_taps"], delay=d)
                best = None
                for n in s["lms_orders"]:
                    m = kung(np.concatenate([[0.0], h]), order=n, dt=DT_S, delay=d)
                    v = _vaf_of(m, u_cv, y_cv)
                    if best is None or v > best[0]:
                        best = (v, m)
                record(name, best[1])
            elif name == "oe-greybox":
                from rotorlab.ident.greybox import oe_fit
                from rotorlab.ident.structures import rate_tf_structure

                r = oe_fit(rate_tf_structure(delay_s=d * DT_S), u_id, y_id, DT_S, estimate_x0=True,
                           restarts=s["oe_restarts"], rng=ctx.seed)
                record(name, _discrete_model(r.sys, d * DT_S, "oe-greybox", _jsonable(r.params)))
            elif name == "hinf-match":
                from rotorlab.ident.hinf_match import hinf_match
                from rotorlab.ident.structures import rate_tf_structure

                if "pbsid" not in models:
                    raise RuntimeError("needs the PBSID model")
                r = hinf_match(models["pbsid"], rate_tf_structure(delay_s=d * DT_S), restarts=s["hinf_restarts"],
                               rng=ctx.seed)
                record(name, _discrete_model(r.sys, d * DT_S, "hinf-match", _jsonable(r.params)))
        except (ImportError, AttributeError) as exc:
            skipped[name] = f"skipped: library piece missing ({exc})"
        except Exception as exc:  # one method failing must not hide the others; the report says why
            skipped[name] = f"skipped: {type(exc).__name__}: {exc}"
    res["skipped"] = skipped
    save_model(ctx.work / "models" / "truth.json", truth, input=["u_lon"], output=["q"])
    # in-flight model and the test-bed vs flight nu-gap (published 0.0741 between the PBSID models)
    if "flight" in logs and "pbsid" in models:
        uf, yf = logs["flight"]["u_lon"], logs["flight"]["q"]
        st = models["pbsid"].settings
        mf = pbsid(uf, yf, st["order"], st["past"], st.get("future"), dt=DT_S, delay=d)
        save_model(ctx.work / "models" / "pbsid-flight.json", mf, input=["u_lon"], output=["q"])
        res["flight"] = {"order": int(mf.order), "nugap_testbed_flight": float(nugap(models["pbsid"].sys, mf.sys)),
                         "nugap_truth": float(nugap(mf.sys, truth)), "published_nugap": 0.0741}
    if not models:
        raise PipelineError("no identification method succeeded: " + "; ".join(f"{k}: {v}" for k, v in skipped.items()))
    res["nominal"] = "pbsid" if "pbsid" in models else next(iter(models))
    res["truth_order"] = int(truth.nstates)
    return res


def _jsonable(obj):
    return json.loads(json.dumps(obj, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


def load_identified(path):
    """IdentifiedModel back from a model JSON (delay-free sys and delay in samples at 50 Hz)."""
    from rotorlab.ident.model import IdentifiedModel
    from rotorlab.ident.modelio import load_model

    sys, delay_s, meta = load_model(path)
    return IdentifiedModel(sys=sys, delay=int(round(delay_s / DT_S)), method=str(meta.get("method", "")),
                           settings=meta.get("settings", {}))


# ----------------------------------------------------------------------------------------------------------
# stage 3: bootstrap


def bode_grid(n: int = 200) -> np.ndarray:
    return np.logspace(-1, math.log10(0.9 * math.pi / DT_S), n)


def stage_bootstrap(ctx: _Ctx) -> dict:
    from rotorlab.ident.bootstrap import bootstrap
    from rotorlab.ident.modelio import save_model
    from rotorlab.ident.subspace import pbsid
    from rotorlab.tune.robust import additive_spread, fit_wdelta

    ident = ctx.result("identify")
    if "pbsid" not in ident["models"]:
        raise PipelineError("the bootstrap needs the PBSID model: " + ident["skipped"].get("pbsid", "missing"))
    st = ident["models"]["pbsid"]["settings"]
    log = _read_log(ctx.upstream("experiments") / "id.parquet")
    identify = functools.partial(pbsid, order=st["order"], past=st["past"], future=st.get("future"), dt=DT_S,
                                 delay=st["delay"])
    br = bootstrap(log["u_lon"], log["q"], identify, n_boot=ctx.s["n_boot"], seed=ctx.seed,
                   n_jobs=max(1, getattr(ctx.executor, "workers", 1)), progress=ctx.opts.progress)
    w = bode_grid(120)
    W = fit_wdelta(br.nominal.sys, [m.sys for m in br.models], w, order=3)
    save_model(ctx.work / "w_delta.json", W, input=["delta"], output=["q"])
    band = br.band(w, 0.95)
    stack = {k: np.stack([np.asarray(getattr(m.sys, k), float) for m in br.models]) for k in "ABCD"}
    np.savez(ctx.work / "replicas.npz", w_rad_s=w, mag_lo=band["mag_lo"][:, 0, 0], mag_hi=band["mag_hi"][:, 0, 0],
             phase_lo=band["phase_lo"][:, 0, 0], phase_hi=band["phase_hi"][:, 0, 0],
             spread=additive_spread(br.nominal.sys, [m.sys for m in br.models], w),
             poles_c=br.poles_continuous(), **stack)
    from rotorlab.lti import freqresp

    Wmag = np.abs(freqresp(W, w)[:, 0, 0])
    return {"n_boot": ctx.s["n_boot"], "order": int(st["order"]), "w_delta_order": int(W.nstates),
            "w_delta_peak": float(Wmag.max()), "w_delta_dc": float(Wmag[0]),
            "poles_c_median": [[float(z.real), float(z.imag)] for z in np.median(br.poles_continuous().real, 0)
                               + 1j * np.median(np.abs(br.poles_continuous().imag), 0)]}


# ----------------------------------------------------------------------------------------------------------
# stage 4: tuning, h_lim, Monte Carlo


def _pid(loop, dt: float):
    from rotorlab.lti import pid2_ss

    return pid2_ss(loop.kp, loop.ki, loop.kd, loop.tf, loop.b, loop.c, dt)


def cascade_loop(G, axis_gains, delay: int, dt: float = DT_S, w_input: bool = True):
    """Closed published cascade around the delay-free discrete rate plant ``G`` (u % -> q deg/s).

    Outer 2-DoF PD on the angle -> rate set-point; inner 2-DoF PID on the rate -> u; ``delay`` samples on
    the plant input; the angle is the forward-Euler integral of the measured rate (``dt/(z-1)``, the
    flight software's 50 Hz angle update). Inputs ``(theta_ref, d_u[, w])``: set-point, disturbance added to
    the plant input (gust) and, with ``w_input``, the additive-uncertainty signal added to the plant output
    ``q`` (so also to the angle). Outputs ``(theta, u)``. All closed-loop states are kept, so
    ``h_lim`` can check internal stability. Linear: saturations are ignored, as in the published design.

    Written here with ``control.interconnect`` because the tuning library's cascade builder
    (``rotorlab.tune.cascade``) was not available when the pipeline was written.
    """
    import control as ct
    from rotorlab.lti import as_ss, delay_ss

    P = as_ss(G)
    if delay:
        P = ct.series(delay_ss(int(delay), dt), P)
    P = ct.ss(P.A, P.B, P.C, P.D, dt, inputs=["up"], outputs=["qp"], name="plant")
    integ = ct.ss([[1.0]], [[dt]], [[1.0]], [[0.0]], dt, inputs=["qm"], outputs=["theta"], name="integ")
    Co = as_ss(_pid(axis_gains.outer, dt))
    Co = ct.ss(Co.A, Co.B, Co.C, Co.D, dt, inputs=["theta_ref", "theta"], outputs=["q_ref"], name="outer")
    Ci = as_ss(_pid(axis_gains.inner, dt))
    Ci = ct.ss(Ci.A, Ci.B, Ci.C, Ci.D, dt, inputs=["q_ref", "qm"], outputs=["u"], name="inner")
    su = ct.summing_junction(["u", "d_u"], "up", dt=dt, name="su")
    sq = ct.summing_junction(["qp", "w"], "qm", dt=dt, name="sq")
    inputs = ["theta_ref", "d_u"] + (["w"] if w_input else [])
    return ct.interconnect([P, integ, Co, Ci, su, sq], inplist=inputs, outlist=["theta", "u"], dt=dt,
                           check_unused=False)


def _mc_builder(G, axis_gains=None, delay=0):
    return cascade_loop(G, axis_gains, delay, w_input=False)


def _gain_sets(vehicle: str, tuned_path: Path | None) -> dict:
    from rotorlab.gains import load_gains
    from rotorlab.vehicles import gains_path, list_gains

    sets = {name: load_gains(gains_path(vehicle, name)) for name in list_gains(vehicle)}
    ordered = {k: sets[k] for k in ["standard"] + sorted(k for k in sets if k != "standard") if k in sets}
    if tuned_path is not None and tuned_path.exists():
        ordered["tuned"] = load_gains(tuned_path)
    return ordered


def _try_tune(ctx: _Ctx, G_nom, delay: int):
    """Tune with ``rotorlab.tune.tune_cascade`` to the vehicle's shipped spec from its standard gains."""
    import rotorlab.tune as tune
    from rotorlab.gains import load_gains, save_gains
    from rotorlab.vehicles import gains_path

    fn = getattr(tune, "tune_cascade", None)
    if fn is None:
        try:
            from rotorlab.tune.cascade import tune_cascade as fn  # noqa: F811
        except ImportError as exc:
            return None, f"skipped: rotorlab.tune.tune_cascade is not available ({exc})"
    try:
        from rotorlab.tune.spec import load_spec
    except ImportError as exc:
        return None, f"skipped: rotorlab.tune.spec.load_spec is not available ({exc})"
    try:
        spec = load_spec(ctx.vehicle)
    except Exception as exc:
        return None, f"skipped: no tuning spec for {ctx.vehicle} ({exc})"
    plant = G_nom if not delay else _with_delay(G_nom, delay)
    out = fn(spec, [plant], load_gains(gains_path(ctx.vehicle, "standard")), seed=ctx.seed)
    gains, report = (out if isinstance(out, tuple) else (out.gains, getattr(out, "report", None)))
    save_gains(dataclasses.replace(gains, name="tuned"), ctx.work / "tuned.toml")
    return report, None


def _with_delay(G, delay):
    import control as ct
    from rotorlab.lti import delay_ss

    return ct.series(delay_ss(int(delay), DT_S), G)


def _evaluate(ctx, gains_by_set: dict, G_nom, delay) -> dict:
    """Goal report of every gain set with ``rotorlab.tune.evaluate`` when it exists."""
    import rotorlab.tune as tune

    ev = getattr(tune, "evaluate", None)
    if ev is None:
        return {"skipped": "skipped: rotorlab.tune.evaluate is not available"}
    from rotorlab.tune.spec import load_spec

    spec = load_spec(ctx.vehicle)
    out = {}
    for name, gs in gains_by_set.items():
        rep = ev(spec, gs, [_with_delay(G_nom, delay)])
        out[name] = _jsonable(rep if isinstance(rep, (dict, list)) else getattr(rep, "as_dict", lambda: str(rep))())
    return out


def stage_tune(ctx: _Ctx) -> dict:
    from rotorlab.ident.modelio import load_model
    from rotorlab.tune.montecarlo import montecarlo
    from rotorlab.tune.robust import h_lim

    ident = ctx.result("identify")
    nominal = load_identified(ctx.upstream("identify") / "models" / f"{ident['nominal']}.json")
    G, d = nominal.sys, nominal.delay
    W, _, _ = load_model(ctx.upstream("bootstrap") / "w_delta.json")
    res = {"nominal_model": ident["nominal"], "delay_samples": d}
    try:
        report, skip = _try_tune(ctx, G, d)
    except Exception as exc:  # the spec may be infeasible or the tuner may fail: validate the others anyway
        report, skip = None, f"skipped: tuning failed: {type(exc).__name__}: {exc}"
    res["tuning"] = skip or "done"
    if report is not None:
        res["tuning_report"] = _jsonable(report if isinstance(report, (dict, list)) else str(report))
    sets = _gain_sets(ctx.vehicle, ctx.work / "tuned.toml")
    res["gains"] = {k: {ax: {"outer": g.outer.as_dict(), "inner": g.inner.as_dict()} for ax, g in gs.axes.items()
                        if ax == "pitch"} for k, gs in sets.items()}
    try:
        res["goals"] = _evaluate(ctx, sets, G, d)
    except Exception as exc:
        res["goals"] = {"skipped": f"skipped: {type(exc).__name__}: {exc}"}
    res["h_lim"], res["montecarlo"], res["nominal_closed_loop_stable"] = {}, {}, {}
    mc_arrays = {}
    for k, (name, gs) in enumerate(ctx.progress(sets.items(), "h_lim + montecarlo", total=len(sets))):
        cl = cascade_loop(G, gs["pitch"], d)
        V = cl[1, 2]  # w (additive uncertainty output) -> u
        try:
            res["h_lim"][name] = float(h_lim(W, V))
            res["nominal_closed_loop_stable"][name] = True
        except Exception as exc:
            res["h_lim"][name] = None
            res["nominal_closed_loop_stable"][name] = False
            res["montecarlo"][name] = {"skipped": f"skipped: {exc}"}
            continue
        mc = montecarlo(G, W, functools.partial(_mc_builder, axis_gains=gs["pitch"], delay=d), res["h_lim"][name],
                        n=ctx.s["n_mc"], seed=np.random.SeedSequence([ctx.seed, k]),
                        n_jobs=max(1, getattr(ctx.executor, "workers", 1)), t_final_s=3.0, progress=False)
        summ = mc.summary()
        res["montecarlo"][name] = {"n": ctx.s["n_mc"], "h": res["h_lim"][name],
                                   "fraction_unstable": float(summ["fraction_unstable"]),
                                   **{k2: [float(x) for x in summ[k2]] for k2 in ("rise_s", "settling_s",
                                                                                  "overshoot_pct", "load_peak")}}
        q = (0.0, 0.05, 0.5, 0.95, 1.0)
        try:
            mc_arrays[f"{name}__setpoint"] = mc.band("setpoint", q)
            mc_arrays[f"{name}__load"] = mc.band("load", q)
        except Exception:
            pass
        mc_arrays["t"] = mc.t
    np.savez(ctx.work / "montecarlo.npz", **mc_arrays)
    res["transfer"], res["h_lim_flight"] = _transfer(ctx, sets, G, d, W)
    return res


def _step_iae(G, axis_gains, delay, t_final_s: float = 3.0) -> float:
    """IAE (deg s per deg) of the nominal linear cascade's unit set-point step (inf when unstable)."""
    from rotorlab import lti

    cl = cascade_loop(G, axis_gains, delay, w_input=False)
    if not lti.is_stable(cl):
        return math.inf
    import control as ct

    t = np.arange(0.0, t_final_s + 1e-9, DT_S)
    _, y = ct.step_response(cl[0, 0], T=t)
    return float(np.sum(np.abs(1.0 - np.ravel(y))) * DT_S)


def _transfer(ctx, sets, G, d, W):
    """Test-bed tuning on the flight model: tracking IAE on each model and h_lim with the flight model."""
    from rotorlab.tune.robust import h_lim

    p = ctx.upstream("identify") / "models" / "pbsid-flight.json"
    if not p.exists():
        return {}, {}
    Gf = load_identified(p).sys
    transfer, hl = {}, {}
    for name, gs in sets.items():
        a, b = _step_iae(G, gs["pitch"], d), _step_iae(Gf, gs["pitch"], d)
        transfer[name] = {"iae_testbed": a, "iae_flight": b,
                          "loss_pct": 100.0 * (b - a) / a if math.isfinite(a) and math.isfinite(b) else None}
        try:
            hl[name] = float(h_lim(W, cascade_loop(Gf, gs["pitch"], d)[1, 2]))
        except Exception:
            hl[name] = None
    return transfer, hl


# ----------------------------------------------------------------------------------------------------------
# stage 5: validation on the twin


def run_validation(task: dict) -> dict:
    """One validation scenario with one gain set (picklable task). Returns metrics and the log arrays."""
    from rotorlab.gains import parse_gains
    from rotorlab.sim import scenarios
    from rotorlab.sim.runner import run_scenario

    if task["scenario"] not in scenarios.SCENARIOS:
        return {"skipped": f"skipped: scenario '{task['scenario']}' is not registered in rotorlab.sim.scenarios"}
    gs = parse_gains(task["gains"], name=task["set"])
    opts = dict(task.get("options") or {})
    if task["scenario"] == "hover" and task.get("standard") is not None:
        # the published flight test: standard gains, switched in flight to the set under test (none for standard)
        if task["set"] == "standard":
            opts["switch_s"] = None
        else:
            opts["switch_to"] = gs
            gs = parse_gains(task["standard"], name="standard")
    try:
        r = run_scenario(task["scenario"], task["vehicle"], gains=gs, seed=task["seed"],
                         duration_s=task.get("duration_s"), options=opts)
    except Exception as exc:  # a scenario refusing this vehicle is reported, not fatal
        return {"skipped": f"skipped: {type(exc).__name__}: {exc}"}
    return {"metrics": _jsonable(r.metrics), "stopped": r.stopped, "scene": r.info.get("scene"),
            "columns": {k: r.log[k].copy() for k in r.log.columns}, "units": r.log.units}


def stage_validate(ctx: _Ctx) -> dict:
    from rotorlab.executor import task_seeds

    sets = _gain_sets(ctx.vehicle, ctx.upstream("tune") / "tuned.toml")
    seeds = task_seeds(ctx.seed + 1, len(VALIDATION_SCENARIOS))
    tasks = []
    for sc, seed in zip(VALIDATION_SCENARIOS, seeds):
        for name, gs in sets.items():
            # common random numbers: every gain set sees the same noise, gusts and turbulence
            tasks.append({"scenario": sc, "set": name, "vehicle": ctx.vehicle, "seed": seed,
                          "gains": _gains_table(gs), "duration_s": ctx.s["validation_s"].get(sc), "options": {},
                          "standard": _gains_table(sets["standard"]) if "standard" in sets else None})
    results = ctx.executor.map(run_validation, tasks, desc="validation", progress=ctx.opts.progress)
    (ctx.work / "logs").mkdir()
    res = {"validation": {}, "skipped": {}}
    for t, r in zip(tasks, results):
        if "skipped" in r:
            res["skipped"].setdefault(t["scenario"], r["skipped"])
            continue
        res["validation"].setdefault(t["scenario"], {})[t["set"]] = {**r["metrics"], "stopped": r["stopped"]}
        _write_log(ctx.work / "logs" / f"{t['scenario']}__{t['set']}.parquet", r["columns"], r["units"],
                   {"scenario": t["scenario"], "gains": t["set"], "seed": t["seed"], "scene": r["scene"]})
    return res


def _gains_table(gs) -> dict:
    return {ax: {"outer": g.outer.as_dict(), "inner": g.inner.as_dict()} for ax, g in gs.axes.items()}


# ----------------------------------------------------------------------------------------------------------
# stage 6: report


def stage_report(ctx: _Ctx) -> dict:
    from rotorlab import report

    return report.write_report(ctx)


STAGE_FUNCS = {"experiments": stage_experiments, "identify": stage_identify, "bootstrap": stage_bootstrap,
               "tune": stage_tune, "validate": stage_validate, "report": stage_report}
UPSTREAM = {"experiments": (), "identify": ("experiments",), "bootstrap": ("experiments", "identify"),
            "tune": ("identify", "bootstrap"), "validate": ("tune",),
            "report": ("experiments", "identify", "bootstrap", "tune", "validate")}
# settings each stage depends on (a change elsewhere does not invalidate it)
STAGE_KEYS = {"experiments": ("segments", "cv_s", "val_s", "flight_s"),
              "identify": ("moesp_orders", "moesp_horizons", "pbsid_orders", "pbsid_horizons", "lms_orders",
                           "lms_taps", "hinf_restarts", "oe_restarts"),
              "bootstrap": ("n_boot",), "tune": ("n_mc",), "validate": ("validation_s",), "report": ("record_runs",)}


def _stage_hash(stage, opts, s, fingerprint, upstream_hashes, version) -> str:
    return _sha({"format_version": FORMAT_VERSION, "rotorlab": version, "stage": stage, "vehicle": opts.vehicle,
                 "vehicle_files": fingerprint, "seed": opts.seed, "settings": {k: s[k] for k in STAGE_KEYS[stage]},
                 "upstream": upstream_hashes})


def run_pipeline(opts: PipelineOptions, *, stages=STAGES, log=print) -> dict:
    """Run (or resume) the pipeline into ``opts.out``; returns the manifest.

    Each stage prints one line: its number, name, ``done``/``cached`` and its time.
    """
    from rotorlab import __version__
    from rotorlab.executor import get_executor
    from rotorlab.vehicles import load_vehicle

    load_vehicle(opts.vehicle)  # unknown vehicle -> UnknownNameError listing the valid ones, before any work
    s = settings_for(opts.level, opts.n_boot, opts.n_mc)
    out = Path(opts.out)
    man = _check_folder(out, opts.vehicle)
    man.update(seed=opts.seed, level=opts.level, settings=s)
    out.mkdir(parents=True, exist_ok=True)
    (out / "stages").mkdir(exist_ok=True)
    atomic.write_json(out / "manifest.json", man)
    fp = _vehicle_fingerprint(opts.vehicle)
    t_all = time.perf_counter()
    out_hashes: dict = {}
    executor = None
    try:
        for i, stage in enumerate(STAGES, 1):
            if stage not in stages:
                continue
            final = stage_dir(out, stage)
            ups = {u: out_hashes.get(u) or (_dir_hash(stage_dir(out, u)) if stage_dir(out, u).exists() else None)
                   for u in UPSTREAM[stage]}
            h = _stage_hash(stage, opts, s, fp, ups, __version__)
            done = final / "stage.json"
            if done.exists() and json.loads(done.read_text()).get("hash") == h:
                out_hashes[stage] = _dir_hash(final)
                log(f"[{i}/{len(STAGES)}] {stage:<12} cached ({final})")
                continue
            if executor is None:
                executor = get_executor(opts.executor, opts.workers)
            work = out / "stages" / f".{stage}.partial"
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            log(f"[{i}/{len(STAGES)}] {stage:<12} running ...")
            t0 = time.perf_counter()
            ctx = _Ctx(opts, s, out, work, executor)
            result = STAGE_FUNCS[stage](ctx)
            dt_s = time.perf_counter() - t0
            atomic.write_json(work / "stage.json", {"stage": stage, "hash": h, "seconds": dt_s, "upstream": ups,
                                                    "result": result})
            shutil.rmtree(final, ignore_errors=True)
            work.rename(final)  # the commit point: a stage folder either is complete or does not exist
            out_hashes[stage] = _dir_hash(final)
            man["stages"][stage] = {"hash": h, "output_hash": out_hashes[stage], "seconds": round(dt_s, 3)}
            atomic.write_json(out / "manifest.json", man)
            log(f"[{i}/{len(STAGES)}] {stage:<12} done in {dt_s:.1f} s")
    finally:
        if executor is not None:
            executor.close()
    total = time.perf_counter() - t_all
    log(f"pipeline finished in {total:.1f} s; report: {stage_dir(out, 'report') / 'report.md'}")
    man["total_seconds"] = round(total, 3)
    atomic.write_json(out / "manifest.json", man)
    return man
