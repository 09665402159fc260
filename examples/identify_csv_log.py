"""
Identify a model from a CSV log
===============================

Fly the published PRBS campaign on the P2-A2 pitch rig, save the log as a CSV file with a flight computer's own
column names (as a real log would come), then read it back with a column map, identify the pitch dynamics with
PBSID and score the model against the twin's true linearisation (the ground truth no real rig has).

For a real flight log, start at :func:`rotorlab.ident.load_log`: it checks the log (uniform time, no gaps, no NaN,
signals that move) and names the row and column of anything wrong.
"""

import tempfile
from pathlib import Path

import numpy as np

from rotorlab import ident
from rotorlab.sim.linearize import truth_model
from rotorlab.sim.runner import run_scenario

# %%
# A short PRBS campaign on the twin (one 30 s segment; the pipeline flies three of 60 s). The log is in
# flight-software units: ``u_lon`` pitch command in %, ``q`` IMU pitch rate in deg/s, sampled at 50 Hz.
run = run_scenario("prbs", "anteos-p2a2", seed=1, duration_s=30.0)
folder = Path(tempfile.mkdtemp())
csv = folder / "flight.csv"
t, u, q = run.log["t"], run.log["u_lon"], run.log["q"]
np.savetxt(csv, np.column_stack([t, u, q]), delimiter=",", header="time,elevator_pct,gyro_y_dps", comments="")
print(f"wrote {csv.name}: {len(t)} rows")

# %%
# Read it with a column map (our name -> the file's name) and identify a second-order model. The campaign's
# three-sample transport delay is estimated from the data.
log = ident.load_log(csv, column_map={"t": "time", "u_lon": "elevator_pct", "q": "gyro_y_dps"})
u, y = log["u_lon"], log["q"]
delay = ident.estimate_delay(u, y, max_delay=10)
n_id = int(0.7 * len(u))
model = ident.pbsid(u[:n_id], y[:n_id], order=2, past=20, future=10, dt=log.dt, delay=delay)
print(f"estimated delay: {delay} samples ({delay * log.dt:.3f} s)")
print("poles [rad/s]:", np.round(np.log(model.sys.poles()) / log.dt, 2))

# %%
# Cross-validation on the last 30 % of the record, and the nu-gap to the twin's true model (0: identical,
# 1: as far apart as models get; the two published P2-A2 models are 0.07 apart).
fit = float(np.squeeze(ident.vaf(y[n_id:], ident.simulate(model, u[n_id:]))))
gap = ident.nugap(model.sys, truth_model("anteos-p2a2"))
print(f"cross-validation VAF {fit:.1f} %, nu-gap to the truth {gap:.3f}")
assert fit > 80 and gap < 0.3
