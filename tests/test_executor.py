"""Executors: same numbers everywhere, clear errors for bad specs and unreachable schedulers."""

import numpy as np
import pytest

from rotorlab.executor import ExecutorError, get_executor, task_seeds
from rotorlab.pipeline.stages.experiments import run_experiment


def _square(x):
    return x * x


def _plan():
    seeds = task_seeds(7, 2)
    return [{"name": f"r{i}", "scenario": "prbs", "vehicle": "anteos-p2a2", "seed": s, "duration_s": 1.5,
             "options": {}} for i, s in enumerate(seeds)]


def test_task_seeds_are_reproducible_and_distinct():
    a, b = task_seeds(3, 5), task_seeds(3, 5)
    assert a == b and len(set(a)) == 5
    assert task_seeds(4, 5) != a
    # child i of SeedSequence(seed), whatever n is: adding tasks does not reseed the earlier ones
    assert task_seeds(3, 8)[:5] == a


def test_map_keeps_item_order():
    with get_executor("local", 2) as ex:
        assert ex.map(_square, list(range(20))) == [i * i for i in range(20)]


def test_same_campaign_on_every_executor():
    plan = _plan()
    results = {}
    for spec in ("serial", "local", "dask"):
        with get_executor(spec, 2) as ex:
            results[spec] = ex.map(run_experiment, plan)
    ref = results["serial"]
    assert np.std(ref[0]["columns"]["q"]) > 0.1  # the rig moved: the comparison is not trivially of zeros
    for spec in ("local", "dask"):
        for r0, r1 in zip(ref, results[spec], strict=True):  # every task came back
            assert r0["name"] == r1["name"]
            for col in ("u_lon", "q", "theta"):
                np.testing.assert_array_equal(r0["columns"][col], r1["columns"][col])
    # different tasks got different seeds, hence different noise
    assert not np.array_equal(ref[0]["columns"]["u_lon"], ref[1]["columns"]["u_lon"])


def test_unreachable_dask_scheduler_fails_clearly():
    with pytest.raises(ExecutorError, match=r"no Dask scheduler answered at tcp://127.0.0.1:9 within 2 s"):
        get_executor("dask://127.0.0.1:9", timeout_s=2)


@pytest.mark.parametrize("spec", ["threads", "dask://nohostport", "dask://host:port"])
def test_bad_executor_spec(spec):
    with pytest.raises(ExecutorError, match="dask://HOST:PORT"):
        get_executor(spec)
