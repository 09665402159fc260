"""The sensor protocol and the suite that samples sensors together at a control tick.

A sensor turns one field of MuJoCo's data (``sensordata`` or ``act``) into readings in flight-software units.
:meth:`Sensor.read` takes that field as a 1-D array (one simulation, :class:`~rotorlab.sim.simulator.Simulator`)
or as a 2-D array with one row per simulation (``mujoco.batch``, :func:`rotorlab.sim.batch.run_batch`), so the
scalar and the batched paths share one conversion.

Noise is the suite's: the noisy channels of all its sensors draw together, so one seed gives one stream whatever
reads it. At reset a bias is drawn for each sensor that has one (``normal(0, bias_std, n_channels)``, in suite
order); at every noisy tick one ``standard_normal(n_noisy)`` vector covers every noisy channel in suite order, and
a reading is ``value + (bias + std * z)`` (:class:`NoiseStream`).
"""

from __future__ import annotations

import math
from operator import add

import mujoco
import numpy as np

from rotorlab.errors import ConfigError
from rotorlab.scenes import PREFIX


def sensor_slice(model, name: str) -> slice | None:
    """Where MuJoCo sensor ``name`` (with or without the vehicle prefix) lives in ``sensordata``; None if absent."""
    for full in (f"{PREFIX}{name}", name):
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, full)
        if sid >= 0:
            adr, dim = int(model.sensor_adr[sid]), int(model.sensor_dim[sid])
            return slice(adr, adr + dim)
    return None


class Sensor:
    """Base class: one file per sensor, registered in :data:`rotorlab.sim.sensors.SENSORS`.

    Subclasses set :attr:`name`, :attr:`channels` and :attr:`field`, find their data in ``__init__(model,
    vehicle)`` (raising :class:`LookupError` when the model lacks it, e.g. a load cell off the thrust stand) and
    implement :meth:`read`.
    """

    #: registry name
    name: str = "sensor"
    #: readings, name -> unit (flight-software units and frames)
    channels: dict = {}
    #: the MjData field :meth:`read` takes
    field: str = "sensordata"
    #: its MuJoCo data is computed in the acceleration stage (a force or an acceleration): current at a tick
    #: only when the tick ends with that stage (:attr:`rotorlab.sim.simulator.Simulator.forces_at_tick`)
    acceleration_stage: bool = False

    def __init__(self, model, vehicle):
        self.noise_std = np.zeros(len(self.channels))  # per channel, in the channel's unit
        self.bias_std = 0.0  # turn-on bias, drawn once per run, in the channels' unit

    @property
    def noisy(self) -> bool:
        return bool(np.any(self.noise_std > 0) or self.bias_std > 0)

    def read(self, x) -> np.ndarray:
        """Noise-free readings ``(..., len(channels))`` from the MjData field ``x`` (1-D, or 2-D: one row per
        simulation)."""
        raise NotImplementedError

    def read_floats(self, x: list):
        """:meth:`read` of one simulation, from the MjData field as a list of floats to a list or tuple of floats,
        the same values bit for bit (tests/test_sensors.py). The simulator samples through here every tick: a sensor
        whose conversion is a few float operations overrides it with them, as numpy's per-call cost on a
        3-vector is several times the arithmetic."""
        return self.read(np.asarray(x)).tolist()

    def _require(self, model, name: str) -> slice:
        sl = sensor_slice(model, name)
        if sl is None:
            raise LookupError(f"the model has no MuJoCo sensor '{name}' for the {self.name} sensor")
        return sl


class SensorSuite:
    """Sensors sampled together at a tick, with one seeded noise stream (module docstring).

    Parameters
    ----------
    sensors : sequence of Sensor
        In draw order.
    """

    def __init__(self, sensors):
        self.sensors = list(sensors)
        fields = {s.field for s in self.sensors}
        if len(fields) > 1:
            raise ConfigError(field="sensors", expected="sensors reading one MjData field", got=sorted(fields))
        self.field = fields.pop() if fields else "sensordata"
        self.channels = [c for s in self.sensors for c in s.channels]
        self.units = {c: u for s in self.sensors for c, u in s.channels.items()}
        self.slices, k = [], 0
        for s in self.sensors:
            self.slices.append(slice(k, k + len(s.channels)))
            k += len(s.channels)
        noisy = [s.noisy for s in self.sensors]
        # the noise draw covers the noisy sensors only, in suite order (noise-free ones consume no draws)
        self.n_noisy = sum(len(s.channels) for s, n in zip(self.sensors, noisy) if n)
        self._noisy_cols = np.concatenate([np.arange(sl.start, sl.stop) for sl, n in zip(self.slices, noisy) if n]) \
            if self.n_noisy else np.zeros(0, dtype=int)
        self._noisy_list = self._noisy_cols.tolist()
        self.noise_std = np.concatenate([s.noise_std for s, n in zip(self.sensors, noisy) if n]) \
            if self.n_noisy else np.zeros(0)
        self.set_current(self.sensors)

    def set_current(self, current) -> None:
        """The sensors whose data MuJoCo computes at the ticks (default: all). One simulation's :meth:`sample`
        reads only these; the others' channels are NaN, never a stale reading, and are not converted
        (:attr:`rotorlab.sim.simulator.Simulator.forces_at_tick` off: the accelerometer). Their noise is still
        drawn, so the stream, and every other channel's reading, is the seed's whatever is current."""
        live = [s in current for s in self.sensors]
        self._reads = [s.read_floats for s, ok in zip(self.sensors, live) if ok]
        cols = [k for sl, ok in zip(self.slices, live) if ok for k in range(sl.start, sl.stop)]
        self._live_channels = [self.channels[k] for k in cols]
        self._stale = {c: math.nan for s, ok in zip(self.sensors, live) if not ok for c in s.channels}
        # the noise row's index of each current channel (-1: noise-free); the usual case, the current channels
        # the first of the noisy ones, adds the row in one map
        noise_of = {k: j for j, k in enumerate(self._noisy_list)}
        self._live_noise = [noise_of.get(k, -1) for k in cols]
        self._noise_prefix = self._live_noise == list(range(len(cols)))

    def draw_bias(self, rng: np.random.Generator) -> np.ndarray:
        """Turn-on biases of the noisy channels ``(n_noisy,)``: one ``normal(0, bias_std, n)`` per biased sensor."""
        bias = np.zeros(self.n_noisy)
        k = 0
        for s in self.sensors:
            if not s.noisy:
                continue
            n = len(s.channels)
            if s.bias_std > 0:
                bias[k:k + n] = rng.normal(0.0, s.bias_std, n)
            k += n
        return bias

    def read(self, x, out=None) -> np.ndarray:
        """Noise-free readings of every channel ``(..., n_channels)`` from the MjData field ``x``."""
        if out is None:
            out = np.empty(np.shape(x)[:-1] + (len(self.channels),))
        for s, sl in zip(self.sensors, self.slices):
            out[..., sl] = s.read(x)
        return out

    def sample(self, x, noise: NoiseStream | None = None, out: dict | None = None) -> dict:
        """The readings at a control tick, channel -> value: floats from a 1-D ``x`` (one simulation; an array
        or a memoryview of MjData's ``sensordata``), arrays ``(n,)`` from a 2-D array (a row per simulation); one
        tick of ``noise`` added when given. Into ``out`` when given (the runner's signal dict,
        :meth:`rotorlab.sim.control.flight_software.FlightSoftware.step_signals`), else into a new dict; returns
        it. The simulator and the batched runner both sample through here."""
        if x.ndim == 1:
            # one simulation: floats throughout (Sensor.read_floats), the same sums as add_noise's, the current
            # sensors only (set_current)
            xs = x.tolist()
            vals = []
            for read in self._reads:
                vals += read(xs)
            if noise is not None:
                row = noise.next_floats()
                if self._noise_prefix:
                    vals = map(add, vals, row)  # the additions in C, consumed by the dict below
                else:
                    for i, k in enumerate(self._live_noise):
                        if k >= 0:
                            vals[i] += row[k]
            if out is None:
                out = {}
            out.update(zip(self._live_channels, vals))
            if self._stale:
                out.update(self._stale)
            return out
        vals = self.read(x)
        if noise is not None:
            self.add_noise(vals, noise.next())
        vals = vals.T
        if out is None:
            return dict(zip(self.channels, vals))
        out.update(zip(self.channels, vals))
        return out

    def noise(self, rngs, bias) -> NoiseStream:
        """The noise stream of one simulation (one Generator, ``bias (n_noisy,)``) or of several (a list of
        Generators, ``bias (n, n_noisy)``)."""
        return NoiseStream(self.noise_std, rngs, bias)

    def add_noise(self, values: np.ndarray, noise: np.ndarray) -> None:
        """In place: ``values[..., noisy] += noise`` (one tick of :meth:`NoiseStream.next`)."""
        if self._noisy_cols.size == values.shape[-1]:
            values += noise
        else:
            values[..., self._noisy_cols] += noise


#: ticks of noise drawn at a time: one Generator call per chunk instead of per tick (bounds the memory too)
NOISE_CHUNK_TICKS = 256


class NoiseStream:
    """``bias + std * z`` tick after tick, ``z`` drawn :data:`NOISE_CHUNK_TICKS` ticks at a time.

    A Generator fills an array sample by sample, so a chunk of ``(ticks, n_noisy)`` normals is the same stream
    as one ``standard_normal(n_noisy)`` per tick: chunking changes the cost, not a single reading. Ticks without
    noise (``noise_on``) simply do not call :meth:`next`.
    """

    def __init__(self, std: np.ndarray, rngs, bias: np.ndarray):
        self.std, self.rngs, self.bias = std, rngs, bias
        self._chunk = None
        self._rows = None
        self._k = NOISE_CHUNK_TICKS

    def _refill(self) -> None:
        shape = (NOISE_CHUNK_TICKS, self.std.size)
        if isinstance(self.rngs, np.random.Generator):
            z = self.rngs.standard_normal(shape)
        else:  # one stream per simulation: (ticks, n, n_noisy)
            z = np.stack([g.standard_normal(shape) for g in self.rngs], axis=1)
        self._chunk = self.bias + self.std * z
        self._rows = None
        self._k = 0

    def next(self) -> np.ndarray:
        """The next tick's noise, ``(n_noisy,)`` or ``(n, n_noisy)``."""
        if self._k == NOISE_CHUNK_TICKS:
            self._refill()
        self._k += 1
        return self._chunk[self._k - 1]

    def next_floats(self) -> list:
        """:meth:`next` of one simulation as a list of floats (the chunk is converted once, not every tick)."""
        if self._k == NOISE_CHUNK_TICKS:
            self._refill()
        if self._rows is None:
            self._rows = self._chunk.tolist()
        self._k += 1
        return self._rows[self._k - 1]
