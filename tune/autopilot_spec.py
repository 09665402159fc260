"""The generic multirotor spec for an autopilot's loops, derived from the identified plant: a TOML spec with the
derivation written beside every number, readable by :func:`rotorlab.tune.spec.parse_spec`.

The rule, per axis (``G`` the rate response to normalised torque, ``tau`` its input delay, ``dt`` the loop
period, ``F`` the autopilot's gyro low-pass at its cutoff):

* crossover band at the plant input: ``wc_max`` is where the loop's lag beyond the rigid body's integrator (delay,
  zero-order hold, gyro filter and the actuator's lag, the model's fast poles; :func:`crossover_band`) reaches
  75 deg (a plant phase of -165 deg): the D term's lead at crossover, a few tens of degrees behind the D-term
  filter, must still leave the 23 deg or more of phase margin a disk margin of 0.4 implies. Where the actuator is
  slow against the delay the D term is better spent cancelling it: with the PD zero on the slowest actuator pole
  the loop keeps the lag of the delay, the hold, the gyro filter, the faster poles and the D path's own filter
  (read from the autopilot's law, :func:`dterm_lag`), and ``wc_max`` is where that reaches 60 deg (loop phase
  -150 deg: 30 deg of margin, of which the I term's lag takes a few); the band's edge is the higher of the two.
  ``wc_min = wc_max / 10`` (yaw's authority, not its phase, sets its crossover, often near the band's low end)
  (hard);
* balanced disk margin at the plant input (both loops broken there, Seiler et al. 2020) at least
  ``max(0.4, the baselines')``: never less robust than what flies today, and never below 0.4 (about 3.5 dB and
  23 deg at once) (hard);
* the command's response to gyro noise ``|u_ctrl / n_q|`` (normalised torque per rad/s, peaking at high
  frequency through the D term) at most ``NOISE_FACTOR`` (2) times the largest of the baselines' that meet the
  disk floor (all baselines' where none does): a tuned D term may double the command noise of a robust set
  flown today, not follow a baseline that buys its rejection with a marginally stable loop; ``NOISE_DEFAULT``
  where no baseline is stable (hard);
* input-disturbance rejection ``theta / d_u`` (angle, rad, per unit torque disturbance), minimised: its peak
  gain, and its gain weighted by ``(s + wc_min) / s`` (the low-frequency part that decides how fast a step
  disturbance is worked off: the IAE), each normalised by the best baseline, so that a value below 1 on both beats
  every baseline on both (soft).

The baselines are the parameter sets the user has (the log's or file's, the autopilot's defaults, what PX4's
autotune module saves on the same model): their margins and noise set the floors, their rejection the yardstick.

With ``match`` (``rotorlab tune --match``) one baseline's robustness replaces the most robust one's: the disk
floor is that baseline's margin (no 0.4 minimum), the noise bound the larger of its gain and the rule above, the
band reaches ``MATCH_BAND`` times its crossover. A baseline that buys its rejection with a small margin (PX4's
autotune module on the tuhh-quad: 0.21-0.24 on roll and pitch) cannot be beaten at the defaults' margin by this
structure's gains with the default filters; at its own margin it can, and with the gyro and D-term low-pass cutoffs
searched too, one set at the defaults' margin beats both (``match="all"`` and
:func:`rotorlab.tune.autopilot.tune_filters`; docs/autopilot-tuning.md has the numbers and the sweep).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import control as ct
import numpy as np
from scipy.optimize import brentq

from rotorlab import lti
from rotorlab.autopilots import filters
from rotorlab.autopilots import get as get_autopilot
from rotorlab.tune import goals as G
from rotorlab.tune.autopilot import AXES, analyse_axis, evaluate_axis

__all__ = ["PHASE_LIMIT_DEG", "CANCELLED_PHASE_LIMIT_DEG", "DISK_FLOOR", "BAND_RATIO", "NOISE_FACTOR", "NOISE_DEFAULT",
           "MATCH_BAND", "ALL_BASELINES", "crossover_band", "dterm_lag", "generic_spec"]

PHASE_LIMIT_DEG = -165.0
# the loop's phase at wc_max with the D term's zero on the slowest actuator pole (its lead spent there)
CANCELLED_PHASE_LIMIT_DEG = -150.0
DISK_FLOOR = 0.4
BAND_RATIO = 10.0
NOISE_FACTOR = 2.0
# with no stable baseline: 1 normalised torque per rad/s (0.3 deg/s of gyro noise moves the command 0.5 %)
NOISE_DEFAULT = 1.0
MATCH_BAND = 1.25
#: ``match`` naming every baseline at once (``rotorlab tune --match all``)
ALL_BASELINES = "all"


def crossover_band(G, delay_s: float, dt_s: float, gyro_cutoff_hz: float, d_lag=None) -> tuple[float, float]:
    """``(wc_min, wc_max)`` rad/s of the rule in the module docstring for the rate model ``G`` (torque -> rate,
    delay removed, continuous or discrete) with input delay ``delay_s``.

    The loop's lag beyond the rigid body's integrator is ``w tau_eff + sum_p arg(1 / (1 - jw / p))``:
    ``tau_eff = delay + dt/2`` (zero-order hold) ``+ sqrt(2) / (2 pi f_c)`` (the gyro's second-order
    Butterworth low-pass, its low-frequency group delay), and one term per stable pole ``p`` of ``G`` with
    ``|p| >= 1 / (10 tau_eff)``: the actuator (motor lag) and faster dynamics, the actuator bandwidth in the
    model (slower poles are the rigid body's own and its drag, and unstable ones the free vehicle's slow modes,
    all far below any crossover). ``wc_max`` is where that lag reaches ``-90 - PHASE_LIMIT_DEG`` = 75 deg, or,
    with ``d_lag`` given and a real fast pole, where the lag without the slowest real fast pole (cancelled by the
    D term's zero) plus ``d_lag(w)`` reaches ``-90 - CANCELLED_PHASE_LIMIT_DEG`` = 60 deg, whichever is higher;
    ``wc_min = wc_max / BAND_RATIO``.

    Parameters
    ----------
    d_lag : callable, optional
        ``d_lag(w_rad_s) -> rad``: the autopilot's D path's lag behind an ideal derivative (:func:`dterm_lag`).

    Examples
    --------
    A rigid body behind a 120 ms motor lag and 17 ms of delay at 250 Hz, no gyro filter: the motor pole takes most
    of the 75 deg; cancelled by the D term (its filter off) the delay alone sets the edge.

    >>> import control as ct
    >>> G = ct.tf([5000.0], [0.12, 1.0, 0.0])
    >>> [round(x, 1) for x in crossover_band(G, 0.017, 1 / 250, 0.0)]
    [1.4, 14.2]
    >>> [round(x, 1) for x in crossover_band(G, 0.017, 1 / 250, 0.0, d_lag=lambda w: 0.0)]
    [5.5, 55.1]
    """
    tau, fast = _lag_terms(G, delay_s, dt_s, gyro_cutoff_hz)
    top = math.pi / dt_s

    def edge(lag, budget_deg):
        budget = math.radians(budget_deg)
        return top if lag(top) < budget else brentq(lambda w: lag(w) - budget, 1e-6, top)

    def poles_lag(w, poles):
        return float(np.sum(-np.angle(1.0 / (1.0 - 1j * w / poles))))

    wmax = edge(lambda w: w * tau + poles_lag(w, fast), -90.0 - PHASE_LIMIT_DEG)
    real = np.flatnonzero(np.abs(fast.imag) <= 1e-9 * np.abs(fast))
    if d_lag is not None and real.size:
        rest = np.delete(fast, real[np.argmin(np.abs(fast[real]))])
        wmax = max(wmax, edge(lambda w: w * tau + poles_lag(w, rest) + d_lag(w), -90.0 - CANCELLED_PHASE_LIMIT_DEG))
    return wmax / BAND_RATIO, wmax


def dterm_lag(autopilot, params: Mapping[str, float], axis: str, dt_s: float):
    """The lag (rad) of ``axis``'s D path behind an ideal derivative, as a function of ``w`` (rad/s): the
    autopilot's rate law (written once, ``rotorlab.autopilots``) with only its D gain, from the measured rate,
    so its D-term filter, its discrete difference and any output filter count as the law computes them.

    Examples
    --------
    >>> from rotorlab.autopilots import px4
    >>> lag = dterm_lag("px4", px4.TABLE.defaults(), "roll", 1 / 400)   # IMU_DGYRO_CUTOFF 20 Hz, second order
    >>> round(math.degrees(lag(50.0)), 1)
    37.1
    """
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    n = ap.axis_names(axis)
    only_d = {**params, n["P"]: 0.0, n["I"]: 0.0, n["FF"]: 0.0, n["D"]: 1.0}
    Cd = ap.rate_controller_lti(only_d, axis, dt_s, gyro_filter=False)

    def lag(w):
        # the D path on the measured rate is -D s (derivative on the measurement) or -D s on the error: both
        # -1 times a derivative from the rate input
        h = -ct.evalfr(Cd[0, 1], np.exp(1j * w * dt_s))
        return math.pi / 2 - float(np.angle(h))

    return lag


def _lag_terms(G, delay_s, dt_s, cutoff_hz):
    """``tau_eff`` (s) and the fast stable poles (rad/s) of :func:`crossover_band`'s lag model."""
    G = lti.as_ss(G)
    if lti.is_discrete(G):
        G = lti.d2c_zoh(G)
    filtered = filters.butter2_on(1.0 / dt_s, cutoff_hz)  # off (0, or at or above Nyquist): no lag
    tau = delay_s + dt_s / 2 + (math.sqrt(2.0) / (2 * math.pi * cutoff_hz) if filtered else 0.0)
    poles = np.linalg.eigvals(np.asarray(G.A, float))
    return tau, poles[(poles.real < 0) & (np.abs(poles) >= 1.0 / (10.0 * tau))]


def _poles_text(G, delay_s, dt_s, cutoff):
    tau, p = _lag_terms(G, delay_s, dt_s, cutoff)
    return f"(tau_eff {tau * 1e3:.1f} ms; poles " + ", ".join(f"{z:.4g}" for z in p[p.imag >= 0]) + " rad/s)"


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def generic_spec(autopilot, plants: Mapping[str, tuple], dt_s: float, params: Mapping[str, float],
                 baselines: Mapping[str, Mapping[str, float]], *, model: str = "model", match: str | None = None) -> str:
    """The spec's TOML text for ``plants`` (axis -> ``(Gp, G, delay_s)``: the loop plant of
    :func:`rotorlab.tune.autopilot.axis_plant`, the rate model it was made from and its delay), with every number's
    derivation in comments.

    ``params`` are the parameters the tuned set replaces (filters taken from them); ``baselines`` name the sets
    compared against (e.g. ``{"file": ..., "defaults": ..., "px4-autotune": ...}``), complete parameter dicts.

    ``match="all"`` (:data:`ALL_BASELINES`) asks for one set that beats every baseline at once: the disk floor
    stays the most robust baseline's (and at least 0.4), the gyro-noise bound is at least the noisiest baseline's
    gain, and the band reaches ``MATCH_BAND`` times the baselines' highest crossover.

    ``match`` naming one baseline holds the tuned set to its robustness instead of the most robust one's: its
    disk margin is the floor (no 0.4 minimum), the gyro-noise bound is the larger of its own gain and the generic
    bound (a baseline that buys its rejection with command noise lends the tuned set the same allowance; one
    quieter than the generic bound does not tighten it), and the band's upper edge is at least ``MATCH_BAND``
    times its highest crossover. It answers "what does the structure reach at that baseline's margin", e.g.
    against PX4 autotune's rule on a vehicle where that rule's margin is small. The disturbance goals stay
    normalised by the best baseline.
    """
    ap = get_autopilot(autopilot) if isinstance(autopilot, str) else autopilot
    cutoff = float(params[ap.GYRO_FILTER_PARAM])
    lines = [
        f"# Generic multirotor spec for {ap.NAME}'s attitude and rate loops on {model}, generated by",
        "# rotorlab.tune.autopilot_spec.generic_spec from the identified plant (rules in that module's docstring).",
        f"# Loop period {_fmt(dt_s)} s ({_fmt(1 / dt_s)} Hz); plants discretised there with their delay exact",
        "# (modified z-transform of the held torque: a delay that is not a whole number of periods is exact too).",
        "",
        "[meta]",
        f'model = "{model}"',
        f"baselines = [{', '.join(repr(b).replace(chr(39), chr(34)) for b in baselines)}]",
        "",
        "[autopilot]",
        f'name = "{ap.NAME}"',
        f"dt = {_fmt(dt_s)}",
        f"axes = [{', '.join(chr(34) + a + chr(34) for a in plants)}]",
        "",
    ]
    for axis, (Gp, G_rate, delay_s) in plants.items():
        if axis not in AXES:
            raise ValueError(f"axis must be one of {AXES}, got {axis!r}")
        lo, hi = crossover_band(G_rate, delay_s, dt_s, cutoff, d_lag=dterm_lag(ap, params, axis, dt_s))
        an = {b: analyse_axis(ap, p, axis, Gp) for b, p in baselines.items()}
        ok = {b: a for b, a in an.items() if a.stable}
        robust = ([a.noise_gain for a in ok.values() if a.disk_alpha >= DISK_FLOOR]
                  or [a.noise_gain for a in ok.values()])
        noise = NOISE_FACTOR * max(robust) if robust else NOISE_DEFAULT
        noise_why = (f"{NOISE_FACTOR:g} x the largest of the baselines' that meet the disk floor {DISK_FLOOR:g}"
                     if robust else f"{NOISE_DEFAULT:g} (no stable baseline)")
        disk = max([DISK_FLOOR] + [a.disk_alpha for a in ok.values()])
        disk_why = f"max({DISK_FLOOR}, baselines')"
        band_why = ""
        if match == ALL_BASELINES:
            # every baseline beaten at once: the most robust one's margin, the noisiest one's command noise
            loudest = max(ok, key=lambda b: ok[b].noise_gain, default=None)
            if loudest is not None and ok[loudest].noise_gain > noise:
                noise, noise_why = ok[loudest].noise_gain, f"{loudest}'s gain, the noisiest baseline's (match all)"
            hi = max(hi, MATCH_BAND * max((w for a in ok.values() for w in a.wc_rad_s), default=0.0))
            disk_why += " (match all)"
            band_why = f"; at least {MATCH_BAND:g} x the baselines' highest crossover (match all)"
        elif match is not None:
            if match not in baselines:
                raise ValueError(f"match: no baseline {match!r}; baselines are {sorted(baselines)}")
            if match not in ok:
                raise ValueError(f"match: the baseline {match!r} is unstable on {axis}")
            m = ok[match]
            disk = m.disk_alpha
            if m.noise_gain > noise:
                noise, noise_why = m.noise_gain, f"{match}'s gain (match; above the generic bound {noise:.4g})"
            else:
                noise_why += f" (match: {match}'s own gain {m.noise_gain:.4g} is below it)"
            hi = max(hi, MATCH_BAND * max(m.wc_rad_s, default=0.0))
            disk_why = f"{match}'s (match)"
            band_why = f"; at least {MATCH_BAND:g} x {match}'s highest crossover (match)"
        hp = G.Rejection("d_u", "theta", G.highpass_max_gain(1, 0.0, lo))
        lf = {b: evaluate_axis(ap, baselines[b], axis, Gp, [hp])[0].value for b in ok}
        peak = min((a.dist_hinf for a in ok.values()), default=1.0)
        lf_best = min(lf.values(), default=1.0)
        gm = 20 * math.log10((2 + disk) / (2 - disk))
        pm = math.degrees(2 * math.atan(disk / 2))
        table = "; ".join(f"{b}: disk {a.disk_alpha:.3f}, noise {a.noise_gain:.4g}, peak {a.dist_hinf:.4g}, "
                          f"low-frequency {lf[b]:.4g}" if a.stable else f"{b}: unstable" for b, a in an.items())
        filt = (f"the {_fmt(cutoff)} Hz gyro filter" if filters.butter2_on(1.0 / dt_s, cutoff)
                else f"no gyro filter (cutoff {_fmt(cutoff)} Hz: off)")
        lines += [
            f"# ---- {axis}: delay {_fmt(delay_s)} s = {_fmt(delay_s / dt_s)} loop periods. Baselines: {table}.",
            f"# Crossover band: the lag of delay, hold, {filt} and the model's actuator "
            f"(fast) poles {_poles_text(G_rate, delay_s, dt_s, cutoff)} reaches {-90 - PHASE_LIMIT_DEG:g} deg beyond "
            f"the integrator, or with the slowest actuator pole cancelled by the D term and its filter's lag added "
            f"{-90 - CANCELLED_PHASE_LIMIT_DEG:g} deg, at wc_max (the higher){band_why}: {hi:.4g} rad/s; "
            f"wc_min = wc_max / {BAND_RATIO:g}.",
            "[[goal]]", f'axis = "{axis}"', 'type = "crossover"', 'loop = "u"',
            f"band_rad_s = [{_fmt(lo)}, {_fmt(hi)}]", "",
            f"# Disk margin at the plant input >= {disk_why} = {disk:.4g}: GM {gm:.4g} dB and PM "
            f"{pm:.4g} deg at once.",
            "[[goal]]", f'axis = "{axis}"', 'type = "margins"', 'point = "u"', f"gm_db = {_fmt(gm)}",
            f"pm_deg = {_fmt(pm)}", "",
            f"# Gyro noise to command (through P and the D term), normalised torque per rad/s: at most {noise_why}.",
            "[[goal]]", f'axis = "{axis}"', 'type = "effort"', 'from = "n_q"', 'to = "u_ctrl"',
            f"max_gain = {_fmt(noise * 1.0001)}", "hard = true", "",
            "# Input disturbance, minimised: the peak |theta/d_u| (rad per unit torque) over the best baseline's ...",
            "[[goal]]", f'axis = "{axis}"', 'type = "rejection"', 'name = "disturbance peak d_u->theta"',
            'from = "d_u"', 'to = "theta"', f"weight = {_fmt(peak)}", "",
            "# ... and |theta/d_u| weighted by (s + wc_min)/s over the best baseline's (low frequencies: the IAE).",
            "[[goal]]", f'axis = "{axis}"', 'type = "rejection"', 'name = "disturbance low-frequency d_u->theta"',
            'from = "d_u"', 'to = "theta"', f'weight = {{ kind = "highpass", order = 1, gain_db = {_fmt(20 * math.log10(lf_best))}, '
            f"corner_rad_s = {_fmt(lo)} }}", "",
        ]
    return "\n".join(lines)
