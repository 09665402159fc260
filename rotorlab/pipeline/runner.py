"""Running a pipeline into a run folder: stage hashes, the manifest, and the atomic commit of each stage.

Caching and resume: a stage is skipped when ``stages/<stage>/stage.json`` holds the same input hash, computed
from the vehicle TOML and gain-file bytes, the effective settings (``--quick``/``--tiny`` grids and sizes),
the seed, the upstream stages' output hashes, the rotorlab version and
:data:`rotorlab.pipeline.settings.FORMAT_VERSION`. A stage builds its files in ``stages/.<stage>.partial``
and is renamed into place only when complete, so Ctrl-C, a crash or a full disk loses nothing already done
and never leaves a half stage that looks finished. The executor is not part of the hash: every executor gives
the same numbers (seeds per task).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
from pathlib import Path

from rotorlab import __version__, atomic
from rotorlab.executor import get_executor
from rotorlab.pipeline.runfolder import RunFolder, StageContext, read_manifest, stage_dir
from rotorlab.pipeline.settings import FORMAT_VERSION, PipelineError, PipelineOptions, settings_for
from rotorlab.pipeline.stages import REGISTRY, STAGES
from rotorlab.vehicles import load_vehicle, vehicle_path

__all__ = ["run_pipeline", "stage_hash", "dir_hash"]


def _sha(obj) -> str:
    data = obj if isinstance(obj, bytes) else json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha256(data).hexdigest()


def _vehicle_fingerprint(vehicle: str) -> dict:
    p = vehicle_path(vehicle)
    files = [p] + sorted((p.parent / "gains").glob("*.toml"))
    return {f.name if f == p else f"gains/{f.name}": _sha(f.read_bytes()) for f in files}


def dir_hash(path: Path) -> str:
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


def stage_hash(stage: str, opts: PipelineOptions, s: dict, fingerprint: dict, upstream_hashes: dict,
               version: str = __version__) -> str:
    """Input hash of ``stage``: everything its numbers depend on (see the module docstring)."""
    return _sha({"format_version": FORMAT_VERSION, "rotorlab": version, "stage": stage, "vehicle": opts.vehicle,
                 "vehicle_files": fingerprint, "seed": opts.seed,
                 "settings": {k: s[k] for k in REGISTRY[stage].settings}, "upstream": upstream_hashes})


def _open_run_folder(out: Path, vehicle: str) -> dict:
    """The manifest of ``out`` (a fresh one for a new or empty folder), refusing a folder that is not a
    compatible run of ``vehicle``. The one place a run opens its folder: the run-folder lock belongs here."""
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


def _is_cached(final: Path, h: str) -> bool:
    """Whether the committed stage folder ``final`` was built from inputs hashing to ``h``. The one place a
    cached stage is trusted: verifying its files against the manifest's output hash belongs here."""
    done = final / "stage.json"
    return done.exists() and json.loads(done.read_text()).get("hash") == h


def run_pipeline(opts: PipelineOptions, *, stages=STAGES, log=print) -> dict:
    """Run (or resume) the pipeline into ``opts.out``; returns the manifest.

    Each stage prints one line: its number, name, ``done``/``cached`` and its time.
    """
    load_vehicle(opts.vehicle)  # unknown vehicle -> UnknownNameError listing the valid ones, before any work
    s = settings_for(opts.level, opts.n_boot, opts.n_mc)
    out = Path(opts.out)
    man = _open_run_folder(out, opts.vehicle)
    man.update(seed=opts.seed, level=opts.level, settings=s)
    out.mkdir(parents=True, exist_ok=True)
    (out / "stages").mkdir(exist_ok=True)
    atomic.write_json(out / "manifest.json", man)
    run = RunFolder(out, opts.vehicle)
    fp = _vehicle_fingerprint(opts.vehicle)
    t_all = time.perf_counter()
    out_hashes: dict = {}
    executor = None
    try:
        for i, stage in enumerate(STAGES, 1):
            if stage not in stages:
                continue
            final = stage_dir(out, stage)
            ups = {u: out_hashes.get(u) or (dir_hash(stage_dir(out, u)) if stage_dir(out, u).exists() else None)
                   for u in REGISTRY[stage].upstream}
            h = stage_hash(stage, opts, s, fp, ups)
            if _is_cached(final, h):
                out_hashes[stage] = dir_hash(final)
                log(f"[{i}/{len(STAGES)}] {stage:<12} cached ({final})")
                continue
            if executor is None:
                executor = get_executor(opts.executor, opts.workers)
            work = out / "stages" / f".{stage}.partial"
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            log(f"[{i}/{len(STAGES)}] {stage:<12} running ...")
            t0 = time.perf_counter()
            result = REGISTRY[stage].run(StageContext(run, work, opts, s, executor))
            dt_s = time.perf_counter() - t0
            atomic.write_json(work / "stage.json", {"stage": stage, "hash": h, "seconds": dt_s, "upstream": ups,
                                                    "result": result})
            shutil.rmtree(final, ignore_errors=True)
            work.rename(final)  # the commit point: a stage folder either is complete or does not exist
            out_hashes[stage] = dir_hash(final)
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
