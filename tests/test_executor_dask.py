"""Every parallel library step (bootstrap replications, Monte Carlo samples, tuning starts) runs on a Dask
cluster through the executor's map, on the cluster's worker processes, with the same numbers as in this
process. The cluster is a LocalCluster of 2 worker processes reached by its address, as `--executor
dask://HOST:PORT` reaches a remote one."""

import functools
import os
import time

import control as ct
import numpy as np
import pytest
from helpers import published_tf

from rotorlab.excitation import prbs
from rotorlab.executor import Executor, get_executor
from rotorlab.gains import load_gains
from rotorlab.ident import IdentifiedModel, bootstrap, pbsid
from rotorlab.lti import c2d_zoh
from rotorlab.tune import PlantModel, load_spec, tune_cascade
from rotorlab.tune.montecarlo import montecarlo, single_loop
from rotorlab.vehicles import gains_path

distributed = pytest.importorskip("dask.distributed")

DT = 0.02
G = c2d_zoh(published_tf("anteos-p2a2", "testbed")[0], DT)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as lc:
        host_port = lc.scheduler_address.removeprefix("tcp://")
        with get_executor(f"dask://{host_port}", timeout_s=30) as ex:
            yield ex, lc


def _traced(fn, task):
    """Run ``fn(task)`` and say where: (pid, Dask worker address or None)."""
    try:
        where = distributed.get_worker().address
    except ValueError:  # not on a Dask worker
        where = None
    return os.getpid(), where, fn(task)


class _Where(Executor):
    """The Dask executor, recording the process and worker of every task the libraries hand it."""

    def __init__(self, ex):
        self.ex, self.pids, self.where = ex, set(), set()
        self.workers = ex.workers

    def map(self, fn, tasks, *, desc=None, progress=False):
        out = self.ex.map(functools.partial(_traced, fn), tasks)
        self.pids |= {p for p, _, _ in out}
        self.where |= {w for _, w, _ in out}
        return [r for _, _, r in out]


def _slow_square(x):
    time.sleep(0.2)  # long enough that the scheduler spreads the tasks over both workers
    return x * x


def test_tasks_run_on_the_cluster_workers(cluster):
    ex, lc = cluster
    assert ex.workers == 2
    where = _Where(ex)
    assert where.map(_slow_square, list(range(8))) == [i * i for i in range(8)]
    assert os.getpid() not in where.pids and len(where.pids) == 2
    assert where.where == set(lc.scheduler_info["workers"])


def test_bootstrap_on_dask_matches_this_process(cluster):
    u = prbs(1500, DT, hold_range_s=(0.05, 0.8), amplitude=7.0, seed=3)
    y = IdentifiedModel(G, delay=3).simulate(u)[:, 0]
    y = y + 0.1 * y.std() * np.random.default_rng(4).standard_normal(len(y))
    ident = functools.partial(pbsid, order=2, past=20, future=10, delay=3, dt=DT)
    where = _Where(cluster[0])
    a = bootstrap(u, y, ident, n_boot=6, seed=3, n_jobs=1, progress=False)
    b = bootstrap(u, y, ident, n_boot=6, seed=3, chunk=2, executor=where)
    assert os.getpid() not in where.pids and where.where <= set(cluster[1].scheduler_info["workers"])
    for ma, mb in zip(a.models, b.models, strict=True):
        np.testing.assert_array_equal(np.asarray(ma.sys.A), np.asarray(mb.sys.A))
    assert not np.array_equal(np.asarray(a.models[0].sys.A), np.asarray(a.models[1].sys.A))


def test_montecarlo_on_dask_matches_this_process(cluster):
    C = ct.ss(ct.tf([0.3, 0.5], [1.0, -1.0], DT))
    W = c2d_zoh(ct.tf([0.5, 1.0], [0.05, 1.0]) * 0.05, DT)
    builder = functools.partial(single_loop, C=C)
    where = _Where(cluster[0])
    a = montecarlo(G, W, builder, 1.0, n=12, seed=11, progress=False, t_final_s=1.0)
    b = montecarlo(G, W, builder, 1.0, n=12, seed=11, executor=where, t_final_s=1.0)
    assert os.getpid() not in where.pids
    np.testing.assert_array_equal(a.setpoint, b.setpoint)
    np.testing.assert_array_equal(a.abscissa, b.abscissa)


def test_tuning_starts_on_dask_match_this_process(cluster):
    spec = load_spec("anteos-p2a2")
    plant = PlantModel(*published_tf("anteos-p2a2", "testbed"))
    std = load_gains(gains_path("anteos-p2a2", "standard"))
    where = _Where(cluster[0])
    a = tune_cascade(spec, [plant], std, starts=2, seed=0, max_iter=3)
    b = tune_cascade(spec, [plant], std, starts=2, seed=0, max_iter=3, executor=where)
    assert os.getpid() not in where.pids
    assert b.starts == a.starts and b.objective == a.objective
    assert b.gains["pitch"].inner.as_dict() == a.gains["pitch"].inner.as_dict()
