"""Acceptance numbers of issue 28's tuning on the tuhh-quad twin (prints them; no asserts; a few minutes).

1. Plants: the twin's true linearisation per axis (sim/linearize.py, delay removed, minimal, back to continuous
   time), in the autopilots' units, with the rotors' delays (roll 0.024 s, pitch 0.028 s; yaw, driven by both
   pairs, 0.026 s, 6.5 loop periods), written as model JSON.
2. ``rotorlab tune --autopilot px4`` (generic spec; ``--match px4-autotune``; ``--match all --filters search``)
   and ``--autopilot ardupilot``
   at 250 Hz: the linear analysis of the tuned set and of every baseline is printed by the command.
3. The PX4 autotune module's set (its identification run on the same loops flying the defaults, then its rule:
   what PX4 would save, written without the range check as PX4 writes it: its MC_YAW_P exceeds the documented 5)
   and the defaults flown beside the tuned sets: ``input-disturbance`` on the pitch and roll rigs (10 % step),
   and a 10 % yaw step at the plant input in free flight (the scenario has no yaw rig).

Run: ``python benchmarks/autopilot_tune_twin.py [OUTDIR]``.
"""

import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import control as ct
import numpy as np

from rotorlab import autopilots, lti
from rotorlab.ident.modelio import save_model
from rotorlab.sim.control.autopilot import AutopilotSpec
from rotorlab.sim.linearize import linearize
from rotorlab.sim.runner import make_flight_software, resolve_gains
from rotorlab.sim.scenarios import Setup
from rotorlab.sim.simulator import Simulator
from rotorlab.tune.autopilot import axis_plant, px4_autotune_params
from rotorlab.vehicles import load_vehicle

D2R = math.pi / 180
DELAY_S = {"roll": 0.024, "pitch": 0.028, "yaw": 0.026}
ROTORLAB = [sys.executable, "-m", "rotorlab"]


def models(v, out):
    G = {}
    for axis in DELAY_S:
        P0 = linearize("free-flight", v, input=axis, output=[f"gyro_{axis}"], delay=False)
        Gc = ct.minreal(lti.d2c_zoh(P0), 1e-7, verbose=False)
        G[axis] = ct.ss(Gc.A, Gc.B * 100 * D2R, Gc.C, Gc.D * 100 * D2R)  # normalised torque -> rad/s
        save_model(out / f"{axis}.json", G[axis], delay_s=DELAY_S[axis], input=["torque"], output=["rate"],
                   units={"torque": "norm", "rate": "rad/s"})
    return G


def yaw_step(v, controller, fraction_pct=10.0, t_on=1.0, duration_s=8.0):
    ap, src = controller.split(":", 1)
    params = {} if src == "defaults" else autopilots.read_params(src)
    sim = Simulator("free-flight", v, sensor_noise=False)
    dt = sim.control_dt_s
    fs = make_flight_software(v, resolve_gains(v, None), Setup(mode="cascade", reference=lambda t: {}), dt,
                              controller=AutopilotSpec.from_params(ap, params, source=src))
    sig, psi = {}, []
    for _ in range(int(round(duration_s / dt))):
        t = sim.time
        sim.measure(sig)
        sim.set_rotor_commands(fs.step_signals(t, sig))
        if t >= t_on - 1e-9:
            sim.add_axis_input([0.0, 0.0, 0.0, fraction_pct])
        psi.append((t, sig["psi"]))
        sim.tick()
    psi = np.array(psi)
    dev = psi[psi[:, 0] >= t_on - 1e-9, 1] - psi[psi[:, 0] < t_on][-1, 1]
    return float(np.max(np.abs(dev))), float(np.sum(np.abs(dev)) * dt)


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="aptune-"))
    out.mkdir(parents=True, exist_ok=True)
    v = load_vehicle("tuhh-quad")
    G = models(v, out)
    p = autopilots.px4.TABLE.defaults()
    gains, rejected = px4_autotune_params({a: axis_plant(G[a], DELAY_S[a], 1 / 250) for a in G}, p)
    (out / "px4-autotune.params").write_text("# PX4 autotune's rule on the twin's models\n" + "".join(
        f"1\t1\t{k}\t{val!r}\t9\n" for k, val in gains.items()))
    print("PX4 autotune rule rejects:", rejected or "none")
    model_args = [f"--model={a}={out / (a + '.json')}" for a in DELAY_S]
    runs = {"px4-tuned": ["--autopilot", "px4", "--out", str(out / "px4-tuned.params")],
            "px4-match": ["--autopilot", "px4", "--match", "px4-autotune", "--out", str(out / "px4-match.params")],
            "px4-all": ["--autopilot", "px4", "--match", "all", "--filters", "search",
                        "--out", str(out / "px4-all.params")],
            "ardupilot-tuned": ["--autopilot", "ardupilot", "--out", str(out / "ardupilot-tuned.parm")]}
    for name, args in runs.items():
        print(f"==== rotorlab tune {name}")
        r = subprocess.run(ROTORLAB + ["tune", *model_args, "--loop-hz", "250", *args], capture_output=True,
                           text=True)
        print("\n".join(ln for ln in r.stdout.splitlines() if ln.startswith(("  ", "roll", "pitch", "yaw", "wrote"))))
    sets = [f"px4:{out / 'px4-tuned.params'}", f"px4:{out / 'px4-match.params'}", f"px4:{out / 'px4-all.params'}",
            "px4:defaults",
            f"px4:{out / 'px4-autotune.params'}", f"ardupilot:{out / 'ardupilot-tuned.parm'}", "ardupilot:defaults"]
    print("==== twin: input-disturbance (10 %), rigs; angle peak deg, IAE deg s, command power above 5 Hz")
    for c in sets:
        for scene in ("roll-rig", "pitch-rig"):
            r = subprocess.run(ROTORLAB + ["run", "input-disturbance", "--vehicle", "tuhh-quad", "--scene", scene,
                                           "--controller", c, "--out", str(out / "runs" / f"{Path(c).stem}-{scene}"),
                                           "--json"], capture_output=True, text=True)
            m = json.loads(r.stdout)["metrics"]
            ax = next(iter(m))
            d, u = m[ax]["disturbance"], m[ax]["control"]
            print(f"{c:60s} {scene:9s} peak {d['peak_deviation']:.3f}  IAE {d['iae']:.3f}  hf {u['hf_power']:.4f}")
    print("==== twin: 10 % yaw step at the plant input, free flight; heading peak deg, IAE deg s (7 s)")
    for c in sets:
        pk, iae = yaw_step(v, c)
        print(f"{c:60s} yaw       peak {pk:.3f}  IAE {iae:.3f}")


if __name__ == "__main__":
    main()
