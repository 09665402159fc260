"""Figures of the README: the twins against the published models and the published closed loop.

Run ``python docs/make_figures.py`` (about a minute); it writes ``docs/*.png``.
"""

from pathlib import Path

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rotorlab import lti  # noqa: E402
from rotorlab.sim.linearize import linearize  # noqa: E402
from rotorlab.sim.runner import run_scenario  # noqa: E402
from rotorlab.vehicles import load_vehicle  # noqa: E402

OUT = Path(__file__).resolve().parent


def calibration():
    """Rig (test-bed) and free-flight responses of the twins against the published identified models: the
    vehicle's rotors own the dynamics, so the rig calibration carries over to flight."""
    w = np.logspace(-0.5, 2, 300)
    fig, ax = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    for col, name in enumerate(("anteos-p2a2", "anteos-a2minib")):
        v = load_vehicle(name)
        curves = [(v.published["testbed"], "k--", "published test-bed model"),
                  (linearize("pitch-rig", name, "pitch", "gyro_pitch", delay=False), "C0", "twin on the pitch rig"),
                  (linearize("free-flight", name, "pitch", "gyro_pitch", delay=False), "C1", "twin in free flight")]
        if "flight" in v.published:
            curves.insert(1, (v.published["flight"], "k:", "published in-flight model"))
        for sys, style, label in curves:
            G = lti.freqresp(ct.tf(sys.num, sys.den) if hasattr(sys, "source") else sys, w)[:, 0, 0]
            ax[0, col].semilogx(w, 20 * np.log10(np.abs(G)), style, label=label)
            ax[1, col].semilogx(w, np.degrees(np.unwrap(np.angle(G))), style)
        for a in ax[:, col]:
            a.axvspan(1, 15, color="0.9", zorder=0)
            a.grid(True, which="both", alpha=0.3)
        ax[0, col].set_title(f"{name}: pitch q/u, delay removed")
        ax[0, col].legend(loc="lower left", fontsize=8)
        ax[1, col].set_xlabel("frequency [rad/s]")
        ax[1, col].set_ylim(-200, 100)
    ax[0, 0].set_ylabel("|q/u| [dB, (deg/s)/%]")
    ax[1, 0].set_ylabel("phase [deg]")
    fig.tight_layout()
    fig.savefig(OUT / "calibration.png", dpi=110)


def published_loop():
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    for gains, c in (("standard", "C3"), ("optimal-testbed", "C0")):
        r = run_scenario("setpoint", "anteos-p2a2", gains=gains, seed=0)
        t = r.log["t"]
        sel = t < 2.0
        ax[0].plot(t[sel], r.log["theta"][sel], c, label=f"twin, {gains}")
        ax[1].plot(t[sel], r.log["u_lon"][sel], c)
    ax[0].plot(t[sel], r.log["theta_ref"][sel], "k:", label="set-point")
    ax[0].set_ylabel("pitch angle [deg]")
    ax[1].set_ylabel("pitch command u_lon [%]")
    for a in ax:
        a.set_xlabel("time [s]")
        a.grid(alpha=0.3)
    ax[0].legend()
    ax[0].set_title("P2-A2 pitch rig: 0.3 deg set-point step")
    fig.tight_layout()
    fig.savefig(OUT / "published_loop.png", dpi=110)


def rope_pull():
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for gains, c in (("standard", "C3"), ("optimal", "C0")):
        r = run_scenario("rope-pull", "anteos-a2minib", gains=gains, seed=0)
        t = r.log["t"]
        ax[0].plot(t, r.log["theta"], c, label=gains)
        ax[1].plot(t, r.log["u_lon"], c)
    ax[0].set_ylabel("pitch [deg]")
    ax[1].set_ylabel("u_lon [%]")
    ax[1].set_xlabel("time [s]")
    ax[0].legend()
    ax[0].set_title("A2-MINI/B rope pull on the pitch rig (twin)")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "rope_pull.png", dpi=110)


FIGURES = {"calibration": calibration, "published_loop": published_loop, "rope_pull": rope_pull}

if __name__ == "__main__":
    import sys

    for name in sys.argv[1:] or FIGURES:  # a subset by name, e.g. ``python docs/make_figures.py calibration``
        FIGURES[name]()
    print("wrote", *sorted(p.name for p in OUT.glob("*.png")))
