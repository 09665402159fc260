"""Batched closed-loop runs: many simulations of one scene model stepped in-process by ``mujoco.batch.Batch``
under the flight software of the scalar runs flying them all at once (``FlightSoftware(..., n=n)``: one dispatch,
the loops of :mod:`rotorlab.sim.control.vector`).

One call of :func:`run_batch` runs ``n`` copies of a rig scenario (``setpoint``, ``gust``, ``rest`` on the
``pitch-rig`` or ``roll-rig``) that differ in seed, gains and, optionally, physical parameters. Each
simulation follows the scalar path of :func:`rotorlab.sim.runner.run_scenario` step for step:

* the model is the one :class:`~rotorlab.sim.simulator.Simulator` builds, every simulation starts from its
  reset state (hover keyframe, actuator delay lines filled with the trim: the whole ``mjSTATE_INTEGRATION``
  row, ``history`` included, is copied into every row of the batch);
* per control tick the batch takes the 20 physics steps of one control period in one call and then computes
  the position and velocity stages at the new state (``stage=mjSTAGE_VEL``), so the IMU is sampled at the
  tick as the scalar ``mj_step`` + ``mj_forward`` does;
* the IMU is the scalar simulator's :class:`~rotorlab.sim.sensors.SensorSuite` sampled over the batch's rows, its
  noise and bias from a ``numpy.random.Generator`` per simulation seeded like the scalar simulator's
  (``default_rng(seed)``: bias first, then one normal per noisy channel per noisy tick), so a batched run with
  noise is the scalar run with the same seed (the accelerometer is read but not used: the batch's forward pass
  stops at the velocity stage);
* rotor commands, wind (the scenario's gust plus any per-simulation mean wind) and the stop checks go through
  the simulator's own functions over the batch's rows (:func:`~rotorlab.sim.simulator.set_rotor_ctrl`,
  :func:`~rotorlab.sim.simulator.set_wind`: per-simulation ``opt.wind`` and body-axis wind on the rotor aero
  actuators; :data:`~rotorlab.sim.simulator.DIVERGENCE_WARNINGS` and
  :class:`~rotorlab.sim.simulator.StopCheck`).

Per-simulation physical variation (``vary``) uses the batch's per-simulation model fields: airframe mass and
inertia (followed by ``set_const``) and a steady wind per simulation.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import mujoco
import numpy as np
from mujoco.batch import Batch, SimulationError
from tqdm import tqdm

from rotorlab.errors import ConfigError
from rotorlab.gains import GainSet
from rotorlab.scenes import PHYSICS_DT_S, PREFIX
from rotorlab.sim import randomize, scenarios
from rotorlab.sim.disturbances.mean_wind import SampledWind, WindDisturbance, total_wind_ned, toward_ned
from rotorlab.sim.frames import NED_TO_ZUP, RAD2DEG, euler_deg_from_quats
from rotorlab.sim.runner import BASE_COLUMNS, check_duration, make_flight_software, resolve_gains
from rotorlab.sim.simulator import DIVERGENCE_WARNINGS, Simulator, diverged_reason, set_rotor_ctrl, set_wind
from rotorlab.vehicles import DEFAULT_VEHICLE, load_vehicle
from rotorlab.vehicles.bodies import airframe_inertial

#: scenes the batched runner supports (the rigs: cascade and open-loop modes without position hold)
SCENES = ("pitch-rig", "roll-rig")
#: the randomisation parameters (:mod:`rotorlab.sim.randomize`) the batch's per-simulation model fields can carry
VARY_KEYS = ("mass", "inertia", "wind")
#: log columns of the physics' ground truth (the others are the flight software's signals)
_TRUTH_COLUMNS = ("phi_true", "theta_true", "p_true", "q_true", "p_dot", "q_dot")


@dataclasses.dataclass
class BatchResult:
    """Traces and per-simulation data of a batched run.

    Attributes
    ----------
    scenario, vehicle, scene : str
    seeds : ndarray (n,) of int
    t : ndarray (n_ticks,)
        Tick times, s (common to all simulations).
    traces : dict name -> ndarray (n, n_ticks)
        Log columns (units as :data:`rotorlab.sim.runner.BASE_COLUMNS`); NaN after a simulation stopped.
    rows : ndarray (n,) of int
        Logged ticks of each simulation (``n_ticks`` unless it stopped early).
    stopped : list of str or None
        Why each simulation stopped early, or None.
    params : dict name -> ndarray (n, ...)
        Per-simulation physical parameters: ``mass_kg``, ``inertia_kgm2`` (n, 3), ``wind_ned_mps`` (n, 3).
    info : dict
        Scenario, options, durations, noise, gains names.
    """

    scenario: str
    vehicle: str
    scene: str
    seeds: np.ndarray
    t: np.ndarray
    traces: dict
    rows: np.ndarray
    stopped: list
    params: dict
    info: dict
    _ctx: object = dataclasses.field(repr=False, default=None)
    _setup: object = dataclasses.field(repr=False, default=None)

    @property
    def n(self) -> int:
        return len(self.seeds)

    def log(self, i: int) -> dict:
        """Simulation ``i``'s log as a dict of column arrays (``t`` included), trimmed to its rows: the shape of
        :class:`rotorlab.sim.log.RunLog` that the scenario metrics read."""
        k = int(self.rows[i])
        out = {"t": self.t[:k]}
        out.update({name: a[i, :k] for name, a in self.traces.items()})
        return out

    def metrics_of(self, i: int) -> dict:
        """The scenario's metrics of simulation ``i`` (the nested dict ``run_scenario`` puts in ``run.json``)."""
        fn = getattr(scenarios.get(self.scenario), "metrics", None)
        if fn is None:
            return {}
        ctx = dataclasses.replace(self._ctx, seed=int(self.seeds[i]))
        return fn(self.log(i), ctx, self._setup)

    @functools.cached_property
    def metrics(self) -> dict:
        """Metrics table: flattened metric name (``steps.0.overshoot_pct``) -> ndarray (n,), NaN where a
        simulation has no value (e.g. it stopped before that step). Computed on first access."""
        flat = [_flatten(self.metrics_of(i)) for i in range(self.n)]
        names = sorted({k for f in flat for k in f})
        return {k: np.array([_num(f.get(k)) for f in flat]) for k in names}


def _flatten(obj, prefix: str = "") -> dict:
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    if isinstance(obj, (list, tuple)):
        out = {}
        for k, v in enumerate(obj):
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    # labels (e.g. the scored axis) are not numbers: the table keeps numbers only
    return {} if isinstance(obj, str) else {prefix[:-1]: obj}


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _seeds(seeds, n: int) -> np.ndarray:
    if seeds is None:
        return np.arange(n)
    if np.ndim(seeds) == 0:
        return int(seeds) + np.arange(n)
    s = np.asarray(seeds).ravel()
    if s.size != n or not np.issubdtype(s.dtype, np.integer):
        raise ConfigError(field="seeds", expected=f"None, an int or {n} ints", got=f"{s.size} values of {s.dtype}")
    return s.astype(np.int64)


def _gain_sets(v, gains, n: int):
    """One GainSet for all simulations, or a list of n."""
    if gains is None or isinstance(gains, (GainSet, str)) or hasattr(gains, "__fspath__"):
        return resolve_gains(v, gains)
    sets = list(gains)
    if len(sets) != n:
        raise ConfigError(field="gains", expected=f"one gain set or {n} of them", got=len(sets))
    return [resolve_gains(v, g) for g in sets]


def _check_setup(name: str, setup: scenarios.Setup) -> None:
    why = None
    if setup.drive is not None:
        why = "drives the actuators itself (bench test)"
    elif setup.mode not in ("cascade", "open-loop"):
        why = f"uses the '{setup.mode}' mode"
    elif setup.controller:
        why = "flies its own controller in place of the cascade"
    elif setup.excitation or setup.schedule or setup.on_tick is not None or setup.extra_columns:
        why = "uses excitation, a gain schedule or scenario-specific logging"
    else:
        for d in setup.disturbances:
            if not isinstance(d, WindDisturbance) or isinstance(d, SampledWind):
                why = f"uses the '{d.name}' disturbance (only deterministic wind is batched)"
    if why:
        raise ConfigError(f"scenario '{name}' {why}, which the batched runner does not vectorise; "
                          "run it with rotorlab.sim.runner.run_scenario", field="scenario", got=name)


def _variation(vary: dict | None, seeds: np.ndarray, vehicle) -> tuple[dict, dict]:
    """Per-simulation parameters from :func:`rotorlab.sim.randomize.draw`, each with a Generator seeded by the
    simulation's seed alone (so a simulation's parameters do not depend on the batch it runs in). The airframe
    body's mass and inertia are those the MJCF builder gives the drawn vehicle
    (:func:`rotorlab.vehicles.bodies.airframe_inertial` of :func:`rotorlab.sim.randomize.apply`): the draw
    means the same here as in ``rotorlab montecarlo``, and the body is the one the draw kept rigid."""
    vary = dict(vary or {})
    for k in vary:
        if k in randomize.KEYS and k not in VARY_KEYS:
            raise ConfigError(f"'{k}' needs a model compiled per simulation; run it with rotorlab montecarlo",
                              field=f"vary.{k}", expected=f"one of {list(VARY_KEYS)}", got=k)
    draws = [randomize.draw(vehicle, vary, np.random.default_rng([int(s), 0x76617279]), PHYSICS_DT_S, keys=VARY_KEYS,
                            field="vary") for s in seeds]
    bodies = [airframe_inertial(randomize.apply(vehicle, d)) for d in draws]
    mass = np.array([b[0] for b in bodies])
    inertia = np.array([b[1] for b in bodies]).reshape(len(seeds), 3)
    wind = np.array([d.wind_speed_mps * toward_ned(d.wind_from_deg) for d in draws]).reshape(len(seeds), 3)
    return {"mass_kg": mass, "inertia_kgm2": inertia, "wind_ned_mps": wind}, randomize.check_spreads(vary, VARY_KEYS,
                                                                                                       "vary")


def run_batch(scenario: str, vehicle=DEFAULT_VEHICLE, n: int = 1, *, gains=None, seeds=None, vary: dict | None = None,
              duration_s: float | None = None, scene: str | None = None, nthread: int = 0,
              options: dict | None = None, sensor_noise: bool | None = None, progress: bool = False) -> BatchResult:
    """Run ``n`` closed-loop simulations of a rig scenario in one ``mujoco.batch.Batch``.

    Parameters
    ----------
    scenario : str
        ``setpoint``, ``gust`` or ``rest`` (scenarios whose flight software is the attitude cascade or the
        open-loop supervisor, with deterministic wind at most).
    vehicle : str, path or VehicleSpec
    n : int
        Number of simulations.
    gains : GainSet, str, path or None, or a sequence of n of them
        Common gains, or one set per simulation.
    seeds : None, int or sequence of n ints
        Seeds of the simulations (IMU noise and bias as the scalar simulator with that seed; parameter
        variation). None: ``0 .. n-1``; an int ``s``: ``s .. s+n-1``.
    vary : dict, optional
        ``{'mass': s, 'inertia': s, 'wind': s_mps}``, drawn as everywhere in rotorlab
        (:mod:`rotorlab.sim.randomize`): the vehicle's mass and each principal inertia times factors uniform in
        ``[1 - s, 1 + s]`` (the airframe body takes them less the IMU board's and rotor discs' share, as the
        MJCF builder does), a steady horizontal wind of speed uniform in ``[0, s_mps]`` from a uniform direction,
        added to the scenario's.
    duration_s : float, optional
        Run length, s (default the scenario's).
    scene : str, optional
        ``pitch-rig`` (default of the rig scenarios) or ``roll-rig``.
    nthread : int
        Batch threads (0: all CPUs).
    options : dict, optional
        Scenario options, as for ``run_scenario``.
    sensor_noise : bool, optional
        IMU noise on/off (default: the scenario's).
    progress : bool
        tqdm progress bar over the ticks.
    """
    if not (isinstance(n, (int, np.integer)) and n >= 1):
        raise ConfigError(field="n", expected="a number of simulations >= 1", got=n)
    n = int(n)
    mod, scene = scenarios.get_with_scene(scenario, scene)
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    if scene not in SCENES:
        raise ConfigError("the batched runner runs the rig scenes", field="scene", expected=list(SCENES), got=scene)
    duration_s = float(duration_s if duration_s is not None else mod.DURATION_S)
    n_ticks = check_duration(duration_s, v.control_dt_s, logs=n)
    seeds = _seeds(seeds, n)
    gsets = _gain_sets(v, gains, n)
    ctx = scenarios.Context(vehicle=v, scene=scene, gains=gsets if isinstance(gsets, GainSet) else gsets[0],
                            seed=int(seeds[0]), duration_s=duration_s, options=dict(options or {}))
    setup = mod.setup(ctx)
    _check_setup(scenario, setup)
    noise = setup.sensor_noise if sensor_noise is None else bool(sensor_noise)

    # the scalar simulator builds the model and its reset state: the batch starts every simulation from it
    sim = Simulator(scene, v, seed=0, sensor_noise=False, disturbances=setup.disturbances)
    m, d0 = sim.model, sim.data
    airframe = m.body(f"{PREFIX}airframe").id
    params, vary_d = _variation(vary, seeds, v)
    row = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d0, row, mujoco.mjtState.mjSTATE_INTEGRATION)
    batch = Batch(m, nsim=n, nthread=nthread)
    if batch.nstate != row.size:
        raise RuntimeError(f"mujoco.batch rows hold {batch.nstate} numbers, mjSTATE_INTEGRATION {row.size}")
    batch.state[:] = row
    if vary_d.get("mass") or vary_d.get("inertia"):
        batch.expand("body_mass")[:, airframe] = params["mass_kg"]
        batch.expand("body_inertia")[:, airframe, :] = params["inertia_kgm2"]
        batch.set_const()
    # live views; a derived field is filled by the calls after its binding, so bind before the first forward
    sd, ctrl, qpos = batch.bind("sensordata"), batch.bind("ctrl"), batch.bind("qpos")
    xquat, xmat, cvel = batch.bind("xquat"), batch.bind("xmat"), batch.bind("cvel")
    time = batch.bind("time")
    stage_vel = int(mujoco.mjtStage.mjSTAGE_VEL)
    batch.forward(stage=stage_vel)

    # the run's flight software, as run_scenario builds it, flying the n simulations at once
    dt = sim.control_dt_s
    fs = make_flight_software(v, gsets, setup, dt, n=n)
    stops, thrust, spinup, aero = sim.stops, sim.thrust_ids, sim.spinup_ids, sim.aero_ids
    n_thrust = len(sim.scene.thrust_actuators)

    # IMU noise: per-simulation generators seeded as Simulator.reset seeds its own
    imu = sim.imu
    rngs = [np.random.default_rng(int(s)) for s in seeds]
    stream = imu.noise(rngs, np.array([imu.draw_bias(g) if noise else np.zeros(imu.n_noisy) for g in rngs]))

    # wind: the scenario's (common) plus each simulation's steady wind
    wind_dists = list(setup.disturbances)
    wind_sim_zup = params["wind_ned_mps"] * NED_TO_ZUP
    windy = bool(wind_dists) or bool(np.any(wind_sim_zup))
    opt_wind = batch.expand("opt.wind") if windy else None

    columns = dict(BASE_COLUMNS)
    for dist in wind_dists:
        columns.update(dist.columns)
    tr = {c: np.full((n_ticks, n), np.nan) for c in columns}
    fs_columns = [c for c in BASE_COLUMNS if c not in _TRUTH_COLUMNS]
    t_log = np.full(n_ticks, np.nan)
    rows = np.full(n, n_ticks)
    stopped: list = [None] * n
    active = np.ones(n, dtype=bool)
    ids = None  # all simulations while none has stopped
    noise_on = setup.noise_on

    for k in tqdm(range(n_ticks), desc="simulating batch", unit="tick", disable=not progress, leave=False):
        i0 = int(np.argmax(active))
        t = float(time[i0])
        t_log[k] = t
        # ---- the scalar loop's tick (rotorlab.sim.runner): measure, flight software, rotor commands
        meas = imu.sample(sd, stream if noise and (noise_on is None or noise_on(t)) else None)
        out = fs.step(t, meas)
        set_rotor_ctrl(ctrl, out["rotor_pct"][:, :n_thrust], v, thrust, spinup)
        # ---- ground truth and log
        att_true = euler_deg_from_quats(xquat[:, airframe])
        R = xmat[:, airframe].reshape(n, 3, 3)
        w_loc = np.einsum("nji,nj->ni", R, cvel[:, airframe, 0:3])
        for name in fs_columns:
            tr[name][k] = out[name]
        tr["phi_true"][k], tr["theta_true"][k] = att_true[:, 0], att_true[:, 1]
        tr["p_true"][k], tr["q_true"][k] = w_loc[:, 0] * RAD2DEG, -w_loc[:, 1] * RAD2DEG
        # ---- wind at the tick (Simulator.tick: the disturbances' sum, then set_wind)
        if windy:
            w = total_wind_ned(wind_dists, t) * NED_TO_ZUP + wind_sim_zup
            if wind_dists:
                w_ned = w * NED_TO_ZUP
                tr["wind_u"][k], tr["wind_v"][k], tr["wind_w"][k] = w_ned.T
            set_wind(opt_wind, ctrl, xmat[:, airframe], w, aero)
        # ---- physics: one control period, sensors at the tick
        failed = np.zeros(n, dtype=bool)
        try:
            batch.step(ids, nstep=sim.n_substeps, stage=stage_vel)
        except SimulationError as exc:
            for i in exc.ids:
                stopped[int(i)] = f"MuJoCo error at t = {t:.3f} s: {batch.error(int(i))}"
                failed[int(i)] = True
        # ---- checks (Simulator.check: MuJoCo's divergence warnings, then StopCheck; the rigs read qpos alone),
        # vectorised to find the rows that stop, whose reasons are then formed one by one
        bad = np.zeros(n, dtype=bool)
        for wi in DIVERGENCE_WARNINGS:
            bad |= batch.warning[:, int(wi), 0] > 0
        t_next = t + dt
        new = []
        for i in np.flatnonzero(active & (failed | bad | stops.rig_hits(qpos))):
            if stopped[i] is None:
                stopped[i] = diverged_reason(t_next) if bad[i] else stops.reason(qpos[i], None, None, t_next)
            if stopped[i] is not None:
                new.append(i)
        if new:
            rows[new] = k + 1
            active[new] = False
            if not active.any():
                break
            ids = np.flatnonzero(active)

    # derived columns, as the scalar loop forms them tick by tick
    for rate, acc in (("p_true", "p_dot"), ("q_true", "q_dot")):
        x = tr[rate]
        tr[acc][0] = 0.0
        tr[acc][1:] = (x[1:] - x[:-1]) / dt
    traces = {}
    kk = np.arange(n_ticks)[:, None]
    for name, a in tr.items():
        a[kk >= rows[None, :]] = np.nan
        traces[name] = np.ascontiguousarray(a.T)
    info = {"scenario": scenario, "vehicle": v.name, "scene": scene, "duration_s": duration_s, "n": n,
            "control_dt_s": dt, "physics_dt_s": float(m.opt.timestep), "sensor_noise": noise,
            "options": ctx.options, "vary": vary_d, "nthread": batch.nthread,
            "gains": gsets.name if isinstance(gsets, GainSet) else [g.name for g in gsets]}
    return BatchResult(scenario, v.name, scene, seeds, t_log, traces, rows, stopped, params, info, ctx, setup)


__all__ = ["BatchResult", "run_batch", "SCENES", "VARY_KEYS"]
