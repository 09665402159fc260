"""Conversions between the run folder's model and gain files and the libraries' objects at the 50 Hz
flight-software rate."""

from __future__ import annotations

import math
from pathlib import Path

import control as ct

from rotorlab.ident.model import IdentifiedModel
from rotorlab.ident.modelio import load_model
from rotorlab.lti import c2d_zoh_delay, is_discrete, negative_real_poles, with_io_delay
from rotorlab.pipeline.settings import DT_S
from rotorlab.tune.cascade import PlantModel

__all__ = ["discrete_model", "load_identified", "load_plant", "mc_plant", "zoh_invertible", "gains_table"]


def zoh_invertible(model) -> bool:
    """Whether a discrete model has a ZOH continuous equivalent (no pole on the negative real axis)."""
    return negative_real_poles(model.sys).size == 0


def discrete_model(sys_c, delay_s: float, method: str, settings: dict) -> IdentifiedModel:
    """IdentifiedModel of a continuous grey-box result at 50 Hz: exact ZOH with the fractional part of the
    delay (s) inside ``sys`` (:func:`rotorlab.lti.c2d_zoh_delay`) and the whole samples as ``delay``."""
    # minimal first: a grey-box structure may carry states its measured output does not see (TUHH: the
    # angle state behind a rate output), which would sit as hidden poles at z = 1 in every closed loop
    sys_c = ct.minreal(sys_c, verbose=False)
    d = int(math.floor(delay_s / DT_S + 1e-9))
    return IdentifiedModel(sys=c2d_zoh_delay(sys_c, DT_S, delay_s - d * DT_S), delay=d, method=method,
                           settings=settings)


def load_identified(path) -> IdentifiedModel:
    """IdentifiedModel at 50 Hz from a model JSON: a discrete model as stored (delay in whole samples), a
    continuous grey-box model through its exact ZOH image (:func:`discrete_model`)."""
    sys, delay_s, meta = load_model(path)
    method, settings = str(meta.get("method", "")), meta.get("settings", {})
    if not is_discrete(sys):
        return discrete_model(sys, delay_s, method, settings)
    return IdentifiedModel(sys=sys, delay=int(round(delay_s / DT_S)), method=method, settings=settings)


def load_plant(path, name: str | None = None) -> PlantModel:
    """:class:`rotorlab.tune.PlantModel` of a model JSON for the tuning library. A continuous model whose
    delay is not a whole number of 50 Hz samples (TUHH: 0.028 s) keeps the whole samples as ``delay_s`` and
    the fraction as a 2nd-order Pade factor in ``G``: ``rotorlab.tune.cascade_plant`` appends discrete delays
    only as whole samples."""
    sys, delay_s, _ = load_model(path)
    name = name or Path(path).stem
    if not is_discrete(sys):
        sys = ct.minreal(sys, verbose=False)  # see discrete_model
    d = int(math.floor(delay_s / DT_S + 1e-9))
    frac_s = delay_s - d * DT_S
    if is_discrete(sys) or frac_s < 1e-9:
        return PlantModel(sys, delay_s, name)
    return PlantModel(with_io_delay(sys, frac_s, pade_order=2), d * DT_S, name)


def mc_plant(m: IdentifiedModel) -> PlantModel:
    """The tuning library's PlantModel of a 50 Hz identified model (delay in whole samples -> s)."""
    return PlantModel(m.sys, m.delay * DT_S, m.method)


def gains_table(gs) -> dict:
    """A gain set as plain nested dicts ``{axis: {"outer": {...}, "inner": {...}}}`` (JSON, task payloads)."""
    return {ax: {"outer": g.outer.as_dict(), "inner": g.inner.as_dict()} for ax, g in gs.axes.items()}
