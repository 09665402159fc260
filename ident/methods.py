"""The identification methods, one table (:data:`METHODS`) for ``rotorlab ident --method`` and the pipeline.

Each entry fits one model to a record ``u -> y`` sampled at ``dt`` (s) with a known input delay of ``delay``
samples, from named settings. Black-box methods return an :class:`~rotorlab.ident.model.IdentifiedModel`
(discrete, delay in whole samples); grey-box methods return a
:class:`~rotorlab.ident.greybox.GreyBoxResult` (continuous, delay in s). A new method is one function here
(or in its own module) plus its entry in :data:`METHODS`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from rotorlab.errors import UnknownNameError

from .arx import arx
from .greybox import GreyBoxModel, GreyBoxResult, oe_fit
from .hinf_match import HinfMatchResult, hinf_match
from .lms import kung, lms_batch
from .model import IdentifiedModel
from .subspace import moesp, pbsid

__all__ = ["Method", "METHODS", "get_method", "fit_pi_moesp", "fit_pbsid", "fit_lms_kung", "fit_arx", "fit_oe",
           "fit_hinf_match"]


def fit_pi_moesp(u, y, *, dt: float, delay: int, order: int, horizon: int) -> IdentifiedModel:
    """PI-MOESP: MOESP with past-input instruments (ref. 000), ``horizon`` block rows."""
    return moesp(u, y, order, horizon, dt=dt, delay=delay, instruments="u")


def fit_pbsid(u, y, *, dt: float, delay: int, order: int, past: int, future: int | None = None) -> IdentifiedModel:
    """PBSID with ``past``/``future`` windows (ref. 000)."""
    return pbsid(u, y, order, past, future, dt=dt, delay=delay)


def fit_lms_kung(u, y, *, dt: float, delay: int, order: int, taps: int) -> IdentifiedModel:
    """LMS impulse response of ``taps`` taps, realised by Kung's method at ``order``."""
    h, _ = lms_batch(u, y, taps, delay=delay)
    # the LMS weights start with the direct term (w[0] = h[0] = D), the first sample Kung's method reads: no
    # padding (a leading zero would add one sample of delay)
    return kung(h, order=order, dt=dt, delay=delay)


def fit_arx(u, y, *, dt: float, delay: int, order: int, nb: int | None = None) -> IdentifiedModel:
    """ARX with ``order`` poles and ``nb`` (default ``order``) numerator terms from lag ``delay``
    (:func:`rotorlab.ident.arx.arx`)."""
    return arx(u, y, order, order if nb is None else nb, dt=dt, delay=delay)


def fit_oe(u, y, *, dt: float, delay: int, structure: GreyBoxModel, restarts: int = 0, rng=None) -> GreyBoxResult:
    """Output-error fit of a grey-box ``structure`` with its delay fixed at ``delay`` samples."""
    if isinstance(structure.delay, str):
        structure = structure.replace(**{structure.delay: {"value": delay * dt, "fixed": True}})
    return oe_fit(structure, u, y, dt, estimate_x0=True, restarts=restarts, rng=rng)


def fit_hinf_match(u, y, *, dt: float, delay: int, structure: GreyBoxModel, order: int | None = None,
                   horizon: int | None = None, black_box: IdentifiedModel | None = None, restarts: int = 3,
                   rng=None) -> HinfMatchResult:
    """H-inf matching of a grey-box ``structure`` to a black-box model (ref. 000): ``black_box`` when given,
    else a PI-MOESP model of ``order`` and ``horizon`` fitted here."""
    if black_box is None:
        black_box = fit_pi_moesp(u, y, dt=dt, delay=delay, order=order, horizon=horizon)
    return hinf_match(black_box, structure, restarts=restarts, rng=rng)


@dataclasses.dataclass(frozen=True)
class Method:
    """An identification method: ``fit(u, y, dt=, delay=, **settings)``, the settings it takes, and whether
    it returns a grey-box result (continuous, with physical parameters)."""

    name: str
    fit: Callable
    settings: tuple[str, ...]
    greybox: bool
    description: str


METHODS: dict[str, Method] = {m.name: m for m in (
    Method("pi-moesp", fit_pi_moesp, ("order", "horizon"), False, "MOESP with past-input instruments"),
    Method("pbsid", fit_pbsid, ("order", "past", "future"), False, "predictor-based subspace identification"),
    Method("lms-kung", fit_lms_kung, ("order", "taps"), False, "LMS impulse response + Kung realisation"),
    Method("arx", fit_arx, ("order",), False, "ARX by linear least squares (equation error)"),
    Method("oe-greybox", fit_oe, ("structure",), True, "output-error fit of a grey-box structure"),
    Method("hinf-match", fit_hinf_match, ("structure", "order", "horizon"), True,
           "H-inf matching of a grey-box structure to a PI-MOESP model"),
)}


def get_method(name: str) -> Method:
    """The method called ``name`` (UnknownNameError listing the valid ones).

    Parameters
    ----------
    name : str
        A key of :data:`METHODS` (``rotorlab ident --method`` takes the same names).

    Returns
    -------
    Method
        Its entry: the fitting function and the settings it takes.

    Examples
    --------
    >>> from rotorlab import ident
    >>> m = ident.get_method("pbsid")
    >>> m.name
    'pbsid'
    >>> sorted(ident.METHODS)
    ['arx', 'hinf-match', 'lms-kung', 'oe-greybox', 'pbsid', 'pi-moesp']
    """
    if name not in METHODS:
        raise UnknownNameError("identification method", name, METHODS)
    return METHODS[name]
