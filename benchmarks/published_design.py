"""Published gain sets vs our tuned gains, analysed with the same tools (prints a markdown table).

Columns: crossover of the outer (theta, inner closed) and inner (q, outer open) loops, margins at the plant
input (both loops broken there), 10-90 % rise time, 2 % settling time and overshoot of the angle step,
peak angle deviation after a 1 % step input disturbance (gust), and the spec objective (max soft goal).
Run: ``python benchmarks/published_design.py``.
"""

from pathlib import Path

import control as ct
import numpy as np

from rotorlab.gains import load_gains
from rotorlab.tune.cascade import N_CON, N_MEAS, cascade_plant, cascade_structure, generalised_plant, plant_model
from rotorlab.tune.goals import CrossoverBand, evaluate, objective, tune_cascade
from rotorlab.tune.hinfstruct import closed_loop
from rotorlab.tune.margins import crossover_frequencies, margins
from rotorlab.tune.spec import load_spec
from rotorlab.vehicles import load_vehicle

VEH = Path(__file__).resolve().parents[1] / "vehicles"


def analyse(spec, gains, model):
    ax = gains["pitch"]
    Gp = cascade_plant(model, spec.dt)
    K = cascade_structure(spec.dt, ax).ss()
    wc_o = crossover_frequencies(CrossoverBand("theta", 1, 2).loop_tf(Gp, K))
    wc_i = crossover_frequencies(CrossoverBand("q", 1, 2).loop_tf(Gp, K))
    m = margins(CrossoverBand("u", 1, 2).loop_tf(Gp, K))
    t = np.arange(0, 6, spec.dt)
    T = closed_loop(generalised_plant(Gp, inputs=("theta_ref",), outputs=("theta",)), N_MEAS, N_CON, K)
    y = ct.step_response(T, t).outputs.ravel()
    rise = t[np.argmax(y >= 0.9)] - t[np.argmax(y >= 0.1)]
    out = np.flatnonzero(np.abs(y - 1) > 0.02)
    settle = t[out[-1] + 1] if out.size and out[-1] + 1 < t.size else np.nan
    D = closed_loop(generalised_plant(Gp, inputs=("d_u",), outputs=("theta",)), N_MEAS, N_CON, K)
    gust = np.max(np.abs(ct.step_response(D, t).outputs.ravel()))
    obj = objective(evaluate(spec, gains, [model]))
    fmt = lambda a: "/".join(f"{x:.2f}" for x in a) or "none"
    return (f"{fmt(wc_o)} | {fmt(wc_i)} | {m.gm_db:.1f} | {m.pm_deg:.1f} | {m.disk_alpha:.2f} | {rise:.2f} | "
            f"{settle:.2f} | {100 * (y.max() - 1):.1f} | {gust:.3f} | {obj:.3f}")


def published(vehicle, which, name):
    """The published identified model ``[published.WHICH]`` of the vehicle spec (its one source) as a plant."""
    pm = load_vehicle(vehicle).published[which]
    return plant_model(pm.num, pm.den, pm.delay_s, name)


def main():
    cases = [
        ("anteos-p2a2", published("anteos-p2a2", "testbed", "test-bed"),
         ["standard", "optimal-testbed", "optimal-flight"]),
        ("anteos-p2a2", published("anteos-p2a2", "flight", "flight"),
         ["standard", "optimal-testbed", "optimal-flight"]),
        ("anteos-a2minib", published("anteos-a2minib", "testbed", "test-bed"), ["standard", "optimal"]),
    ]
    print("| vehicle / model | gains | wc outer [rad/s] | wc inner [rad/s] | GM_u [dB] | PM_u [deg] | disk alpha_u "
          "| rise [s] | settle 2% [s] | overshoot [%] | gust peak [deg/%] | spec objective |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for vehicle, model, sets in cases:
        spec = load_spec(vehicle)
        for name in sets:
            g = load_gains(VEH / vehicle / "gains" / f"{name}.toml")
            print(f"| {vehicle} / {model.name} | {name} (published) | {analyse(spec, g, model)} |")
        tuned = tune_cascade(spec, [model], load_gains(VEH / vehicle / "gains" / "standard.toml")).gains
        print(f"| {vehicle} / {model.name} | rotorlab tuned from standard | {analyse(spec, tuned, model)} |")


if __name__ == "__main__":
    main()
