"""Running a pipeline into a run folder: stage hashes, the manifest, and the atomic commit of each stage.

Caching and resume: a stage is skipped when ``stages/<stage>/stage.json`` holds the same input hash, computed
from the vehicle TOML and gain-file bytes, the effective settings (``--quick``/``--tiny`` grids and sizes),
the seed, the upstream stages' output hashes, the rotorlab version and
:data:`rotorlab.pipeline.settings.FORMAT_VERSION`; for the log pipeline (:func:`run_log_pipeline`) the log's bytes,
the starting vehicle's TOML and the autopilot asked take the vehicle files' place. A stage builds its files in
``stages/.<stage>.partial`` and is renamed into place only when complete, so Ctrl-C, a crash or a full disk loses
nothing already done and never leaves a half stage that looks finished. The executor is not part of the hash: every executor gives
the same numbers (seeds per task).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import socket
import time
from pathlib import Path

from rotorlab import __version__, atomic
from rotorlab.config import read_json
from rotorlab.errors import RotorlabError
from rotorlab.executor import get_executor
from rotorlab.pipeline.runfolder import RunFolder, StageContext, read_manifest, stage_dir
from rotorlab.pipeline.settings import (
    FORMAT_VERSION,
    LogPipelineOptions,
    PipelineError,
    PipelineOptions,
    log_settings_for,
    settings_for,
)
from rotorlab.pipeline.stages import LOG_REGISTRY, LOG_STAGES, REGISTRY, STAGES
from rotorlab.tune.spec import builtin_specs
from rotorlab.vehicles import gains_dir, gains_path, load_vehicle, vehicle_path

__all__ = ["run_pipeline", "run_log_pipeline", "log_fingerprint", "stage_hash", "dir_hash", "run_folder_lock",
           "LOCK_NAME"]

LOCK_NAME = ".rotorlab.lock"


def _sha(obj) -> str:
    data = obj if isinstance(obj, bytes) else json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha256(data).hexdigest()


def _vehicle_fingerprint(vehicle: str) -> dict:
    """Content hashes of the vehicle's configuration: its TOML, gain sets and shipped tuning spec (the tune
    stage's requirements), so that editing any of them re-runs what depends on it."""
    p = vehicle_path(vehicle)
    files = {p.name: p, **{f"gains/{f.name}": f for f in sorted(gains_dir(vehicle).glob("*.toml"))}}
    spec = builtin_specs().get(vehicle)
    if spec is not None:
        files["spec"] = Path(spec)
    return {k: _sha(f.read_bytes()) for k, f in files.items()}


def dir_hash(path: Path) -> str:
    """Hash of a committed stage: its result numbers and every file's bytes (not stage.json's timing)."""
    h = hashlib.sha256()
    for f in sorted(p for p in path.rglob("*") if p.is_file()):
        rel = f.relative_to(path).as_posix()
        h.update(rel.encode())
        if rel == "stage.json":
            try:
                doc = json.loads(f.read_text(encoding="utf-8"))
                h.update(json.dumps(doc.get("result"), sort_keys=True).encode())
            except (ValueError, UnicodeDecodeError, AttributeError, RecursionError):  # damaged: hashed as its bytes
                h.update(f.read_bytes())
        else:
            h.update(f.read_bytes())
    return h.hexdigest()


def stage_hash(stage: str, opts: PipelineOptions, s: dict, fingerprint: dict, upstream_hashes: dict,
               version: str = __version__, registry: dict | None = None) -> str:
    """Input hash of ``stage``: everything its numbers depend on (see the module docstring). ``registry``: the
    stages of the pipeline the stage belongs to (default: the twin pipeline's :data:`REGISTRY`)."""
    registry = REGISTRY if registry is None else registry
    return _sha({"format_version": FORMAT_VERSION, "rotorlab": version, "stage": stage, "vehicle": opts.vehicle,
                 "vehicle_files": fingerprint, "seed": opts.seed,
                 "settings": {k: s[k] for k in registry[stage].settings}, "upstream": upstream_hashes})


#: descriptors of the run-folder locks this process holds: a forked child (a pool worker) closes its copies at
#: once, so the lock lives exactly as long as the pipeline process and never in a worker that outlives it
_HELD_LOCKS: set[int] = set()


def _close_inherited_locks() -> None:
    for fd in list(_HELD_LOCKS):
        with contextlib.suppress(OSError):
            os.close(fd)
    _HELD_LOCKS.clear()


os.register_at_fork(after_in_child=_close_inherited_locks)


def _lock_holders(path: Path) -> list[int]:
    """Pids of the processes that have ``path`` open (Linux /proc; empty elsewhere or where unreadable)."""
    pids = []
    target = str(path.resolve())
    for proc in Path("/proc").glob("[0-9]*"):
        with contextlib.suppress(OSError):
            if any(os.readlink(fd) == target for fd in (proc / "fd").iterdir()):
                pids.append(int(proc.name))
    return sorted(p for p in pids if p != os.getpid())


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@contextlib.contextmanager
def run_folder_lock(out: Path):
    """Hold the run folder ``out`` for one pipeline: a second pipeline into the same folder is refused.

    An advisory ``flock`` on ``OUT/.rotorlab.lock``: the kernel releases it when the holder exits in any way
    (Ctrl-C, SIGKILL, a crash), so a lock is never stale and needs no clean-up; the file itself may stay.
    Only the pipeline process holds it: the descriptor is close-on-exec and every forked worker closes its
    copy (a worker that outlived a killed pipeline held the lock and blocked the re-run). A lock still held
    after its recorded pipeline died (workers of an older rotorlab) is reported as such, with their pids.
    It records the holder's pid, host and start time for the refusal message. Without it two runs shared
    ``stages/.<stage>.partial`` and committed a stage holding only the other's stage.json, for good.
    """
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    _HELD_LOCKS.add(fd)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 512, 0).decode("utf-8", "replace").strip() or "another process"
            words = holder.split()
            pid = int(words[1]) if len(words) > 1 and words[0] == "pid" and words[1].isdigit() else None
            same_host = socket.gethostname() in holder
            if pid is not None and same_host and not _alive(pid):
                left = _lock_holders(path)
                raise PipelineError(
                    f"{out} is locked by processes left over from a pipeline that is no longer running ({holder}): "
                    f"pid(s) {', '.join(map(str, left)) or 'unknown'} still hold {path}; stop them "
                    f"(kill {' '.join(map(str, left)) or 'PID'}) and run the same command again to resume") from None
            raise PipelineError(f"{out} is in use by another rotorlab pipeline ({holder}); wait for it to finish "
                                "or choose another --out folder") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}, started "
                      f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode(), 0)
        yield path
    finally:
        _HELD_LOCKS.discard(fd)
        os.close(fd)  # releases the flock


#: the options of a run that choose its numbers: a folder holding a run made with others is not replaced
_RUN_CHOICES = (("seed", "--seed"), ("level", "--quick/--tiny"), ("settings", "--n-boot/--n-mc"))


#: settings that choose what a stage adds, not the numbers a run folder holds: another --controller re-runs the
#: validation (its hash) into the same folder instead of refusing it
_NOT_RUN_CHOICES = ("controller",)


def _choices(settings):
    return None if settings is None else {k: v for k, v in settings.items() if k not in _NOT_RUN_CHOICES}


def _controller_setting(value: str | None) -> dict | None:
    """``--controller AUTOPILOT:PARAMS`` as the validate stage's setting: the autopilot, its complete parameters
    and the set's name in the report (``px4:FILE``)."""
    if value is None:
        return None
    from rotorlab.sim.control.autopilot import parse_autopilot

    spec = parse_autopilot(value)  # a missing or bad file: ConfigError naming it
    if spec is None:
        from rotorlab import autopilots

        raise PipelineError(f"--controller: expected AUTOPILOT:PARAMS with AUTOPILOT one of "
                            f"{', '.join(autopilots.AUTOPILOTS)} and PARAMS 'defaults' or a parameter file, got "
                            f"{value!r}")
    return {"name": f"{spec.autopilot}:{Path(spec.source).name}", "autopilot": spec.autopilot,
            "params": dict(spec.params), "source": spec.source}


def _open_run_folder(out: Path, vehicle: str, seed: int | None = None, level: str | None = None,
                     settings: dict | None = None) -> dict:
    """The manifest of ``out`` (a fresh one for a new or empty folder), refusing a folder that is not a
    compatible run of ``vehicle``, or (when given) one whose stages were computed with another seed, level or
    sizes: re-running into it would replace those results, so another --out is asked for. Called before the
    lock is taken (a foreign folder is refused before anything is written into it) and again under the lock,
    where the manifest read is the one the run updates."""
    man = read_manifest(out)
    if man is None:
        if out.exists() and any(p.name != LOCK_NAME for p in out.iterdir()):
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
    asked = {"seed": seed, "level": level, "settings": _choices(settings)}
    if man.get("stages"):
        for key, flag in _RUN_CHOICES:
            if key == "settings" and isinstance(man.get(key), dict):
                man = {**man, key: _choices(man[key])}
            if asked[key] is not None and key in man and man[key] != json.loads(json.dumps(asked[key])):
                was = man[key] if key != "settings" else {k: v for k, v in man[key].items()
                                                          if isinstance(man[key], dict) and v != asked[key].get(k)}
                now = asked[key] if key != "settings" else {k: asked[key][k] for k in was if k in asked[key]}
                raise PipelineError(
                    f"{out} holds a pipeline run with {key} {was} ({flag}), not {now}; re-running into it would "
                    f"replace its results: use another --out folder, or delete {out} to start over")
    man["rotorlab_version"] = __version__
    return man


def _cached_stage(final: Path, h: str, committed: dict | None, log=print) -> tuple[str, dict] | None:
    """The output hash and stage.json record of the committed stage folder ``final`` if it was built from inputs
    hashing to ``h`` and its files are still the ones committed: their hash must equal the ``output_hash``
    recorded in stage.json at the commit and in the manifest (``committed``, its entry for the stage, when it
    has one). A stage whose files were edited, truncated or half-overwritten is reported and recomputed, never
    reused (None)."""
    done = final / "stage.json"
    if not done.exists():
        return None
    try:
        doc = read_json(done, "stage record", note=False)
    except ValueError:  # ConfigError: not JSON, not UTF-8, too deep, not a regular file
        log(f"  {done} is not readable JSON: recomputing the stage")
        return None
    if not isinstance(doc, dict) or doc.get("hash") != h:
        return None
    same_inputs = isinstance(committed, dict) and committed.get("hash") == h  # not an entry of an older run
    recorded = {doc.get("output_hash")} | ({committed.get("output_hash")} if same_inputs else set())
    got = dir_hash(final)
    if recorded != {got}:
        log(f"  {final}: files differ from those committed (output hash mismatch): recomputing the stage")
        return None
    return got, doc


def run_pipeline(opts: PipelineOptions, *, stages=STAGES, log=print) -> dict:
    """Run (or resume) the pipeline into ``opts.out``; returns the manifest.

    Each stage prints one line: its number, name, ``done``/``cached`` and its time.
    """
    v = load_vehicle(opts.vehicle)  # unknown vehicle -> UnknownNameError listing the valid ones, before any work
    try:  # tuning and validation start from the vehicle's standard set: a vehicle of one's own needs one too
        gains_path(v, "standard")
    except RotorlabError as exc:
        raise PipelineError(f"the pipeline starts from the vehicle's 'standard' gain set, in gains/standard.toml "
                            f"beside its file ({gains_dir(v)}): {exc}") from None
    s = settings_for(opts.level, opts.n_boot, opts.n_mc)
    s["controller"] = _controller_setting(opts.controller)
    out = Path(opts.out)
    if out.exists() and not out.is_dir():
        raise PipelineError(f"--out {out} is a file; expected a run folder")
    # refuse a foreign or incompatible folder, or one holding another seed's results, before writing into it
    _open_run_folder(out, opts.vehicle, opts.seed, opts.level, s)
    atomic.check_writable_dir(out, "run folder")  # before any work: a read-only --out must not cost a stage
    with run_folder_lock(out):
        return _run_locked(opts, s, out, stages, log)


def log_fingerprint(opts: LogPipelineOptions) -> dict:
    """Content hashes of a log run's inputs: the log (every file of a ulog2csv folder), the starting vehicle's
    TOML (or the shipped default's) and the autopilot asked for, so that changing any of them re-runs what
    depends on it."""
    from rotorlab.pipeline.stages.log_calibrate import DEFAULT_VEHICLE

    log = Path(opts.log)
    files = sorted(f for f in log.rglob("*") if f.is_file()) if log.is_dir() else [log]
    h = hashlib.sha256()
    for f in files:
        h.update(f.relative_to(log).as_posix().encode() if log.is_dir() else b"")
        with open(f, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    vehicle = opts.vehicle_file or DEFAULT_VEHICLE
    return {"log": h.hexdigest(), "vehicle": _sha(vehicle_path(vehicle).read_bytes()),
            "autopilot": opts.autopilot or "from the log"}


def run_log_pipeline(opts: LogPipelineOptions, *, stages=LOG_STAGES, log=print) -> dict:
    """Run (or resume) the log pipeline (``rotorlab pipeline --log``) into ``opts.out``; returns the manifest.

    The same machinery as :func:`run_pipeline` (locked run folder, stage hashes, atomic stage commits, the
    executor), entered from a flight log: identify -> calibrate -> tune -> validate -> report
    (:data:`rotorlab.pipeline.stages.LOG_REGISTRY`). The run's identity in its folder is ``log:<file name>``.

    Examples
    --------
    >>> from rotorlab.pipeline import LogPipelineOptions, run_log_pipeline
    >>> opts = LogPipelineOptions(log="flight.ulg", out="runs/flight", level="quick")
    >>> man = run_log_pipeline(opts)  # doctest: +SKIP
    """
    from rotorlab import autopilots
    from rotorlab.ident.flightlogs import detect_format

    path = Path(opts.log)
    if not path.exists():
        raise PipelineError(f"--log {path}: no such file or folder")
    detect_format(path)  # an unknown suffix: DataError naming the formats, before any work
    if opts.autopilot is not None and opts.autopilot not in autopilots.AUTOPILOTS:
        raise PipelineError(f"--autopilot: expected one of {', '.join(autopilots.AUTOPILOTS)}, got {opts.autopilot!r}")
    if opts.vehicle_file is not None:
        load_vehicle(opts.vehicle_file)  # a bad vehicle TOML: ConfigError naming file and field, before any work
    s = log_settings_for(opts.level)
    out = Path(opts.out)
    if out.exists() and not out.is_dir():
        raise PipelineError(f"--out {out} is a file; expected a run folder")
    _open_run_folder(out, opts.vehicle, opts.seed, opts.level, s)
    atomic.check_writable_dir(out, "run folder")
    fp = log_fingerprint(opts)
    with run_folder_lock(out):
        return _run_locked(opts, s, out, stages, log, registry=LOG_REGISTRY, fingerprint=fp,
                           extra={"log": str(path.resolve()), "start_vehicle": opts.vehicle_file,
                                  "autopilot": opts.autopilot})


def _run_locked(opts: PipelineOptions, s: dict, out: Path, stages, log, *, registry: dict | None = None,
                fingerprint: dict | None = None, extra: dict | None = None) -> dict:
    """Run the stages of ``registry`` (default: the twin pipeline's) in its order under the held lock;
    ``fingerprint``: the content hashes of the run's input files (default: the vehicle's configuration);
    ``extra``: more entries for the manifest (the log pipeline's log and autopilot)."""
    registry = REGISTRY if registry is None else registry
    order = tuple(registry)
    man = _open_run_folder(out, opts.vehicle, opts.seed, opts.level, s)
    man.update(seed=opts.seed, level=opts.level, settings=_choices(s), **(extra or {}))
    out.mkdir(parents=True, exist_ok=True)
    (out / "stages").mkdir(exist_ok=True)
    atomic.write_json(out / "manifest.json", man)
    run = RunFolder(out, opts.vehicle)
    fp = _vehicle_fingerprint(opts.vehicle) if fingerprint is None else fingerprint
    t_all = time.perf_counter()
    out_hashes: dict = {}
    executor = None
    try:
        for i, stage in enumerate(order, 1):
            if stage not in stages:
                continue
            final = stage_dir(out, stage)
            ups = {u: out_hashes.get(u) or (dir_hash(stage_dir(out, u)) if stage_dir(out, u).exists() else None)
                   for u in registry[stage].upstream}
            h = stage_hash(stage, opts, s, fp, ups, registry=registry)
            found = _cached_stage(final, h, man["stages"].get(stage), log)
            if found is not None:
                cached, record = found
                out_hashes[stage] = cached
                entry = man["stages"].get(stage)
                if not (isinstance(entry, dict) and entry.get("hash") == h and entry.get("output_hash") == cached):
                    # committed, but the run was killed before the manifest recorded it
                    seconds = record.get("seconds", 0.0)
                    man["stages"][stage] = {"hash": h, "output_hash": cached, "seconds": round(float(seconds), 3)}
                    atomic.write_json(out / "manifest.json", man)
                log(f"[{i}/{len(order)}] {stage:<12} cached ({final})")
                continue
            if executor is None:
                executor = get_executor(opts.executor, opts.workers)
            work = out / "stages" / f".{stage}.partial"
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            log(f"[{i}/{len(order)}] {stage:<12} running ...")
            t0 = time.perf_counter()
            result = registry[stage].run(StageContext(run, work, opts, s, executor))
            dt_s = time.perf_counter() - t0
            doc = {"stage": stage, "hash": h, "seconds": dt_s, "upstream": ups, "result": result}
            atomic.write_json(work / "stage.json", doc)
            # dir_hash reads only the result from stage.json, so recording the output hash there leaves it unchanged
            out_hashes[stage] = dir_hash(work)
            atomic.write_json(work / "stage.json", {**doc, "output_hash": out_hashes[stage]})
            shutil.rmtree(final, ignore_errors=True)
            work.rename(final)  # the commit point: a stage folder either is complete or does not exist
            man["stages"][stage] = {"hash": h, "output_hash": out_hashes[stage], "seconds": round(dt_s, 3)}
            atomic.write_json(out / "manifest.json", man)
            log(f"[{i}/{len(order)}] {stage:<12} done in {dt_s:.1f} s")
    finally:
        if executor is not None:
            executor.close()
    total = time.perf_counter() - t_all
    log(f"pipeline finished in {total:.1f} s; report: {stage_dir(out, 'report') / 'report.md'}")
    man["total_seconds"] = round(total, 3)
    atomic.write_json(out / "manifest.json", man)
    return man
