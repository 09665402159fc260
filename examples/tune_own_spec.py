"""
Tune the cascade to your own specification
==========================================

Write tuning goals in TOML (the systune-like goal types of :mod:`rotorlab.tune.goals`), tune the published
attitude cascade (outer PD on the pitch angle, inner PID on the pitch rate, 50 Hz) on an identified plant model,
and compare the goals for the starting and the tuned gains. The plant is the published P2-A2 test-bed model
(rate response to the pitch command, deg/s per %, 0.06 s delay); use your own from ``rotorlab ident``.
"""

import tempfile
from pathlib import Path

from rotorlab import tune
from rotorlab.gains import load_gains, save_gains
from rotorlab.vehicles import gains_path

# %%
# The spec: a crossover band on the rate loop, a hard tracking goal, a soft disturbance-rejection goal (what the
# tuner minimises) and margins at the plant input. ``rotorlab tune --spec FILE.toml`` reads the same file.
SPEC = """
[cascade]
dt = 0.02
axis = "pitch"
tune = ["outer.kp", "outer.kd", "outer.tf", "inner.kp", "inner.ki", "inner.kd", "inner.tf"]

[[goal]]
type = "crossover"
loop = "q"
band_rad_s = [4.0, 14.0]

[[goal]]
type = "tracking"
from = "theta_ref"
to = "theta"
response_time_s = 0.5
max_error_pct = 0.001
peak_error = 2.0
hard = true

[[goal]]
type = "rejection"
from = "d_u"
to = "theta"
weight = { kind = "highpass", order = 1, gain_db = 0.0, corner_rad_s = 10.0 }

[[goal]]
type = "margins"
point = "u"
gm_db = 5.0
pm_deg = 25.0
hard = true
"""
folder = Path(tempfile.mkdtemp())
(folder / "my-spec.toml").write_text(SPEC)
spec = tune.load_spec(folder / "my-spec.toml")

# %%
# The plant model and the starting gains (the vehicle's standard set). One start keeps this example quick; the
# CLI runs four by default.
plant = tune.plant_model([12.517, 36.374], [1, 5.583, 21.3], delay_s=0.06, name="test-bed")
start = load_gains(gains_path("anteos-p2a2", "standard"))
result = tune.tune_cascade(spec, [plant], start, starts=1, seed=0)

print("standard gains:")
print(tune.format_report(tune.evaluate(spec, start, [plant])))
print("\ntuned gains:")
print(tune.format_report(result.report))
path = save_gains(result.gains, folder / "my-gains.toml")
print(f"\nwrote {path.name}; fly it with: rotorlab run setpoint --gains {path}")
assert all(r.passed for r in result.report if r.hard), "a hard goal is missed"
