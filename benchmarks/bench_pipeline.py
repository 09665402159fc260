"""Time of each pipeline stage: ``python benchmarks/bench_pipeline.py [--level quick|full|tiny] [--executor local]``.

Targets: quick < 60 s, full < 5 min on 2 cores. Prints one line per stage and the total, then runs the same
pipeline again into the same folder to show that a resume with unchanged inputs costs almost nothing.
"""

import argparse
import json
import tempfile
import time
from pathlib import Path

from rotorlab.pipeline import PipelineOptions, run_pipeline


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--level", default="quick", choices=["tiny", "quick", "full"])
    ap.add_argument("--vehicle", default="anteos-p2a2")
    ap.add_argument("--executor", default="local")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        opts = PipelineOptions(vehicle=a.vehicle, out=out, level=a.level, executor=a.executor, workers=a.workers,
                               progress=False)
        t0 = time.perf_counter()
        run_pipeline(opts, log=lambda s: None)
        total = time.perf_counter() - t0
        man = json.loads((out / "manifest.json").read_text())
        print(f"pipeline --{a.level} {a.vehicle} executor={a.executor} workers={a.workers}")
        for name, st in man["stages"].items():
            print(f"  {name:<12} {st['seconds']:8.1f} s")
        print(f"  {'total':<12} {total:8.1f} s")
        t0 = time.perf_counter()
        run_pipeline(opts, log=lambda s: None)
        print(f"  resume, nothing changed: {time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
