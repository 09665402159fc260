"""Microseconds per FlightSoftware tick (cascade mode, and the other modes for comparison), and the ratio to the
20 ms control period. Run: ``python benchmarks/bench_flight_software.py``.

Each figure is timed over many short batches of ticks: the minimum is the cost of a tick on an uncontended core,
the median what it costs on this machine as it is loaded now (a shared 2-core box inflates it).
"""

from __future__ import annotations

import math
import statistics
import time

from rotorlab.gains import AxisGains, GainSet, LoopGains
from rotorlab.sim.control import DiscretePID, FlightSoftware, quad_plus
from rotorlab.vehicles import load_vehicle

DT = 0.02
BATCH, REPEATS = 200, 300
STANDARD = AxisGains(outer=LoopGains(kp=9.26, kd=1.11, tf=0.03),
                     inner=LoopGains(kp=0.257, ki=0.643, kd=0.0231, tf=0.0225))


def _time(fn) -> tuple[float, float]:
    """(min, median) microseconds per call of fn(k) over REPEATS batches of BATCH calls."""
    per_call = []
    k = 0
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        for _ in range(BATCH):
            fn(k)
            k += 1
        per_call.append((time.perf_counter() - t0) / BATCH * 1e6)
    return min(per_call), statistics.median(per_call)


def bench_fs(mode: str, altitude_hold: bool) -> tuple[float, float]:
    fs = FlightSoftware(GainSet("standard", {"pitch": STANDARD, "roll": STANDARD}), quad_plus(0.415), DT, mode=mode,
                        limits=load_vehicle("anteos-p2a2").commands)
    fs.set_reference(theta_ref=5.0, phi_ref=-2.0, psi_ref=10.0, x_ref=1.0, y_ref=0.0)
    if altitude_hold:
        fs.set_reference(z_ref=-5.0)
    meas = {"phi": 0.0, "theta": 0.0, "psi": 0.0, "p": 0.0, "q": 0.0, "r": 0.0,
            "x": 0.0, "y": 0.0, "z": -5.0, "vx": 0.0, "vy": 0.0, "vz": 0.0}

    def tick(k):
        # moving measurements so every branch does real arithmetic (costs ~0.3 us of the figure)
        meas["theta"] = 3.0 * math.sin(0.05 * k)
        meas["q"] = 0.15 * math.cos(0.05 * k)
        fs.step(k * DT, meas)

    return _time(tick)


def main() -> None:
    pid = DiscretePID(STANDARD.inner, DT, -30.0, 30.0)
    lo, med = _time(lambda k: pid.step(1.0, 0.5))
    print(f"DiscretePID.step: {lo:.2f} us (median {med:.2f} us)")
    for mode, alt in (("cascade", False), ("cascade", True), ("open-loop", False), ("position", True)):
        lo, med = bench_fs(mode, alt)
        label = f"{mode}{' + altitude hold' if alt and mode != 'position' else ''}"
        print(f"FlightSoftware.step [{label:26s}]: {lo:6.2f} us per tick (median {med:6.2f} us) = "
              f"{lo / (DT * 1e6) * 100:.3f} % of the {DT * 1e3:.0f} ms period; {DT * 1e6 / lo:,.0f} ticks per period")


if __name__ == "__main__":
    main()
