"""The log report: an HTML page with PNG figures a PX4 Flight Review or PlotJuggler user finds familiar: modes,
armed and airborne over time, set-point vs rate per axis with the windows, excitation spectra and coherence, each
model's prediction of the held-out windows."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
from scipy import signal as sig

from rotorlab.atomic import atomic_path, write_text

from .windows import holdout_excitation

__all__ = ["write_report", "plot_points", "PLOT_POINTS"]

# Points per trace in a time plot: a 1000-pixel-wide figure shows no more; a 1 kHz gyro over ten minutes is 600 000
PLOT_POINTS = 4000
COLORS = {"ident": "#2ca02c", "holdout": "#ff7f0e", "excitation": "#9467bd", "airborne": "#1f77b4"}


def _savefig(fig, path: Path) -> Path:
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    return path


def plot_points(t_s, x, max_points: int = PLOT_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(t_s, x)`` thinned for a time plot to at most about ``max_points`` points: the minimum and the maximum of
    each of ``max_points // 2`` equal runs of samples, in time order; a series that short already is returned as is.

    Written here because plain decimation (every n-th sample, or ``scipy.signal.decimate``'s low-pass) drops or
    smooths the spikes and saturations a log review looks for; the min/max envelope keeps every extreme.

    Examples
    --------
    >>> t = np.arange(100_000) * 1e-3
    >>> x = np.zeros_like(t); x[51_234] = 5.0
    >>> tp, xp = plot_points(t, x, 1000)
    >>> len(tp) <= 1000, float(xp.max()), float(tp[np.argmax(xp)])
    (True, 5.0, 51.234)
    """
    t_s, x = np.asarray(t_s), np.asarray(x)
    if len(x) <= max_points:
        return t_s, x
    n_bins = max(1, max_points // 2)
    edges = np.linspace(0, len(x), n_bins + 1).astype(int)
    i_lo = np.array([a + int(np.argmin(x[a:b])) for a, b in zip(edges[:-1], edges[1:])])
    i_hi = np.array([a + int(np.argmax(x[a:b])) for a, b in zip(edges[:-1], edges[1:])])
    idx = np.sort(np.concatenate([i_lo, i_hi]))
    return t_s[idx], x[idx]


def _timeline(res, out: Path) -> Path:
    import matplotlib.pyplot as plt

    log = res.log
    fig, ax = plt.subplots(figsize=(10, 2.4), constrained_layout=True)
    rows = [("mode", log.modes), ("armed", log.armed), ("airborne", log.airborne), ("excitation", log.excitation)]
    cmap = plt.get_cmap("tab10")
    labels = sorted({i.label for i in log.modes})
    for y, (name, ivs) in enumerate(rows):
        for i in ivs:
            c = cmap(labels.index(i.label) % 10) if name == "mode" else COLORS.get(name, "gray")
            ax.broken_barh([(i.start_s, i.duration_s)], (y - 0.4, 0.8), color=c, alpha=0.7)
            if name in ("mode", "excitation"):
                ax.text(i.start_s, y, i.label, va="center", fontsize=7)
    ax.set_yticks(range(len(rows)), [r[0] for r in rows])
    ax.set_xlabel("time (s)")
    ax.set_title(f"{Path(log.path).name}: modes, armed, airborne, excitation")
    p = _savefig(fig, out / "timeline.png")
    plt.close(fig)
    return p


def _axis_figs(res, axis, out: Path) -> list[Path]:
    import matplotlib.pyplot as plt

    log, models = res.log, res.models[axis]
    cl = models["closed-loop"]
    sp, r = log.series(axis, "rate_sp"), log.series(axis, "rate")
    files = []
    fig, ax = plt.subplots(figsize=(10, 3), constrained_layout=True)
    ax.plot(*plot_points(r.t_s, r.values), lw=0.6, label=f"rate ({r.source})")
    ax.plot(*plot_points(sp.t_s, sp.values), lw=0.8, label=f"rate set-point ({sp.source})")
    for w in cl.split.ident:
        ax.axvspan(w.start_s, w.stop_s, color=COLORS["ident"], alpha=0.15)
    for w in cl.split.holdout:
        ax.axvspan(w.start_s, w.stop_s, color=COLORS["holdout"], alpha=0.15)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("rad/s")
    ax.set_title(f"{axis}: set-point vs rate (green: identification windows, orange: held out)")
    ax.legend(fontsize=7, loc="upper right")
    files.append(_savefig(fig, out / f"{axis}-rates.png"))
    plt.close(fig)
    # excitation spectra and coherence over the identification windows
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3), constrained_layout=True)
    for kind, m in models.items():
        if kind.startswith("plant-indirect"):
            continue
        rec = log.record(axis, (m.input, m.output))
        idx = np.concatenate([np.flatnonzero((rec.t_s >= w.start_s) & (rec.t_s < w.stop_s)) for w in m.split.ident])
        u, y = rec.data[m.input][idx], rec.data[m.output][idx]
        nper = int(min(len(u), max(64, round(2 / rec.dt))))
        f, puu = sig.welch(u, fs=1 / rec.dt, nperseg=nper)
        _, coh = sig.coherence(u, y, fs=1 / rec.dt, nperseg=nper)
        a1.loglog(f[1:], puu[1:], label=f"{m.input}")
        a2.semilogx(f[1:], coh[1:], label=f"{m.input} -> {m.output}")
    a1.set_xlabel("Hz")
    a1.set_title(f"{axis}: excitation spectrum")
    a1.legend(fontsize=7)
    a2.set_xlabel("Hz")
    a2.set_ylim(0, 1.05)
    a2.set_title("coherence")
    a2.legend(fontsize=7)
    files.append(_savefig(fig, out / f"{axis}-spectra.png"))
    plt.close(fig)
    # each model's prediction of the held-out windows
    fig, axs = plt.subplots(len(models), 1, figsize=(10, 2.4 * len(models)), constrained_layout=True, squeeze=False)
    for a, (kind, m) in zip(axs[:, 0], models.items()):
        for k, (t, y, yh) in enumerate(m.prediction):
            a.plot(*plot_points(t, y), color="k", lw=0.6, label="measured" if k == 0 else None)
            a.plot(*plot_points(t, yh), color=COLORS["holdout"], lw=0.8, label="model" if k == 0 else None)
        a.set_title(f"{axis} {kind}: held-out prediction, VAF {m.vaf_holdout:.1f} %", fontsize=9)
        a.legend(fontsize=7, loc="upper right")
    axs[-1, 0].set_xlabel("time (s)")
    files.append(_savefig(fig, out / f"{axis}-fit.png"))
    plt.close(fig)
    return files


def write_report(res, out: Path) -> list[Path]:
    """Write ``report.html`` and its PNGs into ``out``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    log = res.log
    files = [_timeline(res, out)]
    for axis in res.models:
        files += _axis_figs(res, axis, out)
    e = html.escape
    rows = []
    for axis, models in res.models.items():
        for kind, m in models.items():
            wins = "<br>".join(f"{w.start_s:.2f}-{w.stop_s:.2f} s: {e(w.reason)}" for w in m.split.ident)
            held = ", ".join(f"{w.start_s:.2f}-{w.stop_s:.2f} s" for w in m.split.holdout)
            rms, coh = holdout_excitation(m.split)
            if np.isfinite(rms):
                # the plant through the controller is scored on its closed loop's windows and input
                u_name = {"plant-indirect": "rate_sp", "plant-indirect-angle": "att_sp"}.get(kind, m.input)
                held += f"<br>{u_name} RMS {rms:.3g} (detrended), coherence {coh:.2f} in the band"
            params = ", ".join(f"{k} = {v:.4g}" for k, v in m.extra.get("params", {}).items())
            desc = f"{e(m.model.method)} {e(str({k: v for k, v in m.model.settings.items() if k != 'dt'}))}"
            rows.append(f"<tr><td>{axis}</td><td>{kind}</td><td>{m.input} ({m.units.get(m.input, '')}) -> "
                        f"{m.output} ({m.units.get(m.output, '')})</td><td>{1 / m.dt:.4g} Hz</td><td>{desc}"
                        f"{'<br>' + e(params) if params else ''}</td><td>{m.vaf_holdout:.1f} %</td>"
                        f"<td>{wins}</td><td>{held}</td></tr>")
    imgs = "".join(f'<p><img src="{p.name}" alt="{p.stem}"></p>' for p in files)
    notes = "".join(f"<li>{e(n)}</li>" for n in log.notes + res.notes)
    sources = "".join(f"<li>{a} {k}: {e(s.source)} at {s.rate_hz:.4g} Hz, {e(s.unit)}</li>"
                      for a in res.models for k, s in log.signals[a].items())
    page = f"""<!DOCTYPE html><html><head><meta charset="utf-8"><title>rotorlab log report: {e(Path(log.path).name)}</title>
<style>body{{font-family:sans-serif;margin:1.5em}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;
padding:4px;font-size:12px;vertical-align:top}}</style></head><body>
<h1>{e(Path(log.path).name)}</h1>
<p>{e(log.autopilot)} {e(log.version)} ({e(log.format)}); airborne {log.airborne_time_s():.1f} s
({e(log.airborne_source)}); {len(log.params)} parameters. Units: rates rad/s, angles rad, rate-loop output
normalised (1); time in s.</p>
<h2>Models (VAF: free-run prediction of the held-out windows)</h2>
<table><tr><th>axis</th><th>model</th><th>signals</th><th>rate</th><th>method</th><th>VAF held out</th>
<th>identification windows and why</th><th>held out</th></tr>{''.join(rows)}</table>
<h2>Notes</h2><ul>{notes or '<li>none</li>'}</ul>
<h2>Signals</h2><ul>{sources}</ul>
<h2>Figures</h2>{imgs}</body></html>
"""
    return files + [write_text(out / "report.html", page)]
