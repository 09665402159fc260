"""Figures people read: one style for the CLI's ``plot``/``bode``/``compare`` and the pipeline report.

Every figure is drawn headless (matplotlib's Agg backend), at least 1100 px wide, with a grid on every axes
and every axis labelled with its quantity and unit; files are written atomically. The same functions back
``rotorlab plot RUN``, ``rotorlab compare RUN1 RUN2`` (time histories of runs, with their set-points and the
in-flight gain switch marked) and ``rotorlab bode MODEL...`` (magnitude in dB and phase in deg against
frequency in rad/s, input delay included).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from rotorlab import atomic
from rotorlab.config import check_input_file, read_json_object
from rotorlab.errors import DataError
from rotorlab.logformat import decode_metadata

# matplotlib is imported by pyplot() on the first figure: a heavy import, and the Agg backend must be chosen
# before pyplot loads. rotorlab.lti (python-control, about 1.7 s) is imported by plot_bode alone: `rotorlab plot`
# and `rotorlab compare` draw logs and do not need it.

__all__ = ["FIG_WIDTH_IN", "DPI", "pyplot", "figure", "save", "read_run", "run_panels", "plot_runs", "plot_bode",
           "label"]

#: 11 in at 100 dpi: 1100 px, legible in a report and on a screen
FIG_WIDTH_IN = 11.0
DPI = 100

#: per-axis channels (angle, set-point, rate, rate set-point, command) in the log's column names
_AXES = {"pitch": ("theta", "theta_ref", "q", "q_ref", "u_lon"), "roll": ("phi", "phi_ref", "p", "p_ref", "u_lat")}


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: dash pattern of the i-th run in :func:`plot_runs` (solid first)
RUN_DASHES = ("-", (0, (5, 2)), (0, (2, 1.5)), (0, (6, 2, 1.5, 2)))


def figure(nrows: int = 1, ncols: int = 1, height_in: float = 4.0, **kw):
    """A figure of :data:`FIG_WIDTH_IN` with constrained layout (no clipped labels) and gridded axes."""
    plt = pyplot()
    fig, axs = plt.subplots(nrows, ncols, figsize=(FIG_WIDTH_IN, height_in), layout="constrained", squeeze=False,
                            **kw)
    for ax in axs.flat:
        ax.grid(True, which="major", alpha=0.45)
        ax.grid(True, which="minor", alpha=0.15)
    return fig, axs


def save(fig, path) -> Path:
    """Write ``fig`` as PNG atomically (no timestamp metadata: the same data give the same bytes)."""
    path = Path(path)
    with atomic.atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=DPI, format="png", metadata={"Software": None})
    pyplot().close(fig)
    return path


def legend_outside(ax, **kw):
    """The legend of ``ax`` right of its axes, never over the data (constrained layout makes room for it)."""
    return ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kw)


def label(name: str, unit: str) -> str:
    """``"name [unit]"`` (``"name [-]"`` for a dimensionless quantity)."""
    return f"{name} [{unit or '-'}]"


def read_run(path) -> dict:
    """A run folder (or its ``log.parquet``): ``{"columns", "units", "info", "name"}``.

    Raises
    ------
    rotorlab.errors.DataError
        No log, or not a rotorlab Parquet log.
    """
    p = Path(path)
    log = p / "log.parquet" if p.is_dir() else p
    if not log.is_file():
        raise DataError(f"{p}: no run log (expected a run folder with log.parquet, as rotorlab run --out writes)")
    check_input_file(log, "run log")  # a FIFO or a device would block or never end
    atomic.note_input(log)
    try:
        tbl = pq.read_table(log)
    except Exception as exc:  # noqa: BLE001 - pyarrow raises several types for a file that is not Parquet
        raise DataError(f"{log}: not a readable Parquet log ({exc})") from None
    units, meta = decode_metadata(tbl.schema.metadata)
    info_path = log.parent / "run.json"
    info = read_json_object(info_path, "run record") if info_path.exists() else dict(meta or {})
    cols = {c: tbl.column(c).to_numpy().astype(float) for c in tbl.column_names}
    if "t" not in cols:
        raise DataError(f"{log}: no time column 't'")
    return {"columns": cols, "units": units or {}, "info": info, "name": log.parent.name if p.is_dir() else p.stem}


def _moved(y) -> bool:
    y = y[np.isfinite(y)]
    return y.size > 0 and float(np.ptp(y)) > 1e-6


def run_panels(runs, signals=None) -> list[list[str]]:
    """Panels to draw for ``runs``: ``signals`` (one panel each; ``a+b`` shares a panel) or, by default, the
    angle with its set-point, the rate with its set-point and the command of each axis that moved, then the
    position error (free flight), the wind and the rope tension where logged."""
    if signals:
        return [s.split("+") for s in signals]
    cols = runs[0]["columns"]
    scene = runs[0]["info"].get("scene", "")
    # a rig moves one axis (the other only shows sensor noise); free flight moves both
    axes = {"pitch-rig": ("pitch",), "roll-rig": ("roll",)}.get(scene, tuple(_AXES))
    panels = []
    for axis in axes:
        angle, ref, rate, rate_ref, cmd = _AXES[axis]
        if angle in cols and any(_moved(r["columns"].get(angle, np.zeros(1))) for r in runs):
            panels += [[angle, ref], [rate, rate_ref], [cmd]]
    for group in (["x", "x_ref"], ["z", "z_ref"], ["wind_u", "wind_v", "wind_w"], ["rope_tension"],
                  ["thrust"], ["torque"]):
        present = [c for c in group if c in cols]
        if present and any(_moved(r["columns"][present[0]]) for r in runs):
            panels.append(present)
    if not panels:  # a scenario with other signals: the first few that move
        panels = [[c] for c in cols if c != "t" and _moved(cols[c])][:4]
    return panels


def plot_runs(runs, path, signals=None, title: str | None = None) -> Path:
    """Time histories of one or several runs (one colour each), one panel per quantity, set-points dashed
    black, the in-flight gain switch marked by a vertical line; x in s, y with units."""
    panels = run_panels(runs, signals)
    for panel in panels:
        for c in panel:
            if not any(c in r["columns"] for r in runs):
                valid = sorted(k for k in runs[0]["columns"] if k != "t")
                raise DataError(f"no signal '{c}' in the run log(s); signals: {', '.join(valid)}")
    fig, axs = figure(len(panels), 1, height_in=1.2 + 2.0 * len(panels), sharex=True)
    axs = axs[:, 0]
    n = len(runs)
    for i, run in enumerate(runs):
        # runs that nearly coincide (two optimal gain sets) must both stay visible: each later run is drawn
        # thinner, on top, with its own dash pattern, so a trace under another still shows at its edges
        dash = RUN_DASHES[i % len(RUN_DASHES)]
        width = 2.4 - 1.4 * i / max(n - 1, 1) if n > 1 else 1.1
        cols = run["columns"]
        t = cols["t"]
        lab = run.get("label") or run["name"]
        for ax, panel in zip(axs, panels):
            for j, c in enumerate(panel):
                if c not in cols:
                    continue
                is_ref = c.endswith("_ref")
                # a signal every run shares (a set-point, the common-random-number wind) is drawn once
                shared = len(runs) > 1 and all(np.array_equal(cols[c], r["columns"].get(c)) for r in runs)
                if shared and i > 0:
                    continue
                if is_ref:
                    style = dict(color="k" if shared or len(runs) == 1 else f"C{i % 10}", ls="--", lw=1.0)
                elif shared:
                    style = dict(color="0.35", lw=1.1)
                else:
                    style = dict(color=f"C{(i + j) % 10}", lw=width, ls=dash, zorder=2 + i)
                name = c + (" (all runs)" if shared else "") if len(runs) == 1 or shared else f"{c}: {lab}"
                ax.plot(t, cols[c], label=name, **style)
        notes = run["info"].get("notes") or {}
        sw = notes.get("switch_s")
        # runs that all switch at one time share one line (coloured lines on the same x would hide each other)
        shared_switch = len(runs) > 1 and all(((r["info"].get("notes") or {}).get("switch_s")) == sw for r in runs)
        if sw is not None and not (shared_switch and i > 0):
            to = notes.get("switch_to") or "the switched set"
            tos = ", ".join(dict.fromkeys(str((r["info"].get("notes") or {}).get("switch_to")) for r in runs))
            text = (f"gain switch at {sw:g} s, each run to its set ({tos})" if shared_switch else
                    f"gain switch to {to} at {sw:g} s" + (f" ({lab})" if len(runs) > 1 else ""))
            for ax in axs:
                ax.axvline(sw, color="k" if shared_switch else f"C{i % 10}", ls=":", lw=1.5,
                           label=text if ax is axs[0] else None)
    u0 = runs[0]["units"]
    for ax, panel in zip(axs, panels):
        unit = next((u0.get(c) for c in panel if u0.get(c)), "")
        names = [c for c in panel if not c.endswith("_ref")] or panel[:1]
        # several signals in a panel (wind_u, wind_v, wind_w): their common stem names the axis, the legend the rest
        stem = os.path.commonprefix(names).rstrip("_") if len(names) > 1 else names[0]
        ax.set_ylabel(label(stem or names[0], unit))
        legend_outside(ax)
    axs[-1].set_xlabel(label("time t", "s"))
    info = runs[0]["info"]
    axs[0].set_title(title or (f"{info.get('scenario', '')} on {info.get('vehicle', '')} ({info.get('scene', '')})"
                               + (f", gains {info.get('gains')}" if len(runs) == 1 else "")))
    return save(fig, path)


def plot_bode(models, path, w_rad_s=None, title: str | None = None) -> Path:
    """Bode diagram of ``models``: ``[(label, sys, delay_s, (in_unit, out_unit))]``; magnitude in dB of the
    gain in output units per input unit, phase in deg including the input delay, frequency in rad/s (up to
    the Nyquist frequency of discrete models)."""
    from rotorlab.lti import freqresp, is_discrete

    nyq = min((np.pi / float(s.dt) for _, s, _, _ in models if is_discrete(s)), default=None)
    if w_rad_s is None:
        w_rad_s = np.logspace(-1, np.log10(0.999 * nyq if nyq else 1000.0), 400)
    w = np.asarray(w_rad_s, float)
    fig, axs = figure(2, 1, height_in=7.0, sharex=True)
    am, ap = axs[:, 0]
    units = set()
    for i, (lab, sys, delay_s, (u_in, u_out)) in enumerate(models):
        G = freqresp(sys, w)[:, 0, 0] * np.exp(-1j * w * delay_s)
        am.semilogx(w, 20 * np.log10(np.abs(G)), color=f"C{i}", label=lab + (f" (delay {delay_s:g} s)" if delay_s else ""))
        ap.semilogx(w, np.degrees(np.unwrap(np.angle(G))), color=f"C{i}")
        units.add(f"({u_out or '-'})/({u_in or '-'})")
    if nyq:
        for ax in (am, ap):
            ax.axvline(nyq, color="0.4", ls=":", lw=1.2, label="Nyquist frequency" if ax is am else None)
    am.set_ylabel(f"magnitude [dB re 1 {units.pop() if len(units) == 1 else 'output unit per input unit'}]")
    ap.set_ylabel(label("phase", "deg"))
    ap.set_xlabel(label("frequency", "rad/s"))
    legend_outside(am)
    am.set_title(title or "Bode diagram")
    return save(fig, path)
