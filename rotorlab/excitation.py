"""Excitation signals for identification experiments: random-hold PRBS (and its exact expected spectrum),
the published ANTEOS campaign and its design for a target band, log sweeps, doublets and 3-2-1-1 multisteps,
and a spectrum check of how much power lands in a band.

Used by both the simulator (to fly the experiments) and the identification library (to design them), so it
imports neither; numpy, scipy.signal (the Welch PSD of :func:`spectrum_check`) and the autopilots' own
excitation laws (:mod:`rotorlab.autopilots`, ground floor like this module).
All signals are numpy arrays sampled at ``dt`` seconds; random ones take a ``seed`` or a
``numpy.random.Generator`` ``rng``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import welch

from rotorlab.autopilots import px4_autotune
from rotorlab.errors import ConfigError

__all__ = [
    "ANTEOS_CAMPAIGN",
    "prbs",
    "prbs_psd",
    "band_fraction",
    "design_campaign",
    "CampaignDesign",
    "campaign",
    "anteos_segments",
    "sweep",
    "doublet",
    "multistep_3211",
    "spectrum_check",
    "SpectrumCheck",
    "px4_autotune_signal",
    "ardupilot_sysid_chirp",
    "ARDUPILOT_SYSID_DELAY_S",
]

#: Published ANTEOS P2-A2 PRBS campaign (000_*.txt, "Identification experiments (3)"): level-hold
#: (switching) time ranges in s and amplitudes in % of the pitch control variable
#: (+/-7/9/11 % = +/-0.012/0.015/0.019 rad blade-pitch difference). Three segments were concatenated.
ANTEOS_CAMPAIGN = {
    "hold_ranges_s": ((0.05, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 0.8)),
    "amplitudes_pct": (7.0, 9.0, 11.0),
    "segments_concatenated": 3,
    "band_rad_s": (4.0, 8.0),
    "dt_s": 0.02,
}


def _rng(seed=None, rng=None) -> np.random.Generator:
    if rng is not None and seed is not None:
        raise ConfigError("pass either seed or rng, not both", field="seed/rng")
    return rng if rng is not None else np.random.default_rng(seed)


def _n_samples(n_samples, duration_s, dt) -> int:
    if dt <= 0:
        raise ConfigError("sample time must be positive", field="dt", expected="dt > 0 s", got=dt)
    if (n_samples is None) == (duration_s is None):
        raise ConfigError("give exactly one of n_samples and duration_s", field="n_samples/duration_s")
    n = int(n_samples) if n_samples is not None else int(round(duration_s / dt))
    if n < 1:
        raise ConfigError("signal length must be at least one sample", field="n_samples/duration_s", got=n)
    return n


def prbs(n_samples: int | None = None, dt: float = 0.02, *, duration_s: float | None = None,
         hold_range_s=(0.05, 0.1), amplitude: float = 7.0, seed=None, rng=None) -> np.ndarray:
    """Random-hold binary sequence of +/- ``amplitude``.

    Each level is held for a time drawn uniformly in ``hold_range_s`` (s) and rounded to a whole number of
    samples (at least one), then the sign flips. The first level's sign is random.

    Parameters
    ----------
    n_samples, duration_s : give one
        Length in samples or in s.
    dt : float
        Sample time, s.
    hold_range_s : (float, float)
        Minimum and maximum hold (switching) time, s.
    amplitude : float
        Level, in the unit of the input (the published campaign: % of control variable).

    Returns
    -------
    ndarray, shape (n_samples,)
    """
    n = _n_samples(n_samples, duration_s, dt)
    lo, hi = (float(h) for h in hold_range_s)
    if not 0 < lo <= hi:
        raise ConfigError("hold range must satisfy 0 < min <= max", field="hold_range_s",
                          expected="(min_s, max_s)", got=hold_range_s)
    g = _rng(seed, rng)
    # Draw enough holds at once: each is at least max(1, lo/dt) samples.
    min_len = max(1, int(round(lo / dt)))
    n_holds = n // min_len + 2
    holds = np.maximum(1, np.rint(g.uniform(lo, hi, n_holds) / dt).astype(int))
    sign0 = 1.0 if g.random() < 0.5 else -1.0
    levels = sign0 * amplitude * (-1.0) ** np.arange(n_holds)
    return np.repeat(levels, holds)[:n]


def _hold_pmf(hold_range_s, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact distribution of the hold length in samples that :func:`prbs` draws:
    ``max(1, rint(U / dt))`` with ``U`` uniform on ``hold_range_s``. Returns (lengths, probabilities)."""
    lo, hi = (float(h) / dt for h in hold_range_s)
    if not 0 < lo <= hi:
        raise ConfigError("hold range must satisfy 0 < min <= max", field="hold_range_s",
                          expected="(min_s, max_s)", got=hold_range_s)
    if hi - lo < 1e-12:
        return np.array([max(1, int(np.rint(lo)))]), np.array([1.0])
    k = np.arange(max(0, int(np.floor(lo - 0.5))), int(np.ceil(hi + 0.5)) + 1)
    p = np.clip(np.minimum(k + 0.5, hi) - np.maximum(k - 0.5, lo), 0.0, None) / (hi - lo)
    k = np.maximum(k, 1)  # prbs holds at least one sample
    lengths = np.unique(k[p > 0])
    return lengths, np.array([p[(k == n)].sum() for n in lengths])


def prbs_psd(w_rad_s, dt: float = 0.02, hold_range_s=(0.05, 0.1), amplitude: float = 1.0) -> np.ndarray:
    """Expected one-sided PSD (unit^2 per rad/s) of :func:`prbs`, exact for the sampled signal.

    The sequence alternates +-A with independent holds of ``N`` samples, so its first difference is a train
    of alternating +-2A impulses at renewal instants, whose spectrum is ``(4 A^2 / E[N]) Re[(1 - phi) /
    (1 + phi)]`` with ``phi(W) = E[exp(-j W N)]`` the hold length's characteristic function (W in
    rad/sample); dividing by ``|1 - exp(-j W)|^2`` undoes the difference. A hold near ``T`` puts the power
    near ``pi / T`` rad/s (half a period per hold), which is why the hold range sets the excited band.
    One-sided in rad/s: integrates to ``A^2`` over ``0..pi/dt``, as :func:`spectrum_check` normalises.
    """
    w = np.asarray(w_rad_s, dtype=float)
    # the spectrum is flat near DC, where numerator and denominator both vanish like W^2: evaluating it at
    # 1e-4 rad/sample keeps eight significant digits (at 1e-9 rounding would decide the ratio)
    W = np.clip(w * dt, 1e-4, np.pi)
    n, p = _hold_pmf(hold_range_s, dt)
    phi = (p[None, :] * np.exp(-1j * W.reshape(-1, 1) * n[None, :])).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        Sd = 4.0 * amplitude ** 2 / float(n @ p) * np.real((1 - phi) / (1 + phi))
    Sx = Sd / np.abs(1 - np.exp(-1j * W)) ** 2
    return (Sx * dt / np.pi).reshape(w.shape)


def band_fraction(band_rad_s, dt: float = 0.02, hold_range_s=(0.05, 0.1), n_grid: int = 4000) -> float:
    """Expected fraction of the power of :func:`prbs` inside ``band_rad_s`` (rad/s), from :func:`prbs_psd`."""
    lo, hi = (float(b) for b in band_rad_s)
    if not 0 <= lo < hi <= np.pi / dt:
        raise ConfigError("band must satisfy 0 <= low < high <= Nyquist", field="band_rad_s",
                          expected=f"(low, high) within 0..{np.pi / dt:.1f} rad/s", got=band_rad_s)
    w = np.linspace(lo, hi, n_grid)
    return float(np.trapezoid(prbs_psd(w, dt, hold_range_s), w))


@dataclass(frozen=True)
class CampaignDesign:
    """Result of :func:`design_campaign`.

    Attributes
    ----------
    holds : tuple of int
        Index of each segment's hold range into ``hold_ranges_s``.
    amplitudes_pct : tuple of float
        Amplitude of each segment.
    band_rad_s : (float, float)
    band_fraction : float
        Expected fraction of the campaign's input power in the band (equal-length segments).
    range_fractions : tuple of float
        Expected in-band fraction of each candidate hold range, in table order.
    """

    holds: tuple
    amplitudes_pct: tuple
    band_rad_s: tuple
    band_fraction: float
    range_fractions: tuple


def design_campaign(band_rad_s, dt: float = ANTEOS_CAMPAIGN["dt_s"], n_segments: int = 3,
                    amplitudes_pct=ANTEOS_CAMPAIGN["amplitudes_pct"],
                    hold_ranges_s=ANTEOS_CAMPAIGN["hold_ranges_s"]) -> CampaignDesign:
    """Choose each segment's hold range from the published table so that the campaign's input power is
    concentrated in ``band_rad_s`` (ref. 000 aimed its PRBS at the expected dominant attitude dynamics:
    4-8 rad/s for the P2-A2, 3-7 for the A2-MINI/B).

    Every candidate range's expected in-band fraction comes from the exact spectrum (:func:`band_fraction`).
    A binary signal's power is ``A^2`` whatever its holds, so the concatenation of equal-length segments has
    the amplitude^2-weighted mean fraction of its segments: every segment takes the range with the highest
    in-band fraction, which maximises it (on a tie the shorter holds, which also excite faster dynamics).
    Amplitudes stay the published ones, one per segment.
    """
    amps = tuple(float(a) for a in amplitudes_pct)
    if int(n_segments) != n_segments or n_segments < 1 or len(amps) < n_segments:
        raise ConfigError("one amplitude per segment", field="n_segments/amplitudes_pct",
                          expected=f"1 <= n_segments <= {len(amps)}", got=n_segments)
    fr = tuple(band_fraction(band_rad_s, dt, h) for h in hold_ranges_s)
    best = max(range(len(fr)), key=lambda i: (round(fr[i], 9), -i))
    holds = (best,) * int(n_segments)
    amps = amps[:int(n_segments)]
    total = sum(a * a for a in amps)
    frac = sum(a * a * fr[h] for a, h in zip(amps, holds)) / total
    return CampaignDesign(holds, amps, tuple(float(b) for b in band_rad_s), float(frac), fr)


def campaign(segments, dt: float = 0.02, seed=None, rng=None) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate PRBS segments, as the published identification input (three segments).

    Parameters
    ----------
    segments : sequence of (hold_range_s, amplitude, duration_s)
        One entry per segment.
    dt : float
        Sample time, s.

    Returns
    -------
    u : ndarray
        The concatenated signal.
    boundaries : ndarray of int, shape (len(segments) + 1,)
        Sample index where each segment starts, then the total length (segment i is
        ``u[boundaries[i]:boundaries[i + 1]]``).
    """
    g = _rng(seed, rng)
    parts = []
    for i, seg in enumerate(segments):
        try:
            hold, amp, dur = seg
        except (TypeError, ValueError):
            raise ConfigError("each segment is (hold_range_s, amplitude, duration_s)", field=f"segments[{i}]",
                              got=seg) from None
        parts.append(prbs(dt=dt, duration_s=dur, hold_range_s=hold, amplitude=amp, rng=g))
    bounds = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(int)
    return np.concatenate(parts), bounds


def anteos_segments(duration_s: float = 50.0, picks=((0, 0), (1, 1), (2, 2))):
    """Segments for :func:`campaign` from :data:`ANTEOS_CAMPAIGN`: ``picks`` are (hold-range index,
    amplitude index) pairs, one per segment, each ``duration_s`` long."""
    c = ANTEOS_CAMPAIGN
    return [(c["hold_ranges_s"][h], c["amplitudes_pct"][a], duration_s) for h, a in picks]


def sweep(duration_s: float, dt: float, f0_hz: float, f1_hz: float, amplitude: float = 1.0) -> np.ndarray:
    """Logarithmic chirp from ``f0_hz`` to ``f1_hz`` over ``duration_s`` (sine, starts at phase 0)."""
    n = _n_samples(None, duration_s, dt)
    if not 0 < f0_hz < f1_hz:
        raise ConfigError("sweep needs 0 < f0 < f1", field="f0_hz/f1_hz", got=(f0_hz, f1_hz))
    t = np.arange(n) * dt
    k = np.log(f1_hz / f0_hz) / duration_s
    phase = 2 * np.pi * f0_hz * (np.expm1(k * t)) / k
    return amplitude * np.sin(phase)


def _pulses(dt, widths_units, signs, unit_s, amplitude, start_s, duration_s):
    n = _n_samples(None, duration_s, dt)
    u = np.zeros(n)
    k = int(round(start_s / dt))
    unit = max(1, int(round(unit_s / dt)))
    for w, sgn in zip(widths_units, signs):
        u[k: k + w * unit] = sgn * amplitude
        k += w * unit
    if k > n:
        raise ConfigError("the pulse train does not fit in the signal", field="duration_s",
                          expected=f">= {k * dt:.3f} s", got=duration_s)
    return u


def doublet(dt: float, pulse_s: float, amplitude: float = 1.0, start_s: float = 0.0,
            duration_s: float | None = None) -> np.ndarray:
    """+amplitude for ``pulse_s`` then -amplitude for ``pulse_s``, from ``start_s``; zero elsewhere."""
    duration_s = duration_s if duration_s is not None else start_s + 4 * pulse_s
    return _pulses(dt, (1, 1), (1, -1), pulse_s, amplitude, start_s, duration_s)


def multistep_3211(dt: float, unit_s: float, amplitude: float = 1.0, start_s: float = 0.0,
                   duration_s: float | None = None) -> np.ndarray:
    """3-2-1-1 multistep: alternating pulses of 3, 2, 1 and 1 ``unit_s``, from ``start_s``."""
    duration_s = duration_s if duration_s is not None else start_s + 10 * unit_s
    return _pulses(dt, (3, 2, 1, 1), (1, -1, 1, -1), unit_s, amplitude, start_s, duration_s)


@dataclass(frozen=True)
class SpectrumCheck:
    """Result of :func:`spectrum_check`.

    Attributes
    ----------
    w_rad_s, psd : ndarray
        One-sided Welch PSD (unit^2 per rad/s) on its frequency grid (rad/s).
    band_rad_s : (float, float)
    band_fraction : float
        Fraction of the signal power (mean removed) inside the band.
    band_min_db : float
        Lowest PSD inside the band relative to the PSD peak, dB.
    excited : bool
        Band PSD nowhere more than ``max_drop_db`` below the peak and at least ``min_fraction`` of power in it.
    """

    w_rad_s: np.ndarray
    psd: np.ndarray
    band_rad_s: tuple
    band_fraction: float
    band_min_db: float
    excited: bool


def spectrum_check(u, dt: float, band_rad_s=(4.0, 8.0), nperseg: int | None = None,
                   max_drop_db: float = 20.0, min_fraction: float = 0.0) -> SpectrumCheck:
    """Welch PSD of ``u`` and how well the band ``band_rad_s`` (rad/s) is excited.

    ``nperseg`` defaults to the smallest power of two giving at least 8 frequency bins across the band.
    """
    u = np.asarray(u, dtype=float).ravel()
    lo, hi = band_rad_s
    if not 0 <= lo < hi:
        raise ConfigError("band must satisfy 0 <= low < high", field="band_rad_s", got=band_rad_s)
    if hi > np.pi / dt:
        raise ConfigError("band reaches beyond the Nyquist frequency", field="band_rad_s",
                          expected=f"high <= {np.pi / dt:.1f} rad/s", got=band_rad_s)
    if nperseg is None:
        need = 8 * 2 * np.pi / (dt * (hi - lo))
        nperseg = int(min(2 ** np.ceil(np.log2(need)), len(u)))
    f, P = welch(u - u.mean(), fs=1.0 / dt, nperseg=nperseg)
    w = 2 * np.pi * f
    P = P / (2 * np.pi)
    inband = (w >= lo) & (w <= hi)
    total = np.trapezoid(P, w)
    frac = float(np.trapezoid(P[inband], w[inband]) / total) if total > 0 and inband.sum() > 1 else 0.0
    peak = P.max()
    band_min_db = float(10 * np.log10(P[inband].min() / peak)) if peak > 0 and inband.any() else -np.inf
    excited = bool(band_min_db >= -max_drop_db and frac >= min_fraction)
    return SpectrumCheck(w, P, (lo, hi), frac, band_min_db, excited)


#: PX4 autotune's signal clock: the module publishes (and steps its signal) every 100 ms, and its wash-out filter
#: is a first-order low-pass of time constant 0.2 s at that rate (``_publishing_dt_s``, ``_signal_filter``,
#: PX4-Autopilot src/modules/mc_autotune_attitude_control/mc_autotune_attitude_control.hpp and ``.cpp``, ``init``)
def px4_autotune_signal(t_s, amplitude_rad_s: float = 0.7) -> np.ndarray:
    """PX4 multicopter autotune's identification signal on one axis's rate set-point, rad/s, at times ``t_s``
    (s, from the start of the axis's excitation state): the module's publishing-tick sequence
    (:class:`rotorlab.autopilots.px4_autotune.StepSignal`, where the facts and their PX4 sources are) held
    between its ticks (:data:`rotorlab.autopilots.px4_autotune.PUBLISH_S`, 100 ms). The identification state
    of each axis starts the sequence afresh.

    Parameters
    ----------
    t_s : array_like
        Times since the axis's state began, s (negative times give 0).
    amplitude_rad_s : float
        ``MC_AT_SYSID_AMP``.

    Returns
    -------
    ndarray
        Rate set-point added to the attitude controller's, rad/s.

    Examples
    --------
    >>> px4_autotune_signal([0.0, 0.05, 0.1, 0.55, 0.6], 0.7).round(4)  # the first step, washed out, then 0
    array([ 0.7   ,  0.7   ,  0.4667,  0.0922, -0.6385])
    """
    t = np.asarray(t_s, dtype=float)
    tick_s = px4_autotune.PUBLISH_S
    k_max = int(np.floor(max(float(t.max(initial=0.0)), 0.0) / tick_s + 1e-9)) + 1
    signal = px4_autotune.StepSignal(amplitude_rad_s)
    out = np.array([signal.next() for _ in range(k_max)])
    idx = np.floor(t / tick_s + 1e-9).astype(int)
    return np.where(t < 0, 0.0, out[np.clip(idx, 0, k_max - 1)])


#: ArduCopter SYSID mode waits this long after the mode is entered before the chirp starts (``SYSTEM_ID_DELAY``,
#: ArduCopter/mode_systemid.cpp)
ARDUPILOT_SYSID_DELAY_S = 1.0


def ardupilot_sysid_chirp(t_s, magnitude: float, f_start_hz: float, f_stop_hz: float, t_fade_in_s: float,
                          t_rec_s: float, t_fade_out_s: float, delay_s: float = ARDUPILOT_SYSID_DELAY_S) -> np.ndarray:
    """ArduCopter SYSID mode's chirp, at times ``t_s`` (s since the mode was entered), in the unit of
    ``magnitude`` (``SID_MAGNITUDE``: deg/s on the rate axes SID_AXIS 7-9, added to the body-frame rate target).

    The facts, from ArduPilot ``libraries/AP_Math/chirp.cpp`` (``Chirp::init``, ``Chirp::update``) and
    ``ArduCopter/mode_systemid.cpp`` (``init``: ``time_const_freq = 2 / SID_F_START_HZ``, two cycles at the start
    frequency; ``run``: the chirp is evaluated at the mode's time less ``SYSTEM_ID_DELAY`` = 1 s):

    - window: a raised cosine ``0.5 - 0.5 cos(pi t / T_in)`` over the fade-in, 1, then a raised cosine down over the
      last ``T_out`` of ``T_rec``, 0 outside ``(0, T_rec]``;
    - frequency: ``w_min = 2 pi f_start`` held for ``T_c = 2 / f_start`` (output ``sin(w_min (t - T_c))``), then
      exponential, ``w(t) = w_min exp(B (t - T_c) / (T_rec - T_c))`` with ``B = ln(w_max / w_min)``, phase
      ``w_min (T_rec - T_c) / B (exp(B (t - T_c) / (T_rec - T_c)) - 1)``; a constant sine when
      ``f_start == f_stop``.

    Examples
    --------
    >>> u = ardupilot_sysid_chirp(np.arange(0, 14, 0.0025), 20.0, 0.5, 20.0, 2.0, 12.0, 1.0)
    >>> bool(np.all(u[:400] == 0.0)), round(float(np.abs(u).max()), 1)  # the first second: the mode's delay
    (True, 20.0)
    """
    t = np.asarray(t_s, dtype=float) - delay_s
    w_min, w_max = 2 * np.pi * f_start_hz, 2 * np.pi * f_stop_hz
    t_const = 2.0 / f_start_hz
    window = np.select(
        [t <= 0, t <= t_fade_in_s, t <= t_rec_s - t_fade_out_s, t <= t_rec_s],
        [0.0, 0.5 - 0.5 * np.cos(np.pi * t / max(t_fade_in_s, 1e-12)), 1.0,
         0.5 - 0.5 * np.cos(np.pi * (t - (t_rec_s - t_fade_out_s)) / max(t_fade_out_s, 1e-12) + np.pi)], 0.0)
    if w_min == w_max:
        phase = w_min * t
    else:
        B = np.log(w_max / w_min)
        span = t_rec_s - t_const
        with np.errstate(over="ignore"):
            sweep_phase = (w_min * span / B) * np.expm1(B * (t - t_const) / span)
        phase = np.where(t <= t_const, w_min * (t - t_const), sweep_phase)
    on = (t > 0) & (t <= t_rec_s)
    return np.where(on, window * magnitude * np.sin(np.where(on, phase, 0.0)), 0.0)
