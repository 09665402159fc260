"""Stage 3, bootstrap: parametric bootstrap of the PBSID model and the additive-uncertainty weight
``W_delta`` bounding its spread (ref. 000)."""

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
    """``n`` log-spaced frequencies (rad/s) from 0.1 rad/s to 90 % of the 50 Hz Nyquist frequency."""
    return np.logspace(-1, math.log10(0.9 * math.pi / DT_S), n)


def run(ctx: StageContext) -> dict:
    ident = ctx.run.result("identify")
    if "pbsid" not in ident["models"]:
        raise PipelineError("the bootstrap needs the PBSID model: " + ident["skipped"].get("pbsid", "missing"))
    st = ident["models"]["pbsid"]["settings"]
    log = ctx.run.experiment_log("id")
    identify = functools.partial(pbsid, order=st["order"], past=st["past"], future=st.get("future"), dt=DT_S,
                                 delay=st["delay"])
    br = bootstrap(log["u_lon"], log["q"], identify, n_boot=ctx.settings["n_boot"], seed=ctx.seed,
                   n_jobs=ctx.executor.workers, progress=ctx.opts.progress)
    w = bode_grid(N_BODE)
    W = fit_wdelta(br.nominal.sys, [m.sys for m in br.models], w, order=W_DELTA_ORDER)
    save_model(ctx.work / "w_delta.json", W, input=["delta"], output=["q"])
    band = br.band(w, BAND_LEVEL)
    stack = {k: np.stack([np.asarray(getattr(m.sys, k), float) for m in br.models]) for k in "ABCD"}
    np.savez(ctx.work / "replicas.npz", w_rad_s=w, mag_lo=band["mag_lo"][:, 0, 0], mag_hi=band["mag_hi"][:, 0, 0],
             phase_lo=band["phase_lo"][:, 0, 0], phase_hi=band["phase_hi"][:, 0, 0],
             spread=additive_spread(br.nominal.sys, [m.sys for m in br.models], w),
             poles_c=br.poles_continuous(), **stack)
    Wmag = np.abs(freqresp(W, w)[:, 0, 0])
    return {"model": "pbsid", "n_boot": ctx.settings["n_boot"], "order": int(st["order"]),
            "w_delta_order": int(W.nstates), "w_delta_peak": float(Wmag.max()), "w_delta_dc": float(Wmag[0]),
            "poles_c_median": [[float(z.real), float(z.imag)] for z in np.median(br.poles_continuous().real, 0)
                               + 1j * np.median(np.abs(br.poles_continuous().imag), 0)]}


STAGE = Stage("bootstrap", upstream=("experiments", "identify"), settings=("n_boot",), run=run)
