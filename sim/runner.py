"""Headless runs: scenario + vehicle + gains -> simulator + flight software -> log, metrics, run folder."""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path

from tqdm import tqdm

from rotorlab import atomic, autopilots
from rotorlab.errors import ConfigError
from rotorlab.gains import GainSet, load_gains
from rotorlab.scenes import PHYSICS_DT_S
from rotorlab.sim import scenarios
from rotorlab.sim.control.autopilot import AutopilotController, AutopilotSpec
from rotorlab.sim.control.flight_software import FlightSoftware
from rotorlab.sim.control.position import PositionGains
from rotorlab.sim.control.statespace import StateSpaceController, as_controller_spec
from rotorlab.sim.log import RunLog, write_run
from rotorlab.sim.poses import PoseTrack
from rotorlab.sim.simulator import Simulator, vehicle_mixer
from rotorlab.vehicles import DEFAULT_VEHICLE, gains_path, load_vehicle, vehicle_provenance
from rotorlab.vehicles.generic import baseline_gains

# Standard log columns (flight-software units); the pitch channel is named as the papers name it.
BASE_COLUMNS = {
    "theta": "deg", "theta_ref": "deg", "q": "deg/s", "q_ref": "deg/s", "u_lon": "%",
    "phi": "deg", "phi_ref": "deg", "p": "deg/s", "p_ref": "deg/s", "u_lat": "%",
    "psi": "deg", "r": "deg/s", "u_yaw": "%", "u_col": "%",
    "q_dot": "deg/s^2", "p_dot": "deg/s^2",
    "theta_true": "deg", "phi_true": "deg", "q_true": "deg/s", "p_true": "deg/s",
}
FLIGHT_COLUMNS = {"x": "m", "y": "m", "z": "m", "vx": "m/s", "vy": "m/s", "vz": "m/s", "x_ref": "m", "y_ref": "m",
                  "z_ref": "m"}


@dataclasses.dataclass
class RunResult:
    log: RunLog
    info: dict
    out_dir: Path | None
    stopped: str | None  # why the run stopped early, or None
    poses: object = None  # rotorlab.sim.poses.PoseTrack with run_scenario(record_poses=True)
    #: wall-clock seconds: ``build_s`` (model, simulator, flight software), ``sim_s`` (the closed loop),
    #: ``score_s`` (metrics and writing); kept out of ``info`` so run.json stays bit-identical per seed
    timing: dict = dataclasses.field(default_factory=dict)

    @property
    def metrics(self) -> dict:
        return self.info.get("metrics", {})


def resolve_gains(vehicle, gains) -> GainSet | None:
    """``gains``: a GainSet, a path to a TOML, a shipped set name, or None (the vehicle's ``standard``)."""
    if isinstance(gains, GainSet):
        return gains
    if gains is None:
        gains = "standard"
    p = Path(str(gains))
    if p.suffix == ".toml" and p.exists():
        return load_gains(p)
    if p.suffix == ".toml":
        raise ConfigError("gains file not found", file=p)
    # the sets beside the vehicle's own file, never looked up by its name (rotorlab.vehicles.gains_dir)
    return load_gains(gains_path(vehicle, str(gains)))


def _specs(controller) -> list:
    """``controller`` as the list of its specs (one spec, a file, or a list of them)."""
    return list(controller) if isinstance(controller, (list, tuple)) else [controller]


def _run_gains(vehicle, gains, controller) -> GainSet | None:
    """The cascade gains of a run (:func:`resolve_gains`). Where an autopilot's laws fly the attitude, the
    cascade is off (:func:`add_controllers`) and its gains are never read, so a vehicle with no gain set of its
    own (an own vehicle from ``rotorlab vehicle new``, a calibrated twin) flies without one: the flight software
    still holds a cascade, the hand-designed baseline of :func:`rotorlab.vehicles.generic.baseline_gains`."""
    if gains is None and any(isinstance(s, AutopilotSpec) for s in _specs(controller)):
        try:
            return resolve_gains(vehicle, None)
        except ConfigError:
            return baseline_gains(vehicle, name="idle (an autopilot flies)")
    return resolve_gains(vehicle, gains)


def make_flight_software(vehicle, gains: GainSet, setup: scenarios.Setup, dt: float | None = None,
                         controller=None, n: int | None = None) -> FlightSoftware:
    """The flight software of a run at ``dt`` (default: the vehicle's rate), with the discrete controllers
    ``controller`` (:func:`controller_plugins`) in place of the cascade on the commands they set; with ``n``, of
    ``n`` simulations at once (:func:`rotorlab.sim.batch.run_batch`; ``gains`` one GainSet or n of them)."""
    dt = vehicle.control_dt_s if dt is None else dt
    pos = PositionGains.for_vehicle(vehicle.mass_kg, vehicle.hover_collective_pct, vehicle.thrust_exponent)
    fs = FlightSoftware(
        gains, vehicle_mixer(vehicle), dt=dt, mode=setup.mode, limits=setup.limits(vehicle), position_gains=pos,
        open_loop_axes=setup.open_loop_axes, schedule=setup.schedule or None, reference=setup.reference,
        excitation=setup.excitation or None, altitude_hold=setup.altitude_hold, n=n,
    )
    if controller is not None:
        add_controllers(fs, controller)
    if setup.rate_excitation is not None:
        aps = [pl for pl in fs.plugins if isinstance(pl, AutopilotController)]
        if not aps:
            raise ConfigError("this scenario excites an autopilot's rate set-point", field="controller",
                              expected="an autopilot's laws (px4:PARAMS or ardupilot:PARAMS)",
                              got=controller if controller is not None else "the built-in cascade")
        for pl in aps:
            pl.rate_excitation = setup.rate_excitation
    return fs


def add_controllers(fs: FlightSoftware, controller) -> None:
    """Fly ``controller`` (:func:`controller_plugins`) in ``fs``; an autopilot's laws replace the built-in cascade
    (:attr:`FlightSoftware.attitude_by_plugin`), the command excitation added to their output."""
    plugins = controller_plugins(controller, fs)
    fs.plugins.extend(plugins)
    for pl in plugins:
        if isinstance(pl, AutopilotController):
            fs.attitude_by_plugin = pl.add_commands = True


def controller_plugins(controller, fs: FlightSoftware) -> list:
    """Plug-ins for ``controller``: a :class:`~rotorlab.sim.control.statespace.ControllerSpec`, a controller
    file, an :class:`~rotorlab.sim.control.autopilot.AutopilotSpec` (an autopilot's own laws on all three axes, at
    the flight-software rate), or a list of them (e.g. one per axis). Each sees the flight software's saturation of
    the commands it sets, so an anti-windup compensator acts on exactly the part the flight software cuts off."""
    limits = {"u_lat": fs.u_limit_pct, "u_lon": fs.u_limit_pct, "u_yaw": fs.yaw_u_limit_pct}
    seen, out = set(), []
    for obj in _specs(controller):
        if isinstance(obj, AutopilotSpec):
            plugin = AutopilotController(obj, fs.dt, fs.u_limit_pct, fs.yaw_u_limit_pct)
            outputs = plugin.outputs
        else:
            spec = as_controller_spec(obj)
            outputs = spec.outputs
            plugin = StateSpaceController(spec, fs.dt, [limits.get(o, float("inf")) for o in spec.outputs])
        clash = seen & set(outputs)
        if clash:
            raise ConfigError("two controllers set the same command", field="controller",
                              expected="each command set by at most one controller", got=sorted(clash))
        seen |= set(outputs)
        out.append(plugin)
    return out


def autopilot_dt_s(controller, vehicle_dt_s: float, physics_dt_s: float) -> float:
    """The flight-software period of a run: the loop period of an autopilot's parameters when they set it
    (IMU_GYRO_RATEMAX, SCHED_LOOP_RATE) and it is a whole number of physics steps, else the vehicle's. A loop rate
    left at its default does not count (PX4's and ArduPilot's 400 Hz is 2.5 steps of 1 ms); run.json records the
    rate flown and the parameters' rate."""
    for spec in _specs(controller):
        if isinstance(spec, AutopilotSpec):
            ap = autopilots.get(spec.autopilot)
            name = ap.LOOP_RATE_PARAM
            if name in spec.defaulted:
                continue
            dt = 1.0 / ap.loop_hz(spec.params)
            n = dt / physics_dt_s
            if abs(n - round(n)) < 1e-9 and round(n) >= 1:
                return dt
    return vehicle_dt_s


INTERRUPTED = "interrupted (Ctrl-C)"
# Memory a run holds per control tick: the log's row (at most this many float64 columns) and, with
# record_poses, every body pose, rotor thrust and tendon path (a few KiB for the shipped scenes). Checked
# before anything is allocated: `--duration 1e7` asked for 78 GiB and died in numpy after minutes.
LOG_BYTES_PER_TICK = 64 * 8
POSE_BYTES_PER_TICK = 4096


def memory_budget_bytes() -> int:
    """Half of the memory the OS reports available now (MemAvailable; physical memory where that is unknown)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024 // 2
    except OSError:
        pass
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def check_duration(duration_s, control_dt_s: float, record_poses: bool = False, logs: int = 1) -> int:
    """Number of control ticks of a run of ``duration_s``; a ConfigError unless it is finite, at least one
    control step, and its log (``logs`` of them: the batched runner's simulations) fits in
    :func:`memory_budget_bytes`."""
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(field="duration", expected="a finite duration > 0 s", got=duration_s)
    n_ticks = int(round(duration_s / control_dt_s))
    if n_ticks < 1:
        raise ConfigError(field="duration", expected=f"at least one control step ({control_dt_s} s)", got=duration_s)
    per_tick = (LOG_BYTES_PER_TICK + (POSE_BYTES_PER_TICK if record_poses else 0)) * logs
    need, budget = (n_ticks + 1) * per_tick, memory_budget_bytes()
    if need > budget:
        raise ConfigError(f"the log of {n_ticks} ticks needs about {need / 2**30:.3g} GiB, over half the "
                          f"available memory ({budget / 2**30:.3g} GiB)", field="duration",
                          expected=f"at most about {budget // per_tick * control_dt_s:.4g} s", got=duration_s)
    return n_ticks


def run_scenario(name: str, vehicle=DEFAULT_VEHICLE, *, scene: str | None = None, gains=None, seed: int = 0,
                 duration_s: float | None = None, out=None, options: dict | None = None, progress: bool = False,
                 sensor_noise: bool | None = None, record_poses: bool = False, controller=None,
                 interruptible: bool = False) -> RunResult:
    """Run scenario ``name`` headless; write ``log.parquet`` and ``run.json`` into ``out`` when given.

    ``controller``: discrete controllers flown in place of the cascade on the commands they set (a
    :class:`~rotorlab.sim.control.statespace.ControllerSpec`, a ``.json``/``.toml`` controller file, or a list of
    them); the flight software runs at the vehicle's rate (``VehicleSpec.control_dt_s``), or at the loop rate of an
    autopilot's parameters (:func:`autopilot_dt_s`).

    A run that diverges (NaN, MuJoCo warning, rig stop, crash) stops early, keeps the log written so far and
    records the reason in ``run.json`` under ``stopped``. ``record_poses`` keeps the body poses, rotor thrusts,
    wind and tendon paths of every tick in ``RunResult.poses`` (for :func:`rotorlab.sim.rerun_log.record_run`).
    ``interruptible`` (the CLI): Ctrl-C stops the run like a divergence, with ``stopped = INTERRUPTED``, and the
    partial log is written; library callers and pipeline workers get the KeyboardInterrupt instead, so an
    interrupted run can never pass for a finished one.
    """
    t_start = time.perf_counter()
    mod, scene = scenarios.get_with_scene(name, scene)
    v = vehicle if hasattr(vehicle, "rotor") else load_vehicle(vehicle)
    duration_s = float(duration_s if duration_s is not None else mod.DURATION_S)
    control_dt_s = autopilot_dt_s(controller, v.control_dt_s, PHYSICS_DT_S)
    n_ticks = check_duration(duration_s, control_dt_s, record_poses)
    if out is not None:  # before the simulation: a read-only folder must not cost the run
        atomic.check_writable_dir(out, "run folder")
    gs = _run_gains(v, gains, controller)
    ctx = scenarios.Context(vehicle=v, scene=scene, gains=gs, seed=seed, duration_s=duration_s,
                            options=dict(options or {}), dt_s=control_dt_s)
    setup = mod.setup(ctx)
    noise = setup.sensor_noise if sensor_noise is None else sensor_noise
    sim = Simulator(scene, v, seed=seed, sensor_noise=noise, disturbances=setup.disturbances,
                    control_dt_s=control_dt_s)
    fs = make_flight_software(v, gs, setup, sim.control_dt_s, controller if controller is not None else
                              (setup.controller or None))
    columns = {} if setup.drive is not None else dict(BASE_COLUMNS)
    if scene == "free-flight":
        columns.update(FLIGHT_COLUMNS)
    for dist in setup.disturbances:
        columns.update(dist.columns)
    columns.update(setup.extra_columns)
    log = RunLog(columns, n_ticks + 1)
    sim.forces_at_tick = _reads_forces(sim, setup, fs, columns, record_poses)
    poses = None
    if record_poses:
        poses = PoseTrack(sim, n_ticks + 1)
    t_loop = time.perf_counter()
    try:
        stopped = _loop(sim, fs, log, n_ticks, setup, progress, poses)
    except KeyboardInterrupt:
        if not interruptible:
            raise
        stopped = INTERRUPTED
    t_done = time.perf_counter()
    info = {
        "scenario": name, "vehicle": v.name, "vehicle_source": vehicle_provenance(v), "scene": scene, "seed": seed, "duration_s": duration_s,
        "gains": gs.name if gs else None, "gain_values": _gain_dict(gs), "control_dt_s": sim.control_dt_s,
        "physics_dt_s": float(sim.model.opt.timestep), "sensor_noise": noise, "stopped": stopped,
        "options": ctx.options, "notes": setup.notes,
    }
    ctl = [pl.spec for pl in fs.plugins if isinstance(pl, StateSpaceController)]
    if ctl:
        info["controller"] = [{"name": c.name, "dt_s": c.dt_s, "inputs": list(c.inputs), "outputs": list(c.outputs),
                               "states": c.nstates, "antiwindup": c.antiwindup is not None} for c in ctl]
    aps = [pl for pl in fs.plugins if isinstance(pl, AutopilotController)]
    if aps:
        info.setdefault("controller", []).extend(
            {"name": pl.spec.name, "autopilot": pl.spec.autopilot, "dt_s": pl.dt, "outputs": list(pl.outputs),
             "loop_hz": 1.0 / pl.dt, "params_loop_hz": pl.ap.loop_hz(pl.spec.params),
             "params": dict(pl.spec.params), "defaulted": list(pl.spec.defaulted)} for pl in aps)
    metrics_fn = getattr(mod, "metrics", None)
    info["metrics"] = metrics_fn(log, ctx, setup) if metrics_fn else {}
    out_dir = write_run(out, log, info) if out is not None else None
    timing = {"build_s": t_loop - t_start, "sim_s": t_done - t_loop, "score_s": time.perf_counter() - t_done}
    return RunResult(log, info, out_dir, stopped, poses.trimmed() if poses is not None else None, timing)


def _reads_forces(sim: Simulator, setup, fs: FlightSoftware, columns: dict, record_poses: bool) -> bool:
    """Whether anything of this run reads acceleration-stage data at the ticks (:attr:`Simulator.forces_at_tick`):
    the accelerometer's channels logged or a controller's input, a pose recording (the rotor thrusts), or code
    the runner cannot see into (a bench drive, a scenario's per-tick callback, a plug-in without a declared
    input list). The cascade, the position and altitude holds fly on attitudes, rates and positions only."""
    if setup.drive is not None or setup.on_tick is not None or record_poses:
        return True
    reads = set(columns)
    for pl in fs.plugins:
        spec = getattr(pl, "spec", None)
        if spec is None:
            return True
        reads.update(spec.inputs)
    return not reads.isdisjoint(sim.acc_channels)


def _loop(sim: Simulator, fs: FlightSoftware, log: RunLog, n_ticks: int, setup, progress: bool,
          poses=None) -> str | None:
    dt = sim.control_dt_s
    p_prev, q_prev, _ = sim.true_rates_dps()
    on_tick = setup.on_tick
    it = tqdm(range(n_ticks), desc="simulating", unit="tick", leave=False) if progress else range(n_ticks)
    drive = setup.drive
    noise_on, noise = setup.noise_on, sim.sensor_noise
    # the methods of every tick bound once (each lookup makes a bound method, every tick)
    measure, step, set_rotor_commands = sim.measure, fs.step_signals, sim.set_rotor_commands
    true_attitude_deg, true_rates_dps, append, tick, check = (sim.true_attitude_deg, sim.true_rates_dps, log.append,
                                                              sim.tick, sim.check)
    disturbances = sim.disturbances
    # one signal dict for the whole run: measured into, flown by the flight software, completed with the truth
    # and the scenario's columns and logged, tick after tick, so a tick builds and copies no dict (every writer
    # sets the same keys every tick, so nothing of an earlier tick is logged)
    sig = {}
    for _ in it:
        t = sim.time
        if noise_on is not None:
            sim.sensor_noise = noise and noise_on(t)
        if drive is not None:  # bench tests: the scenario drives the actuators itself, no flight software
            append(t, drive(sim, t))
            tick(controls_only=True)
            continue
        set_rotor_commands(step(t, measure(sig)))
        sig["phi_true"], sig["theta_true"], _ = true_attitude_deg()
        p_true, q_true, _ = true_rates_dps()
        sig["p_true"], sig["q_true"] = p_true, q_true
        sig["p_dot"], sig["q_dot"] = (p_true - p_prev) / dt, (q_true - q_prev) / dt
        p_prev, q_prev = p_true, q_true
        if on_tick is not None:
            sig.update(on_tick(sim, sig))
        for dist in disturbances:
            sig.update(dist.values(sim))
        append(t, sig)
        if poses is not None:
            poses.record(sim)
        tick(controls_only=True)  # the loop writes nothing into MuJoCo between ticks but the rotor commands
        reason = check()
        if reason:
            return reason
    return None


def _gain_dict(gs: GainSet | None) -> dict | None:
    if gs is None:
        return None
    return {ax: {"outer": g.outer.as_dict(), "inner": g.inner.as_dict()} for ax, g in gs.axes.items()}


__all__ = ["RunResult", "run_scenario", "check_duration", "INTERRUPTED", "resolve_gains", "make_flight_software",
           "controller_plugins", "add_controllers", "BASE_COLUMNS"]
