"""Cost of reading and identifying a long, high-rate flight log, as a ratio to pyulog parsing the same file:

    ratio = CPU time of identify_flight_log(log, axes roll/pitch/yaw, no report) / CPU time of pyulog.ULog(log)

measured in one process over interleaved repeats (``time.process_time``), the median of the ratios of
neighbouring runs, so the load of the shared machine cancels. Target of issue 27: at most 2.

The log is written here through the project's ULog writer: ``MINUTES`` of flight at 1 kHz (PX4 v1.14 topics:
rate set-point, filtered rate and torque set-point at 1 kHz, land detector, status, thrust), each axis a plant
``K/(s (tau s + 1))`` flown by PX4's rate law (``rotorlab.autopilots.px4`` at its defaults and 1 kHz) from a
pilot-like set-point (low-passed noise), with gyro noise.

One BLAS thread (set below before numpy loads, as bench_ident.py does): the fits' matrices are small, and on a
shared machine OpenBLAS threads spinning against each other count as CPU time (5x the single-thread figure).

Usage: ``python benchmarks/bench_flightlogs.py [minutes] [repeats] [--profile]``
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import cProfile  # noqa: E402
import pstats  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import control as ct  # noqa: E402
import numpy as np  # noqa: E402
from pyulog import ULog  # noqa: E402
from scipy import signal as sig  # noqa: E402

from rotorlab.autopilots import px4  # noqa: E402
from rotorlab.ident.flightlogs.run import identify_flight_log  # noqa: E402
from rotorlab.ident.flightlogs.writers import write_ulog  # noqa: E402

LOOP_HZ = 1000.0
PLANTS = {"roll": (400.0, 0.03), "pitch": (350.0, 0.035), "yaw": (60.0, 0.08)}
AXES = ("roll", "pitch", "yaw")


def _lsim(sysd, u):
    num, den = sig.ss2tf(*(np.asarray(M, float) for M in (sysd.A, sysd.B, sysd.C, sysd.D)))
    return np.column_stack([sig.lfilter(n, den[0] if np.ndim(den) > 1 else den, u) for n in num])


def make_log(path: Path, minutes: float, seed: int = 0) -> Path:
    """A ``minutes``-long 1 kHz PX4 ULog of a simulated three-axis flight (see the module docstring)."""
    rng = np.random.default_rng(seed)
    params = {**px4.TABLE.defaults(), "IMU_GYRO_RATEMAX": int(LOOP_HZ)}
    dt = 1.0 / LOOP_HZ
    n = int(minutes * 60 * LOOP_HZ)
    t = np.arange(n) * dt
    landed = (t < 2.0) | (t > t[-1] - 2.0)
    b, a = sig.butter(2, 2.0, fs=LOOP_HZ)
    rates, outs, sps = {}, {}, {}
    for axis in AXES:
        K, tau = PLANTS[axis]
        P = ct.c2d(ct.ss(ct.tf([K], [tau, 1.0, 0.0])), dt)
        C = px4.rate_controller_lti(params, axis, dt, gyro_filter=False)
        r = sig.lfilter(b, a, rng.standard_normal(n)) * (3.0 if axis != "yaw" else 1.5)
        r[landed] = 0.0
        # u = C_r r + C_y y, y = P u: y = P / (1 - P C_y) C_r r (C_y carries the law's minus sign)
        Cr, Cy = C[0, 0], C[0, 1]
        y = _lsim(ct.ss(ct.series(Cr, ct.feedback(P, Cy, sign=1))), r)[:, 0]
        u = _lsim(ct.ss(Cr), r)[:, 0] + _lsim(ct.ss(Cy), y)[:, 0]
        rates[axis] = y + 0.01 * rng.standard_normal(n)
        outs[axis], sps[axis] = u, r
    us = (1_000_000 + np.round(t * 1e6)).astype(np.uint64)
    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731
    slow = us[::50]
    topics = {
        "vehicle_rates_setpoint": {"timestamp": us, **{ax: f32(sps[ax]) for ax in AXES}},
        "vehicle_angular_velocity": {"timestamp": us, **{f"xyz[{i}]": f32(rates[ax]) for i, ax in enumerate(AXES)}},
        "vehicle_torque_setpoint": {"timestamp": us, **{f"xyz[{i}]": f32(outs[ax]) for i, ax in enumerate(AXES)}},
        "vehicle_land_detected": {"timestamp": slow, "landed": landed[::50].astype(np.uint8)},
        "vehicle_status": {"timestamp": slow, "arming_state": np.full(len(slow), 2, np.uint8),
                           "nav_state": np.full(len(slow), 10, np.uint8)},
        "vehicle_thrust_setpoint": {"timestamp": slow, "xyz[0]": f32(np.zeros(len(slow))),
                                    "xyz[1]": f32(np.zeros(len(slow))),
                                    "xyz[2]": f32(np.where(landed[::50], -0.1, -0.5))},
    }
    return write_ulog(path, topics, params, {"ver_sw_release": 0x010E0000})


def _parse(path) -> float:
    t0 = time.process_time()
    ULog(str(path))
    return time.process_time() - t0


def _identify(path, out) -> float:
    t0 = time.process_time()
    res = identify_flight_log(path, out, ["roll", "pitch", "yaw"], report=False)
    dt = time.process_time() - t0
    assert set(res.models) == set(AXES), res.notes
    return dt


def main(minutes: float = 10.0, repeats: int = 3, profile: bool = False) -> dict:
    folder = Path(tempfile.mkdtemp(prefix="bench_flightlogs_"))
    path = make_log(folder / "long.ulg", minutes)
    print(f"{path}: {path.stat().st_size / 1e6:.1f} MB, {minutes:g} min at {LOOP_HZ:g} Hz")
    if profile:
        cProfile.runctx("_identify(path, folder / 'out')", globals(), {"path": path, "folder": folder,
                                                                      "_identify": _identify}, str(folder / "prof"))
        pstats.Stats(str(folder / "prof")).sort_stats("cumulative").print_stats(30)
    ratios, parse, ident = [], [], []
    for i in range(repeats):
        if i % 2 == 0:
            p, q = _parse(path), _identify(path, folder / "out")
        else:
            q, p = _identify(path, folder / "out"), _parse(path)
        parse.append(p)
        ident.append(q)
        ratios.append(q / p)
    out = {"parse_s": statistics.median(parse), "identify_s": statistics.median(ident),
           "ratio": statistics.median(ratios)}
    print(f"pyulog parse {out['parse_s']:.2f} s CPU, read + identify 3 axes {out['identify_s']:.2f} s CPU: "
          f"ratio {out['ratio']:.2f} (target <= 2)")
    return out


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(float(args[0]) if args else 10.0, int(args[1]) if len(args) > 1 else 3, "--profile" in sys.argv)
