"""Wall time of the log pipeline, end to end and per stage:
``python benchmarks/bench_log_pipeline.py [--level quick|full|tiny] [--log FLIGHT ...] [--real]``.

Target: quick <= 60 s end to end on this machine's 2 cores. Without ``--log`` it runs on a flight the project
writes itself (tests/flightlog_sim.py: three axes excited in turn, written as a ULog); ``--real`` adds every log of
the development folder ``../shared/reallogs`` (or ``$ROTORLAB_REALLOGS``) and skips it when the folder is absent.
Per log: each stage's time, the total, the held-out VAF of the calibrated twin closed with the log's parameters
against the closed-loop fit's, and the verdict's first sentence; then a resume with unchanged inputs.
"""

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from rotorlab.errors import RotorlabError
from rotorlab.pipeline import LogPipelineOptions, run_log_pipeline

ROOT = Path(__file__).resolve().parents[1]
REAL = Path(os.environ.get("ROTORLAB_REALLOGS", ROOT.parent / "shared" / "reallogs"))


def simulated_log(folder: Path) -> Path:
    sys.path.insert(0, str(ROOT / "tests"))
    import flightlog_sim as fs

    from rotorlab.ident.flightlogs.writers import write_ulog

    fs.PLANTS = {"roll": (400.0, 0.03), "pitch": (350.0, 0.03), "yaw": (60.0, 0.03)}  # one motor pole
    f = fs.fly(seed=3, excite_s=10.0)
    return write_ulog(folder / "simulated.ulg", fs.px4_topics(f), fs.px4_params(), {"ver_sw_release": 0x010E0000})


def real_logs() -> list[Path]:
    if not REAL.is_dir():
        print(f"(no real logs: {REAL} is absent)")
        return []
    out = []
    for d in sorted(p for p in REAL.iterdir() if p.is_dir()):
        logs = sorted(p for p in d.iterdir() if p.suffix.lower() in (".ulg", ".bin", ".log"))
        out += logs or ([d] if any(d.glob("*.csv")) else [])
    return out


def bench(log: Path, level: str, executor: str, workers: int, tmp: Path) -> None:
    out = tmp / f"run-{log.stem or log.name}"
    opts = LogPipelineOptions(out=out, level=level, executor=executor, workers=workers,
                              progress=False, log=log)
    print(f"pipeline --log {log} --{level} executor={executor} workers={workers}")
    t0 = time.perf_counter()
    try:
        run_log_pipeline(opts, log=lambda s: None)
    except RotorlabError as exc:
        print(f"  refused after {time.perf_counter() - t0:.1f} s: {exc}")
        return
    total = time.perf_counter() - t0
    man = json.loads((out / "manifest.json").read_text())
    for name, st in man["stages"].items():
        print(f"  {name:<12} {st['seconds']:8.1f} s")
    print(f"  {'total':<12} {total:8.1f} s")
    summary = json.loads((out / "report" / "summary.json").read_text())
    for axis, p in (summary["calibrate"].get("prediction") or {}).items():
        print(f"  {axis:5s} held-out VAF: twin {p['twin_vaf_pct']:.1f} %, closed-loop fit {p['closed_loop_vaf_pct']:.1f} %")
    print(f"  verdict: {summary['verdict'][0]}")
    t0 = time.perf_counter()
    run_log_pipeline(opts, log=lambda s: None)
    print(f"  resume, nothing changed: {time.perf_counter() - t0:.2f} s")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--level", default="quick", choices=["tiny", "quick", "full"])
    ap.add_argument("--log", action="append", default=[], type=Path)
    ap.add_argument("--real", action="store_true", help="also every log of the real-log folder")
    ap.add_argument("--executor", default="local")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        logs = list(a.log) or [simulated_log(tmp)]
        if a.real:
            logs += real_logs()
        for log in logs:
            bench(log, a.level, a.executor, a.workers, tmp)


if __name__ == "__main__":
    main()
