"""One way to run many independent tasks: in this process, on a local process pool, or on Dask.

Every executor maps a picklable top-level function over a list of items and returns the results in the
order of the items, so a caller's numbers never depend on where or in which order the tasks ran.
Randomness travels with the items: :func:`task_seeds` gives each task its own seed from
``numpy.random.SeedSequence(seed).spawn(n)``, never from a worker's global state.

Specs accepted by :func:`get_executor`:

``"serial"``  in this process (tests, debugging).
``"local"``   :class:`concurrent.futures.ProcessPoolExecutor` (the default).
``"dask"``    a ``dask.distributed.LocalCluster`` started for the run (one thread per worker process).
``"dask://HOST:PORT"``  an existing Dask scheduler; connecting is bounded by ``timeout_s`` and a scheduler
that does not answer, or has no worker within ``timeout_s``, gives an :class:`ExecutorError` naming the address.
Connect only to a scheduler you trust: Dask sends pickled objects, which run code in this process when they
are unpickled (docs/security.md).

Local pool workers die with their parent (``prctl(PR_SET_PDEATHSIG)`` on Linux): a pipeline killed with
SIGKILL leaves no worker computing for nobody.
"""

from __future__ import annotations

import asyncio
import concurrent.futures as cf
import multiprocessing
import os
import signal
import socket
import sys
from collections.abc import Callable, Sequence

import numpy as np
from tqdm import tqdm

from rotorlab.errors import RotorlabError

# dask.distributed is imported where a Dask executor is made: an optional dependency (rotorlab[dask]).

__all__ = ["Executor", "ExecutorError", "SerialExecutor", "LocalExecutor", "DaskExecutor", "get_executor",
           "map_tasks", "task_seeds", "EXECUTOR_SPECS"]

EXECUTOR_SPECS = ("serial", "local", "dask", "dask://HOST:PORT")


class ExecutorError(RotorlabError):
    """An executor cannot be started or reached (bad spec, Dask missing, scheduler not answering)."""


def task_seeds(seed: int | None, n: int) -> list[int]:
    """``n`` independent 32-bit seeds, child ``i`` of ``SeedSequence(seed)``: the same on every executor."""
    return [int(s.generate_state(1, np.uint32)[0]) for s in np.random.SeedSequence(seed).spawn(int(n))]


class Executor:
    """Ordered ``map`` over picklable tasks; use as a context manager so workers are shut down."""

    name = "executor"
    workers = 1

    def map(self, fn: Callable, items: Sequence, *, desc: str | None = None, progress: bool = False) -> list:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, workers={self.workers})"


def _bar(total, desc, progress):
    return tqdm(total=total, desc=desc, disable=not progress, leave=False)


class SerialExecutor(Executor):
    name = "serial"

    def map(self, fn, items, *, desc=None, progress=False):
        out = []
        with _bar(len(items), desc, progress) as bar:
            for it in items:
                out.append(fn(it))
                bar.update(1)
        return out


_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _die_with_parent(parent_pid: int) -> None:
    """Ask the kernel to kill this process when its parent dies (Linux ``prctl(PR_SET_PDEATHSIG, SIGKILL)``).

    A pool worker otherwise outlives a parent killed with SIGKILL (or crashed) by minutes, computing for
    nobody and holding what it inherited. Elsewhere, and should the parent already be gone, the worker
    checks its parent instead.
    """
    if sys.platform.startswith("linux"):
        import ctypes

        try:  # ctypes, not a dependency: prctl is one libc call
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


def _worker_init(parent_pid: int) -> None:
    """Pool-worker initializer: die with the parent; leave Ctrl-C to the parent (it reaches the whole process
    group, and the parent stops the workers: otherwise every worker printed its own KeyboardInterrupt
    traceback); SIGTERM and SIGHUP end a worker at once (a forked worker inherits the CLI's handlers, which
    turn them into KeyboardInterrupt for the parent's clean-up)."""
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


#: process pools whose workers were stopped mid-task (Ctrl-C, SIGTERM) in this process
ABANDONED_POOLS = 0


class LocalExecutor(Executor):
    """Process pool on this machine. Forked workers (Linux) start in milliseconds and inherit the imports."""

    name = "local"

    def __init__(self, max_workers: int | None = None):
        self.workers = max(1, int(max_workers or os.cpu_count() or 1))
        methods = multiprocessing.get_all_start_methods()
        self._ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        self._pool = None

    def map(self, fn, items, *, desc=None, progress=False):
        items = list(items)
        if self.workers == 1 or len(items) <= 1:
            return SerialExecutor().map(fn, items, desc=desc, progress=progress)
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=self._ctx,
                                                initializer=_worker_init, initargs=(os.getpid(),))
        futs = [self._pool.submit(fn, it) for it in items]
        try:
            with _bar(len(items), desc, progress) as bar:
                for _ in cf.as_completed(futs):
                    bar.update(1)
        except KeyboardInterrupt:
            self._terminate()
            raise
        return [f.result() for f in futs]

    def _terminate(self):
        """Stop the workers now (Ctrl-C): the pool's shutdown would first finish every running task.

        A worker stopped while it writes a result leaves half a message in the pool's result pipe, and the
        pool's manager thread then waits for the rest for ever; the interpreter joins that thread at exit, so
        :func:`rotorlab.cli.console` ends such a process without the join (:data:`ABANDONED_POOLS`).
        """
        global ABANDONED_POOLS
        ABANDONED_POOLS += 1
        pool, self._pool = self._pool, None
        # the pool has no public way to stop running tasks: its processes (a private attribute) are terminated
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            proc.terminate()
        pool.shutdown(wait=False, cancel_futures=True)

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def map_tasks(fn: Callable, tasks: Sequence, *, executor: Executor | None = None, n_jobs: int = 1,
              desc: str | None = None, progress: bool = False) -> list:
    """The one way the libraries (bootstrap, Monte Carlo, tuning starts) run their tasks: through the
    caller's ``executor`` (a run's local pool or Dask cluster) when given, else on a local pool of ``n_jobs``
    processes made for this call (in this process when ``n_jobs <= 1``). Results in task order."""
    if executor is not None:
        return list(executor.map(fn, tasks, desc=desc, progress=progress))
    with LocalExecutor(max(1, int(n_jobs))) as ex:
        return ex.map(fn, tasks, desc=desc, progress=progress)


class DaskExecutor(Executor):
    """Dask distributed: a fresh ``LocalCluster`` (``address=None``) or an existing scheduler."""

    def __init__(self, address: str | None = None, n_workers: int | None = None, timeout_s: float = 10.0):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as exc:  # optional dependency
            raise ExecutorError("the dask executor needs dask.distributed: pip install 'rotorlab[dask]'") from exc
        self._cluster = None
        if address is None:
            self.name = "dask"
            self.workers = max(1, int(n_workers or os.cpu_count() or 1))
            self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                         dashboard_address=None)
            self.client = Client(self._cluster)
        else:
            self.name = f"dask://{address.removeprefix('tcp://')}"
            self.client = _connect(Client, address, float(timeout_s))
            self.workers = _wait_for_workers(self.client, address, float(timeout_s))

    def map(self, fn, items, *, desc=None, progress=False):
        from dask.distributed import as_completed

        items = list(items)
        futs = self.client.map(fn, items, pure=False)
        with _bar(len(items), desc, progress) as bar:
            for _ in as_completed(futs):
                bar.update(1)
        return self.client.gather(futs)

    def close(self):
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


def _connect(Client, address: str, timeout_s: float):
    """A Dask client of the scheduler at ``tcp://HOST:PORT``, or an :class:`ExecutorError` within ``timeout_s``.

    A plain TCP connect first, so a refused or unroutable address fails in ``timeout_s`` with the OS's reason.
    Then Dask's own ``identity`` RPC, bounded by ``asyncio.wait_for``, must answer "Scheduler" before a client is
    made: against something that accepts connections but is no scheduler (an HTTP server) ``Client(timeout=...)``
    waited for an answer forever, or read the peer's bytes as a frame length and failed allocating exabytes.
    """
    host, port = address.removeprefix("tcp://").rsplit(":", 1)
    hint = "start one with `dask scheduler` or use --executor local"
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except (OSError, ValueError) as exc:
        raise ExecutorError(f"no Dask scheduler answered at {address} within {timeout_s:g} s "
                            f"({getattr(exc, 'strerror', None) or exc}); {hint}") from None

    async def identify():
        from distributed.core import rpc

        async with rpc(address, timeout=timeout_s) as r:
            return await r.identity()

    try:
        ident = asyncio.run(asyncio.wait_for(identify(), timeout_s))
    except Exception as exc:  # noqa: BLE001 - whatever the peer's bytes make Dask raise, it is not a scheduler
        why = "no Dask handshake" if isinstance(exc, (asyncio.TimeoutError, TimeoutError)) else type(exc).__name__
        raise ExecutorError(f"{address} accepts connections but is not a Dask scheduler ({why} within "
                            f"{timeout_s:g} s); {hint}") from None
    if not isinstance(ident, dict) or ident.get("type") != "Scheduler":
        raise ExecutorError(f"{address} answers as {ident.get('type') if isinstance(ident, dict) else ident!r}, "
                            f"not as a Dask scheduler; {hint}")
    try:
        return Client(address, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError) as exc:
        raise ExecutorError(f"the Dask scheduler at {address} stopped answering ({exc}); {hint}") from None


def _wait_for_workers(client, address: str, timeout_s: float) -> int:
    """The number of workers of the scheduler ``client`` is connected to, waiting up to ``timeout_s`` for the
    first: a scheduler without workers accepts tasks and never runs them, so a run waited for ever."""
    n = len(client.scheduler_info().get("workers", {}))
    if n:
        return n
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except (TimeoutError, OSError) as exc:
        client.close()
        raise ExecutorError(f"the Dask scheduler at {address} has no workers (none joined within {timeout_s:g} s: "
                            f"{type(exc).__name__}); start some with `dask worker {address}` or use --executor "
                            "local") from None
    return max(1, len(client.scheduler_info().get("workers", {})))


def get_executor(spec: str | None = "local", max_workers: int | None = None, timeout_s: float = 10.0) -> Executor:
    """Executor from its spec string (see the module docstring)."""
    spec = spec or "local"
    if spec == "serial":
        return SerialExecutor()
    if spec == "local":
        return LocalExecutor(max_workers)
    if spec == "dask":
        return DaskExecutor(None, n_workers=max_workers, timeout_s=timeout_s)
    if spec.startswith("dask://"):
        addr = spec[len("dask://"):]
        if ":" not in addr or not addr.rsplit(":", 1)[1].isdigit():
            raise ExecutorError(f"executor '{spec}': expected dask://HOST:PORT, e.g. dask://127.0.0.1:8786")
        return DaskExecutor("tcp://" + addr, timeout_s=timeout_s)
    raise ExecutorError(f"unknown executor '{spec}'; valid: {', '.join(EXECUTOR_SPECS)}")
