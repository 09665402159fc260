"""Informative windows of a flight log: airborne, excited in the band that matters, or given by the user.

Every :class:`Window` carries the reason it was chosen, for the log report. The held-out part (the last
``holdout`` fraction of the candidate time: the autopilot's excitation windows when it logged any, else the
airborne time less :data:`GROUND_GUARD_S` at each end) is never searched for identification windows, so a model's VAF on it is an honest prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal as sig

from rotorlab.errors import DataError

from .flightlog import FlightLog, Interval, Record

__all__ = ["Window", "Split", "split_windows", "select_windows", "band_stats", "band_stats_many", "MIN_RMS",
           "GROUND_GUARD_S", "MIN_WINDOW_SAMPLES", "holdout_excitation"]

# The least excitation an input must carry in the band (RMS, its unit): 0.05 rad/s (3 deg/s) of rate set-point is
# above what a hovering attitude loop commands from sensor noise and well below a pilot's stick input.
MIN_RMS = {"rate_sp": 0.05}
# Seconds cut from each end of an airborne interval: take-off and touchdown are ground contact, not the flying
# plant, and the thrust threshold and land detectors that bound the interval lag them. On the real development logs
# the last second before a thrust-threshold landing holds the touchdown (gyro RMS 3x the set-point's).
GROUND_GUARD_S = 1.0
# The fewest samples of an automatic window: the direct fits need 100 (identify.MIN_SAMPLES: a 20-sample past and a
# 10-sample future leave too few block-Hankel rows below that), so a window of a slow log (4 s of a 21 Hz RATE
# message is 84 samples) is widened to this rather than chosen and then dropped by the fit
MIN_WINDOW_SAMPLES = 128


@dataclass(frozen=True)
class Window:
    """A time window ``[start_s, stop_s)`` with why it was chosen and its excitation figures.

    ``power`` is the input's mean power in the band (unit^2; for a held-out window the variance of the input with
    its linear trend removed, all of what the model is scored on), ``coherence`` the mean magnitude-squared
    coherence input -> output in the band (NaN where not computed, e.g. a user's window)."""

    start_s: float
    stop_s: float
    reason: str
    power: float = float("nan")
    coherence: float = float("nan")

    @property
    def duration_s(self) -> float:
        return self.stop_s - self.start_s


@dataclass(frozen=True)
class Split:
    """Identification windows and held-out windows of one record."""

    ident: list
    holdout: list


def band_stats(u, y, dt: float, band_hz) -> tuple[float, float]:
    """(input power in band, mean coherence u -> y in band) by Welch's method (``scipy.signal``), segments of
    about 1 s.

    Examples
    --------
    >>> u = np.random.default_rng(0).standard_normal(2000)
    >>> power, coherence = band_stats(u, 2 * u, 0.01, (0.5, 20.0))
    >>> round(coherence, 6)
    1.0
    """
    fs = 1.0 / dt
    nper = int(min(len(u), max(32, round(fs))))
    f, puu = sig.welch(u, fs=fs, nperseg=nper, detrend="linear")
    m = (f >= band_hz[0]) & (f <= band_hz[1])
    if not m.any():
        return 0.0, 0.0
    power = float(np.trapezoid(puu[m], f[m]))
    if not np.std(u) > 0 or not np.std(y) > 0:
        return power, 0.0
    _, cxy = sig.coherence(u, y, fs=fs, nperseg=nper, detrend="linear")
    return power, float(np.nanmean(cxy[m]))


def band_stats_many(U, Y, dt: float, band_hz) -> tuple[np.ndarray, np.ndarray]:
    """:func:`band_stats` of every row of ``U`` and ``Y`` (windows of one length) in one batched Welch pass: the
    per-window calls of a long log cost more in scipy's per-call overhead than in arithmetic.

    Examples
    --------
    >>> U = np.random.default_rng(0).standard_normal((3, 400))
    >>> p, c = band_stats_many(U, 2 * U, 0.01, (0.5, 20.0))
    >>> bool(np.allclose(p, [band_stats(u, 2 * u, 0.01, (0.5, 20.0))[0] for u in U]))
    True
    """
    U, Y = np.atleast_2d(U), np.atleast_2d(Y)
    fs = 1.0 / dt
    nper = int(min(U.shape[1], max(32, round(fs))))
    f, puu = sig.welch(U, fs=fs, nperseg=nper, detrend="linear", axis=-1)
    m = (f >= band_hz[0]) & (f <= band_hz[1])
    if not m.any():
        return np.zeros(len(U)), np.zeros(len(U))
    power = np.trapezoid(puu[:, m], f[m], axis=-1)
    live = (U.std(axis=1) > 0) & (Y.std(axis=1) > 0)
    coh = np.zeros(len(U))
    if live.any():
        with np.errstate(invalid="ignore", divide="ignore"):
            _, cxy = sig.coherence(U[live], Y[live], fs=fs, nperseg=nper, detrend="linear", axis=-1)
        coh[live] = np.nanmean(cxy[:, m], axis=-1)
    return power, coh


def _clip(intervals, start, stop):
    out = []
    for i in intervals:
        lo, hi = max(i.start_s, start), min(i.stop_s, stop)
        if hi > lo:
            out.append(Interval(lo, hi, i.label))
    return out


def _candidates(log: FlightLog, rec: Record) -> tuple[list, str]:
    if not log.airborne:
        how = log.airborne_source or "no land detector, thrust or armed signal in the log"
        raise DataError(f"{log.path}: no airborne time found ({how}); expected a flight, got a log on the ground")
    air = _clip(log.airborne, rec.t_s[0], rec.t_s[-1] + rec.dt)
    # the guard applies to the airborne time only: an autopilot excites only once flying
    guarded = [Interval(i.start_s + GROUND_GUARD_S, i.stop_s - GROUND_GUARD_S, i.label) for i in air
               if i.duration_s > 2 * GROUND_GUARD_S]
    if not guarded:
        raise DataError(f"{log.path}: the {rec.axis} signals do not overlap the airborne time by more than "
                        f"{2 * GROUND_GUARD_S:g} s ({', '.join(f'{i.start_s:.1f}-{i.stop_s:.1f} s' for i in log.airborne)})")
    exc = [i for i in log.excitation if i.label == rec.axis]
    exc_air = [j for i in exc for j in _clip(air, i.start_s, i.stop_s)]
    if exc_air:
        return exc_air, "autopilot excitation window (airborne)"
    return guarded, f"airborne (less {GROUND_GUARD_S:g} s of take-off and touchdown)"


def _same_interval(intervals, t0, t1) -> bool:
    return any(i.start_s <= t0 and t1 <= i.stop_s for i in intervals)


def split_windows(log: FlightLog, rec: Record, holdout: float = 0.4) -> tuple[list, list, str]:
    """(identification candidates, held-out intervals, kind): the last ``holdout`` fraction of the candidate
    time (excitation windows, else airborne) is held out, split on the time axis."""
    cands, kind = _candidates(log, rec)
    total = sum(i.duration_s for i in cands)
    t_cut, acc = None, 0.0
    for i in cands:
        if acc + i.duration_s >= (1 - holdout) * total:
            t_cut = i.start_s + (1 - holdout) * total - acc
            break
        acc += i.duration_s
    ident = [j for i in cands for j in _clip([i], i.start_s, t_cut)]
    held = [j for i in cands for j in _clip([i], t_cut, i.stop_s)]
    return ident, held, kind


def _held_window(iv, rec: Record, u_name: str, y_name: str, band, reason: str) -> Window:
    """A held-out window with its input's power (the variance of the window, linear trend removed) and the mean
    coherence in the band; NaN where under 32 samples. A VAF on held-out data that carries no input scores noise
    and disturbances, and the report says so. The power is not limited to the band: a model is
    scored on all of its input, and a slow axis (yaw, heading hold) lives below the band's low edge."""
    idx = np.flatnonzero((rec.t_s >= iv.start_s) & (rec.t_s < iv.stop_s))
    if len(idx) < 32:
        return Window(iv.start_s, iv.stop_s, reason)
    u, y = rec.data[u_name][idx], rec.data[y_name][idx]
    _, c = band_stats(u, y, rec.dt, band)
    # the record is resampled below the band's top already; Welch's ~1 s segments would drop what is slower
    return Window(iv.start_s, iv.stop_s, reason, float(np.var(sig.detrend(u))), c)


def holdout_excitation(split: Split) -> tuple[float, float]:
    """(input RMS, detrended, mean coherence in the band) over the held-out windows, weighted by
    their durations; NaN where no held-out window was long enough to measure.

    Examples
    --------
    >>> w = [Window(0.0, 10.0, "held out", power=0.04, coherence=0.5), Window(10.0, 40.0, "held out", 0.0, 0.1)]
    >>> rms, coh = holdout_excitation(Split([], w))
    >>> round(rms, 3), round(coh, 2)
    (0.1, 0.2)
    """
    ws = [w for w in split.holdout if np.isfinite(w.power)]
    if not ws:
        return float("nan"), float("nan")
    d = np.array([w.duration_s for w in ws])
    return (float(np.sqrt(np.average([w.power for w in ws], weights=d))),
            float(np.average([w.coherence for w in ws], weights=d)))


def log_excited(log: FlightLog, rec: Record) -> bool:
    """Whether the autopilot logged excitation windows for ``rec``'s axis (autotune, SYSID)."""
    return any(i.label == rec.axis for i in log.excitation)


def _whole_intervals(ident_iv, keep, rec: Record, u_name: str, band, min_power_fraction, min_coherence,
                     kind) -> list:
    """Each identification interval holding a kept window ``(a, b, power, coherence)``, whole, with the kept
    windows' mean power and coherence."""
    out = []
    for iv in ident_iv:
        inside = [(p, c) for a, b, p, c in keep if iv.start_s <= rec.t_s[a] and rec.t_s[b - 1] < iv.stop_s]
        if not inside:
            continue
        p, c = (float(np.mean(v)) for v in zip(*inside))
        out.append(Window(iv.start_s, iv.stop_s,
                          f"{kind}, pilot inputs: the whole interval before the held-out part ({len(inside)} "
                          f"windows with {u_name} power >= {min_power_fraction:.0%} of the best and coherence >= "
                          f"{min_coherence} in {band[0]:g}-{band[1]:.3g} Hz; mean power {p:.3g}, coherence {c:.2f})",
                          p, c))
    return out


def select_windows(log: FlightLog, rec: Record, u_name: str, y_name: str, *, band_hz=(0.3, 15.0),
                   window_s: float = 4.0, min_coherence: float = 0.3, min_power_fraction: float = 0.01,
                   min_rms=None,
                   holdout: float = 0.4, override=None) -> Split:
    """Identification and held-out windows of ``rec`` for the pair ``u_name -> y_name``.

    Automatic: the identification part of the candidate time (see :func:`split_windows`) is cut into windows
    of ``window_s`` (half overlapping); a window is kept when the input's power in ``band_hz`` is at least
    ``min_power_fraction`` of the best window's and the mean coherence in the band is at least
    ``min_coherence`` and, where ``min_rms`` gives one for the input (default :data:`MIN_RMS`), the input's RMS in
    the band reaches it; kept windows less than ``window_s`` apart within one candidate interval are merged.
    A window holds at least :data:`MIN_WINDOW_SAMPLES` samples (``window_s`` widened on a slow log).
    Without autopilot excitation windows (pilot inputs over the airborne time) the windows only decide whether an
    airborne interval is excited: each interval with a kept window is one identification window, its whole
    identification part, since a pilot's inputs come in bursts across the flight and the direct fits need the
    longest stretches of continuous data, not the bursts cut apart.
    The held-out part is returned whole, one window per candidate interval. ``override``: a list of
    ``(start_s, stop_s)`` used as identification windows instead (the held-out part stays the same; a window
    reaching into it is refused).

    Raises
    ------
    DataError
        No airborne time, or no window with excitation in the band.

    Examples
    --------
    >>> split = select_windows(log, log.record("roll", ("rate_sp", "rate")), "rate_sp", "rate")  # doctest: +SKIP
    >>> [w.reason for w in split.ident]  # doctest: +SKIP
    """
    band = (band_hz[0], min(band_hz[1], 0.4 / rec.dt))
    ident_iv, held_iv, kind = split_windows(log, rec, holdout)
    u, y = rec.data[u_name], rec.data[y_name]
    held = [_held_window(i, rec, u_name, y_name, band, f"held out: last {holdout:.0%} of the {kind} time")
            for i in held_iv]
    if override:
        for a, b in override:
            for h in held:
                if a < h.stop_s and h.start_s < b:
                    raise DataError(f"{log.path}: the window {a:g}-{b:g} s overlaps the held-out part "
                                    f"{h.start_s:.2f}-{h.stop_s:.2f} s of the {rec.axis} axis; expected windows "
                                    f"before it (or a smaller --holdout)")
        return Split([Window(float(a), float(b), "given by the user") for a, b in override], held)
    n_win = max(int(round(window_s / rec.dt)), MIN_WINDOW_SAMPLES)
    cands = []
    for iv in ident_iv:
        idx = np.flatnonzero((rec.t_s >= iv.start_s) & (rec.t_s < iv.stop_s))
        if len(idx) < n_win:
            if len(idx) >= 32:  # scored for the report; identify_direct drops what is too short to fit
                cands.append((idx[0], idx[-1] + 1))
            continue
        starts = list(range(idx[0], idx[-1] + 2 - n_win, n_win // 2))
        cands += [(s, s + n_win) for s in starts]
    if not cands:
        raise DataError(f"{log.path}: the {rec.axis} axis has no {kind} stretch of {window_s:g} s before the held-out "
                        f"part; expected a longer flight")
    stats = [None] * len(cands)
    full = [i for i, (a, b) in enumerate(cands) if b - a == n_win]
    if full:
        ix = np.array([cands[i][0] for i in full])[:, None] + np.arange(n_win)
        ps, cs = band_stats_many(u[ix], y[ix], rec.dt, band)
        for i, p, c in zip(full, ps, cs):
            stats[i] = (float(p), float(c))
    for i, (a, b) in enumerate(cands):
        if stats[i] is None:
            stats[i] = band_stats(u[a:b], y[a:b], rec.dt, band)
    pmax = max(p for p, _ in stats)
    floor = (MIN_RMS if min_rms is None else min_rms).get(u_name, 0.0) ** 2
    keep = [(a, b, p, c) for (a, b), (p, c) in zip(cands, stats)
            if pmax > 0 and p >= max(min_power_fraction * pmax, floor) and c >= min_coherence]
    if not keep:
        best = max(stats, key=lambda s: s[1])
        raise DataError(f"{log.path}: no excitation on the {rec.axis} axis: no {window_s:g} s window of {u_name} -> "
                        f"{y_name} with coherence >= {min_coherence} and RMS >= {floor ** 0.5:g} in {band[0]:g}-"
                        f"{band[1]:.3g} Hz (best coherence {best[1]:.2f}, at RMS {best[0] ** 0.5:.3g}); fly stick inputs "
                        "or an autotune/SYSID excitation, or give --window")
    if not log_excited(log, rec):
        return Split(_whole_intervals(ident_iv, keep, rec, u_name, band, min_power_fraction, min_coherence, kind),
                     held)
    # kept windows closer than one window length are bridged: a short lull between stick inputs costs less
    # than cutting the record the subspace fit needs in two
    merged = []
    for a, b, p, c in keep:
        if merged and a <= merged[-1][1] + n_win and _same_interval(ident_iv, rec.t_s[merged[-1][0]], rec.t_s[b - 1]):
            m = merged[-1]
            merged[-1] = (m[0], b, m[2] + [p], m[3] + [c])
        else:
            merged.append((a, b, [p], [c]))
    out = []
    for a, b, ps, cs in merged:
        p, c = float(np.mean(ps)), float(np.mean(cs))
        out.append(Window(float(rec.t_s[a]), float(rec.t_s[b - 1] + rec.dt),
                          f"{kind}; {u_name} power {p:.3g} in {band[0]:g}-{band[1]:.3g} Hz "
                          f"(>= {min_power_fraction:.0%} of the best window), coherence {c:.2f} >= {min_coherence}",
                          p, c))
    return Split(out, held)
