import importlib.util
import json
import os
from pathlib import Path

import pytest

# No MUJOCO_GL here: the suite runs as a user runs it, and `import rotorlab` picks the headless OpenGL backend
# (rotorlab.glbackend: EGL, then OSMesa, else no rendering).
# pytest -n 2 already uses both cores: BLAS threads on top of that only fight each other
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_module():
    """``repo_module(path)``: a script of the repository that is no package (``setup.py``, ``docs/*.py``,
    ``benchmarks/*.py``; ``path`` relative to the root) loaded as a module under a name of its own, never
    ``__main__``, so its command-line entry point does not run."""
    def load(path: str):
        spec = importlib.util.spec_from_file_location(f"repo_{Path(path).stem}", ROOT / path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    return load


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory):
    """``quick_run(vehicle, seed=0)``: the run folder and log lines of a seeded `rotorlab pipeline --quick` (local
    executor, 2 workers), run once per vehicle and seed in a session and shared by the tests that read it."""
    # imported here, not above: the pipeline's workers must see the BLAS thread counts set above
    from rotorlab.pipeline import PipelineOptions, run_pipeline

    runs = {}

    def get(vehicle: str, seed: int = 0):
        if (vehicle, seed) not in runs:
            out, lines = tmp_path_factory.mktemp(f"{vehicle}-s{seed}") / "run", []
            run_pipeline(PipelineOptions(vehicle=vehicle, out=out, level="quick", seed=seed, executor="local",
                                         workers=2, progress=False), log=lines.append)
            runs[vehicle, seed] = out, lines
        return runs[vehicle, seed]
    return get


@pytest.fixture(scope="session")
def quick_summary(quick_run):
    """``quick_summary(vehicle, seed=0)``: summary.json of that :func:`quick_run` run."""
    from rotorlab.pipeline import stage_dir  # as in quick_run

    def get(vehicle: str, seed: int = 0) -> dict:
        return json.loads((stage_dir(quick_run(vehicle, seed)[0], "report") / "summary.json").read_text())
    return get
