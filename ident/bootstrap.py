"""Parametric bootstrap of subspace models (Bittanti & Lovera 2000), as published for the P2-A2 PBSID
models (000_*.txt, "Bootstrap scheme for SMI", 1000 replications).

1. Nominal model in innovation form from the original record (``identify(u, y)``).
2. Its prediction errors and their covariance (Gaussian assumption).
3. B replicated outputs: the nominal model driven by the original ``u`` and fresh Gaussian innovations.
4. B re-identifications with the same settings; their spread is the model uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control as ct
import numpy as np

from rotorlab.errors import DataError
from rotorlab.executor import Executor, map_tasks

from ._data import check_io
from .freqresp import model_frf
from .model import IdentifiedModel, lsim_fast

__all__ = ["BootstrapResult", "bootstrap"]


@dataclass(frozen=True)
class BootstrapResult:
    """Replicated models and the uncertainty they describe.

    Attributes
    ----------
    nominal : IdentifiedModel
    models : list of IdentifiedModel
        The B re-identified models.
    seed : int or None
    """

    nominal: IdentifiedModel
    models: list
    seed: int | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def poles(self) -> np.ndarray:
        """Discrete poles of every replica, shape (B, n) (complex)."""
        return np.array([np.linalg.eigvals(np.asarray(m.sys.A, float)) for m in self.models])

    def poles_continuous(self) -> np.ndarray:
        """Poles mapped to continuous time, ``log(z) / dt`` (exact for ZOH), shape (B, n), rad/s."""
        return np.log(self.poles().astype(complex)) / float(self.nominal.dt)

    def zeros(self) -> list:
        """Transmission zeros of every replica (discrete, list of arrays: counts may differ)."""
        return [np.asarray(ct.zeros(m.sys)) for m in self.models]

    def frf(self, w_rad_s) -> np.ndarray:
        """Frequency responses of all replicas on ``w_rad_s``, shape (B, nw, p, m), delay excluded."""
        w = np.asarray(w_rad_s, float)
        return np.stack([model_frf(m.sys, w) for m in self.models])

    def band(self, w_rad_s, level: float = 0.95) -> dict:
        """Pointwise percentile band of magnitude and phase at ``level`` (two-sided).

        Returns
        -------
        dict with ``w_rad_s``, ``mag_lo``, ``mag_hi``, ``phase_lo``, ``phase_hi`` (rad) and the nominal
        ``mag``, ``phase``, each (nw, p, m). Phases are taken relative to the nominal response, so the
        band does not break where the nominal phase wraps.
        """
        if not 0 < level < 1:
            raise DataError(f"band level must be in (0, 1); got {level}")
        w = np.asarray(w_rad_s, float)
        G = self.frf(w)
        G0 = model_frf(self.nominal.sys, w)
        q = [(1 - level) / 2 * 100, (1 + level) / 2 * 100]
        mag_lo, mag_hi = np.percentile(np.abs(G), q, axis=0)
        rel = np.angle(G / G0)
        ph_lo, ph_hi = np.percentile(rel, q, axis=0)
        ph0 = np.unwrap(np.angle(G0), axis=0)
        return {"w_rad_s": w, "mag": np.abs(G0), "phase": ph0, "mag_lo": mag_lo, "mag_hi": mag_hi,
                "phase_lo": ph0 + ph_lo, "phase_hi": ph0 + ph_hi}


def _replicate_task(task):
    return _replicate(*task)


def _replicate(identify, ABCK, u, y_det, chol, seeds):
    """Worker: one chunk of replications (top-level so process pools can pickle it).

    Models travel as plain arrays: control.StateSpace objects do not pickle.
    """
    A, C, K = ABCK
    p = y_det.shape[1]
    out = []
    for ss in seeds:
        rng = np.random.default_rng(ss)
        e = rng.standard_normal((len(u), p)) @ chol.T
        y_star = y_det + lsim_fast(A, K, C, np.eye(p), e)
        out.append(_pack(identify(u, y_star if p > 1 else y_star[:, 0])))
    return out


def _pack(m: IdentifiedModel) -> dict:
    s = m.sys
    return {"abcd": tuple(np.asarray(M, float) for M in (s.A, s.B, s.C, s.D)), "dt": s.dt, "delay": m.delay,
            "method": m.method, "settings": m.settings, "K": m.K, "noise_cov": m.noise_cov,
            "singular_values": m.singular_values}


def _unpack(d: dict) -> IdentifiedModel:
    return IdentifiedModel(sys=ct.ss(*d["abcd"], d["dt"]), delay=d["delay"], method=d["method"],
                           settings=d["settings"], K=d["K"], noise_cov=d["noise_cov"],
                           singular_values=d["singular_values"])


def bootstrap(u, y, identify, n_boot: int = 1000, seed: int | None = 0, n_jobs: int = 1,
              chunk: int | None = None, progress: bool = True, executor: Executor | None = None,
              desc: str = "bootstrap") -> BootstrapResult:
    """Parametric bootstrap of an identification method.

    Parameters
    ----------
    u, y : array_like
        The original record.
    identify : callable ``(u, y) -> IdentifiedModel``
        Identification with fixed settings, e.g. ``functools.partial(pbsid, order=5, past=11, future=7,
        delay=3, dt=0.02)``; must be picklable when ``n_jobs > 1`` (partials of module functions are).
        The nominal model should carry ``K`` and ``noise_cov`` (PBSID does; MOESP fits them to its
        residual); ``K = None`` means output-error innovations.
    n_boot : int
        Number of replications B.
    seed : int
        Root seed; replication i uses ``SeedSequence(seed).spawn(n_boot)[i]``, so results do not depend on
        ``n_jobs`` or ``chunk``.
    n_jobs : int
        Worker processes of a local pool (1: in this process) when no ``executor`` is given; with one, its
        workers size the chunks.
    chunk : int, optional
        Replications per task (default: about four tasks per worker).
    progress : bool
        tqdm progress bar over completed chunks, labelled ``desc``.
    executor : :class:`rotorlab.executor.Executor`, optional
        Runs the chunks (e.g. a run's Dask executor: :func:`rotorlab.executor.map_tasks`); default: a local
        process pool of ``n_jobs`` workers. The results do not depend on it.

    Returns
    -------
    BootstrapResult

    Examples
    --------
    >>> import control as ct
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)  # published P2-A2 test-bed model, 50 Hz
    >>> u = np.random.default_rng(0).choice([-1.0, 1.0], 3000)        # a random binary input, %
    >>> y = ct.forced_response(G, U=u).y[0]                            # pitch rate, deg/s (noise-free)
    >>> y = y + 0.2 * np.random.default_rng(1).standard_normal(len(y))  # gyro noise, deg/s

    >>> from functools import partial
    >>> res = ident.bootstrap(u, y, partial(ident.pbsid, order=2, past=20, future=10, dt=0.02), n_boot=20,
    ...                       progress=False)
    >>> len(res.models)
    20
    >>> bool(np.all(np.abs(res.poles()) < 1))           # every replica is a stable model
    True
    """
    u2, y2 = check_io(u, y, min_samples=2, what="bootstrap")
    if n_boot < 1:
        raise DataError(f"n_boot must be >= 1; got {n_boot}")
    nominal = identify(u if np.ndim(u) > 1 else u2[:, 0], y if np.ndim(y) > 1 else y2[:, 0])
    if not isinstance(nominal, IdentifiedModel):
        raise DataError(f"identify must return an IdentifiedModel; got {type(nominal).__name__}")
    if nominal.noise_cov is None:
        raise DataError("the nominal model has no noise_cov: use an identification method that estimates the "
                        "innovation covariance (pbsid, moesp)")
    p = y2.shape[1]
    cov = np.atleast_2d(nominal.noise_cov)
    chol = np.linalg.cholesky(cov + 1e-300 * np.eye(p))
    u_in = u2 if u2.shape[1] > 1 else u2[:, 0]
    y_det = nominal.simulate(u2)
    A, C = np.asarray(nominal.sys.A, float), np.asarray(nominal.sys.C, float)
    ABCK = (A, C, nominal.K if nominal.K is not None else np.zeros((A.shape[0], p)))
    seeds = np.random.SeedSequence(seed).spawn(n_boot)
    n_jobs = executor.workers if executor is not None else max(1, int(n_jobs))
    chunk = chunk or max(1, int(np.ceil(n_boot / (4 * n_jobs))))
    chunks = [seeds[i:i + chunk] for i in range(0, n_boot, chunk)]
    tasks = [(identify, ABCK, u_in, y_det, chol, c) for c in chunks]
    results = map_tasks(_replicate_task, tasks, executor=executor, n_jobs=n_jobs, desc=desc, progress=progress)
    models = [_unpack(d) for r in results for d in r]
    return BootstrapResult(nominal=nominal, models=models, seed=seed)
