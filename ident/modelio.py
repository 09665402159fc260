"""Model JSON: the interchange format between ``rotorlab ident`` and ``rotorlab tune``.

State-space form (written by :func:`save_model`)::

    {"format": "rotorlab-model", "version": 1, "method": "pbsid", "dt": 0.02, "delay_s": 0.06,
     "delay_samples": 3, "A": [[...]], "B": [[...]], "C": [[...]], "D": [[...]], "K": [[...]] | null,
     "settings": {...}, "vaf": [...] | null, "input": ["u_lon"], "output": ["q"], "units": {...}}

Hand-written transfer-function form (read by :func:`load_model`), so published models can be tuned
directly::

    {"num": [12.517, 36.375], "den": [1, 5.583, 21.3], "dt": 0, "delay_s": 0.06,
     "units": {"input": "%", "output": "deg/s"}}

Units: ``units`` maps a signal name (of ``input`` / ``output``; in the transfer-function form the keys
``input`` and ``output``) to its unit (``rotorlab.units``; conventions in docs/units.md). A model without
them (files written before units were carried, or from a log that declared none) is read as before;
:func:`model_io_units` gives None for what it lacks and ``rotorlab tune`` takes that signal as the spec's.

``dt = 0`` means continuous time. The model is always stored with its delay removed; the delay travels
next to it in seconds (and in samples for discrete models).
"""

from __future__ import annotations

import math
from pathlib import Path

import control as ct
import numpy as np

from rotorlab.atomic import write_json
from rotorlab.config import read_json
from rotorlab.errors import ConfigError
from rotorlab.lti import as_ss, dc_gain, is_discrete, s_plane

__all__ = ["FORMAT", "VERSION", "save_model", "load_model", "describe_model", "model_io_units"]

FORMAT = "rotorlab-model"
VERSION = 1
# Every sample of delay is one state of the loop the tuner analyses (exact z^-k at the spec's sample time), and
# its cost grows with the cube of the states: 100 s at 50 Hz asked for 56 GiB. Two seconds is far beyond any
# flyable attitude loop (the published delays are 0.024-0.06 s) and stays at 100 extra states at 50 Hz.
MAX_DELAY_S = 2.0
#: most states of a model read from a file: identified models have a handful, and the tuner's cost grows with
#: the cube of the states (as for the delay's states above); a 32 MiB file could hold thousands
MAX_ORDER = 200


def _parts(model):
    """``(sys, delay_s, method, settings, K)`` from an IdentifiedModel, GreyBoxResult, HinfMatchResult or
    LTI system."""
    if hasattr(model, "sys") and hasattr(model, "delay") and not callable(model.delay):
        sys = as_ss(model.sys)
        dt = float(sys.dt) if is_discrete(sys) else 0.0
        return sys, model.delay * dt, model.method, dict(model.settings), model.K
    if hasattr(model, "sys") and hasattr(model, "delay_s") and hasattr(model, "model"):
        method = "oe" if hasattr(model, "ci95") else "hinf-match"
        settings = {"structure": model.model.name, "params": dict(model.params)}
        return as_ss(model.sys), float(model.delay_s), method, settings, None
    return as_ss(model), 0.0, "", {}, None


def save_model(path, model, vaf=None, extra=None, *, delay_s: float | None = None, input=None, output=None,
               units=None) -> Path:
    """Write a model JSON atomically.

    Parameters
    ----------
    path : str or Path
    model : IdentifiedModel, GreyBoxResult, HinfMatchResult, control.StateSpace or TransferFunction
        Delay-free model (the delay is taken from the object, or ``delay_s`` for a bare LTI system).
    vaf : array_like, optional
        VAF (%) per output, e.g. on cross-validation data.
    extra : dict, optional
        Merged into ``settings`` under ``"extra"`` (JSON-serialisable).
    input, output : list of str, optional
        Signal names.
    units : dict, optional
        ``{signal: unit}``.

    Returns
    -------
    Path
        The file written (``rotorlab tune --model`` and ``rotorlab bode`` read it).

    Examples
    --------
    >>> import tempfile, control as ct
    >>> from pathlib import Path
    >>> from rotorlab import ident
    >>> G = ct.c2d(ct.tf([12.517, 36.374], [1, 5.583, 21.3]), 0.02)
    >>> path = ident.save_model(Path(tempfile.mkdtemp()) / "p2a2.json", G, delay_s=0.06, input=["u_lon"], output=["q"])
    >>> sys, delay_s, meta = ident.load_model(path)
    >>> delay_s, sys.dt, meta["input"]
    (0.06, 0.02, ['u_lon'])
    """
    sys, d_s, method, settings, K = _parts(model)
    if delay_s is not None:
        d_s = float(delay_s)
    dt = float(sys.dt) if is_discrete(sys) else 0.0
    delay_samples = int(round(d_s / dt)) if dt > 0 and abs(d_s / dt - round(d_s / dt)) < 1e-9 else None
    if extra:
        settings = {**settings, "extra": extra}
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "method": method,
        "dt": dt,
        "delay_s": float(d_s),
        "delay_samples": delay_samples,
        "A": np.asarray(sys.A, float).tolist(),
        "B": np.asarray(sys.B, float).tolist(),
        "C": np.asarray(sys.C, float).tolist(),
        "D": np.asarray(sys.D, float).tolist(),
        "K": None if K is None else np.asarray(K, float).tolist(),
        "settings": settings,
        "vaf": None if vaf is None else np.atleast_1d(np.asarray(vaf, float)).tolist(),
        "input": list(input) if input is not None else None,
        "output": list(output) if output is not None else None,
        "units": dict(units or {}),
    }
    return write_json(path, doc)


def _matrix(doc, key, file, shape=None):
    v = doc.get(key)
    try:
        M = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError("not a numeric matrix", file=file, field=key, expected="list of lists of numbers",
                          got=v) from None
    if M.ndim == 1 and M.size == 0:
        M = M.reshape(0, 0)
    if M.ndim != 2:
        raise ConfigError("not a matrix", file=file, field=key, expected="list of lists of numbers", got=v)
    if not np.all(np.isfinite(M)):
        raise ConfigError("non-finite entry", file=file, field=key, expected="finite numbers", got=v)
    if shape is not None:
        want = tuple(s if s is not None else M.shape[i] for i, s in enumerate(shape))
        if M.size == 0 and 0 in want:
            M = M.reshape(want)
        if M.shape != want:
            raise ConfigError("wrong shape", file=file, field=key, expected=f"shape {want}", got=list(M.shape))
    return M


def _number(doc, key, file, default=None, minimum=None):
    v = doc.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ConfigError("not a number", file=file, field=key, expected="a finite number", got=v)
    if minimum is not None and v < minimum:
        raise ConfigError("out of range", file=file, field=key, expected=f">= {minimum}", got=v)
    return float(v)


def load_model(path, whole_samples: bool = True) -> tuple[ct.StateSpace, float, dict]:
    """Read a model JSON (state-space or transfer-function form).

    Parameters
    ----------
    path : str or Path
        A model JSON written by :func:`save_model` (``rotorlab ident --out``) or by hand.
    whole_samples : bool
        Refuse (the default) a discrete model whose delay is not a whole number of its samples: the cascade
        tuner's exact shift register needs one. The autopilot tuner resamples any delay exactly and reads with
        ``whole_samples=False``.

    Returns
    -------
    sys : control.StateSpace
        Delay removed; discrete with ``dt`` or continuous (``dt = 0``).
    delay_s : float
        Input delay (s).
    meta : dict
        The remaining fields (method, settings, vaf, input, output, units, ...).

    Raises
    ------
    ConfigError
        Naming the file and the field at fault.

    Examples
    --------
    The ``{"num", "den", "dt", "delay_s"}`` form, as a hand-written file:

    >>> import json, tempfile
    >>> from pathlib import Path
    >>> from rotorlab import ident
    >>> path = Path(tempfile.mkdtemp()) / "model.json"
    >>> _ = path.write_text(json.dumps({"num": [12.517, 36.374], "den": [1, 5.583, 21.3], "dt": 0, "delay_s": 0.06}))
    >>> sys, delay_s, meta = ident.load_model(path)
    >>> sys.nstates, sys.dt, delay_s
    (2, 0.0, 0.06)
    """
    path = Path(path)
    file = str(path)
    doc = read_json(path, "model")  # a regular file of bounded size and nesting (rotorlab.config)
    if not isinstance(doc, dict):
        raise ConfigError("the top level must be an object", file=file, got=type(doc).__name__)
    dt = _number(doc, "dt", file, default=0.0, minimum=0.0)
    delay_s = _number(doc, "delay_s", file, default=0.0, minimum=0.0)
    if delay_s > MAX_DELAY_S:
        raise ConfigError("each sample of delay is a state of the tuned loop", file=file, field="delay_s",
                          expected=f"at most {MAX_DELAY_S} s", got=delay_s)
    if "num" in doc or "den" in doc:
        num = _vector(doc, "num", file)
        den = _vector(doc, "den", file)
        if den[0] == 0:
            raise ConfigError("leading coefficient is zero", file=file, field="den", expected="non-zero", got=doc["den"])
        if len(den) - 1 > MAX_ORDER:
            raise ConfigError("model order too high", file=file, field="den",
                              expected=f"at most {MAX_ORDER + 1} coefficients (order {MAX_ORDER})",
                              got=f"{len(den)} coefficients")
        if len(num) > len(den):
            raise ConfigError("improper transfer function", file=file, field="num",
                              expected=f"at most {len(den)} coefficients (the length of den)", got=doc["num"])
        if not any(num):
            # a zero model: no controller moves its output, which tuning reported as "no start stabilises"
            raise ConfigError("the model is zero (no input reaches the output)", file=file, field="num",
                              expected="at least one non-zero coefficient", got=doc["num"])
        sys = ct.tf2ss(ct.tf(num, den, dt))
        meta = {k: v for k, v in doc.items() if k not in ("num", "den", "dt", "delay_s")}
        meta.setdefault("method", "transfer-function")
    else:
        fmt = doc.get("format")
        if fmt != FORMAT:
            raise ConfigError("unknown model format", file=file, field="format",
                              expected=f"'{FORMAT}' (or a num/den transfer function)", got=fmt)
        ver = doc.get("version")
        if ver != VERSION:
            raise ConfigError("unsupported version", file=file, field="version", expected=VERSION, got=ver)
        A = _matrix(doc, "A", file)
        n = A.shape[0]
        if n > MAX_ORDER:
            raise ConfigError("model order too high", file=file, field="A",
                              expected=f"at most {MAX_ORDER} states", got=f"{n} states")
        if A.shape != (n, n):
            raise ConfigError("not square", file=file, field="A", expected="an n x n matrix", got=list(A.shape))
        B = _matrix(doc, "B", file, (n, None))
        C = _matrix(doc, "C", file, (None, n))
        D = _matrix(doc, "D", file, (C.shape[0], B.shape[1]))
        if not np.any(D) and not (np.any(B) and np.any(C)):
            raise ConfigError("the model is zero (no input reaches the output)", file=file,
                              field="B" if not np.any(B) else "C", expected="a non-zero matrix", got=doc.get(
                                  "B" if not np.any(B) else "C"))
        sys = ct.ss(A, B, C, D, dt)
        meta = {k: v for k, v in doc.items() if k not in ("A", "B", "C", "D", "dt", "delay_s")}
        if doc.get("K") is not None:
            meta["K"] = _matrix(doc, "K", file, (n, C.shape[0]))
    if dt > 0 and whole_samples:
        k = delay_s / dt
        if abs(k - round(k)) > 1e-6:
            raise ConfigError("delay is not a whole number of samples", file=file, field="delay_s",
                              expected=f"a multiple of dt = {dt}", got=delay_s)
    return sys, delay_s, meta


def model_io_units(meta: dict, file="model") -> tuple[str | None, str | None]:
    """``(input unit, output unit)`` of a SISO model from :func:`load_model`'s ``meta`` (None where the file
    gives none).

    Raises
    ------
    ConfigError
        ``units`` that is not an object of strings, naming the file and the field.
    """
    units = meta.get("units") or {}
    if not isinstance(units, dict) or not all(isinstance(v, str) for v in units.values()):
        raise ConfigError("not a map of signal names to units", file=file, field="units",
                          expected='an object such as {"input": "%", "output": "deg/s"}', got=units)
    out = []
    for key in ("input", "output"):
        names = meta.get(key)
        name = names[0] if isinstance(names, list) and len(names) == 1 else key
        out.append(units.get(name, units.get(key)))
    return out[0], out[1]


def _vector(doc, key, file):
    v = doc.get(key)
    if (not isinstance(v, list) or not v
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
        raise ConfigError("not a list of numbers", file=file, field=key, expected="a non-empty list of finite numbers",
                          got=v)
    return [float(x) for x in v]


def _roots_lines(kind: str, roots, dt: float) -> list[str]:
    """One line per real root or conjugate pair, in rad/s (with natural frequency and damping for pairs)."""
    out = []
    s = s_plane(roots, dt)
    z = np.asarray(roots, complex)
    order = np.argsort(np.abs(s))
    for i in order:
        si, zi = s[i], z[i]
        if si.imag < -1e-9:  # the pair is printed once, from its upper member
            continue
        zs = "" if not dt else (f"z = {zi.real:.4g}" + (f" +/- {abs(zi.imag):.4g}j" if abs(zi.imag) > 1e-9 else "") + ": ")
        if not np.isfinite(si):
            out.append(f"  {kind:5s} {zs}at the origin of z (a pure delay)")
        elif abs(si.imag) > 1e-9:
            wn = abs(si)
            out.append(f"  {kind:5s} {zs}s = {si.real:.4g} +/- {si.imag:.4g}j rad/s (wn {wn:.4g} rad/s, zeta {-si.real / wn:.3g})")
        else:
            out.append(f"  {kind:5s} {zs}s = {si.real:.4g} rad/s")
    return out or [f"  {kind:5s} none"]


def describe_model(sys, delay_s: float = 0.0, units: dict | None = None, input=None, output=None) -> list[str]:
    """A model for people: time base, order, delay, poles and zeros in rad/s (discrete ones mapped by
    s = ln(z)/dt, with natural frequency and damping), and the DC gain with its units.

    Parameters
    ----------
    sys : control.StateSpace or TransferFunction
        The model, delay removed.
    delay_s : float
        Input delay, s.
    units : dict, optional
        ``{signal: unit}`` for the DC gain's unit.
    input, output : list of str, optional
        Signal names.
    """
    ss = as_ss(sys)
    dt = float(ss.dt) if is_discrete(ss) else 0.0
    units = units or {}
    ins = list(input or [f"u{i}" for i in range(ss.ninputs)])
    outs = list(output or [f"y{i}" for i in range(ss.noutputs)])
    base = f"discrete, dt = {dt:g} s" if dt else "continuous"
    delay = f"{delay_s:g} s" + (f" = {round(delay_s / dt)} samples" if dt else "")
    L = [f"model {', '.join(ins)} -> {', '.join(outs)}: {base}, order {ss.nstates}, input delay {delay} "
         "(poles and zeros below without it)"]
    L += _roots_lines("pole", np.linalg.eigvals(np.asarray(ss.A, float)) if ss.nstates else [], dt)
    try:
        zeros = ct.zeros(ss) if ss.nstates else []
    except Exception:  # noqa: BLE001 - slycot refuses some non-square systems; zeros are then not shown
        zeros = None
    L += _roots_lines("zero", zeros, dt) if zeros is not None else ["  zero  (not computed for this system)"]
    K = dc_gain(ss)
    for i, y in enumerate(outs):
        for j, u in enumerate(ins):
            unit = f" ({units[y]})/({units[u]})" if y in units and u in units else ""
            g = K[i, j]
            val = f"{g.real:.4g}" if np.isfinite(g) else "infinite (integrator)"
            L.append(f"  DC gain {u} -> {y}: {val}{unit}")
    return L
