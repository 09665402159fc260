"""Stage 3, bootstrap: parametric bootstrap of the PBSID model and the additive-uncertainty weight
``W_delta`` bounding its spread (ref. 000); the same for the in-flight PBSID model when the campaign has a
flight run, so the in-flight h_lim uses the flight model's own uncertainty, and for the second-order test-bed
PBSID model it is compared with (ref. 000 pairs the two second-order models)."""

from __future__ import annotations

import functools
import math

import numpy as np

from rotorlab.ident.bootstrap import bootstrap
from rotorlab.ident.modelio import save_model
from rotorlab.ident.subspace import pbsid
from rotorlab.lti import freqresp
from rotorlab.pipeline.runfolder import Stage, StageContext
from rotorlab.pipeline.settings import DT_S, PipelineError
from rotorlab.tune.robust import additive_spread, fit_wdelta

__all__ = ["STAGE", "bode_grid"]

W_DELTA_ORDER = 3
N_BODE = 120  # frequencies of the W_delta fit and the stored band
BAND_LEVEL = 0.95


def bode_grid(n: int = 200) -> np.ndarray:
    """``n`` log-spaced frequencies (rad/s) from 0.1 rad/s to the 50 Hz Nyquist frequency (h_lim takes the
    norm over the whole band, so W_delta must bound the spread up to Nyquist)."""
    return np.logspace(-1, math.log10(math.pi / DT_S), n)


def _identify(settings: dict):
    """PBSID with the stored settings of an identified model (picklable for the workers)."""
    return functools.partial(pbsid, order=settings["order"], past=settings["past"], future=settings.get("future"),
                             dt=DT_S, delay=settings["delay"])


def run(ctx: StageContext) -> dict:
    ident = ctx.run.result("identify")
    if "pbsid" not in ident["models"]:
        raise PipelineError("the bootstrap needs the PBSID model: " + ident["skipped"].get("pbsid", "missing"))
    st = ident["models"]["pbsid"]["settings"]
    w = bode_grid(N_BODE)
    id_log = ctx.run.experiment_log("id")
    br, W, Wmag, spread = _bootstrap_wdelta(ctx, id_log, st, ctx.seed, w, "testbed", "bootstrap")
    flight = _own(ctx, w, "pbsid-flight", "flight", "flight", 1)
    pair = _own(ctx, w, "pbsid-testbed-n2", "id", "testbed-n2", 2, log=id_log)
    band = br.band(w, BAND_LEVEL)
    poles_c = br.poles_continuous()
    stack = {k: np.stack([np.asarray(getattr(m.sys, k), float) for m in br.models]) for k in "ABCD"}
    np.savez(ctx.work / "replicas.npz", w_rad_s=w, mag_lo=band["mag_lo"][:, 0, 0], mag_hi=band["mag_hi"][:, 0, 0],
             phase_lo=band["phase_lo"][:, 0, 0], phase_hi=band["phase_hi"][:, 0, 0],
             spread=spread, poles_c=poles_c, **stack)
    return {"model": "pbsid", "n_boot": ctx.settings["n_boot"], "order": int(st["order"]),
            "w_delta_order": int(W.nstates), "w_delta_peak": float(Wmag.max()), "w_delta_dc": float(Wmag[0]),
            "poles_c_median": [[float(z.real), float(z.imag)] for z in np.median(poles_c.real, 0)
                               + 1j * np.median(np.abs(poles_c.imag), 0)],
            **({"flight": flight} if flight else {}), **({"testbed_n2": pair} if pair else {})}


def _own(ctx: StageContext, w, model: str, log_name: str, which: str, stream: int, log=None) -> dict | None:
    """Bootstrap of a further PBSID model of the identify stage on its own record, with the settings it was
    identified with, and its ``W_delta`` (``w_delta-{which}.json``): the in-flight model on the flight record
    (ref. 000 gives in-flight h_lim from the flight model's uncertainty, not the test-bed's) and the second-order
    test-bed model it is paired with (``log``: the record when the caller has read it already). None when the
    identify stage has no such model."""
    if not ctx.run.model_path(model).exists() or not ctx.run.experiment_log_path(log_name).exists():
        return None
    st = ctx.run.identified(model).settings
    # an independent seed stream: these innovations share nothing with the nominal bootstrap's
    seed = int(np.random.SeedSequence([ctx.seed, stream]).generate_state(1)[0])
    _, _, Wmag, spread = _bootstrap_wdelta(ctx, ctx.run.experiment_log(log_name) if log is None else log, st, seed,
                                           w, which, f"{which} bootstrap")
    np.savez(ctx.work / f"replicas-{which}.npz", w_rad_s=w, spread=spread)
    return {"model": model, "order": int(st["order"]), "w_delta_peak": float(Wmag.max()),
            "w_delta_dc": float(Wmag[0])}


def _bootstrap_wdelta(ctx: StageContext, log, settings: dict, seed: int, w, which: str, desc: str):
    """Bootstrap of the PBSID model with ``settings`` on ``log`` (u_lon -> q) and its ``W_delta``, saved where
    :meth:`RunFolder.w_delta_path` reads it. Returns the bootstrap, ``W_delta``, ``|W_delta|`` and the
    replicas' additive spread on ``w``."""
    br = bootstrap(log["u_lon"], log["q"], _identify(settings), n_boot=ctx.settings["n_boot"], seed=seed,
                   executor=ctx.executor, desc=desc, progress=ctx.opts.progress)
    replicas = [m.sys for m in br.models]
    W = fit_wdelta(br.nominal.sys, replicas, w, order=W_DELTA_ORDER)
    save_model(ctx.work / ctx.run.w_delta_path(which).name, W, input=["delta"], output=["q"])
    return br, W, np.abs(freqresp(W, w)[:, 0, 0]), additive_spread(br.nominal.sys, replicas, w)


STAGE = Stage("bootstrap", upstream=("experiments", "identify"), settings=("n_boot",), run=run)
