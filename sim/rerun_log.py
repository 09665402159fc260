"""Rerun visual logs of runs: geometry from the MuJoCo model, body poses, rotor thrust arrows, wind, tendons
(the rope) and the run's time series, on a blueprint with one 3D view and one panel per signal group.

Everything is sent column-wise after the run (``send_columns``), never per tick, into an in-memory recording
that is then written to the ``.rrd`` file through :mod:`rotorlab.atomic` (no viewer is spawned): ``rerun FILE.rrd``
or ``rotorlab view RUN_DIR`` opens it. rerun's own file sink (``RecordingStream.save``) writes from a background
thread: a failed write (full disk, file-size limit) made its ``flush`` wait forever, uninterruptible by Ctrl-C,
and left a truncated file at the final path; here a failed write is an ``OSError`` in this thread and the final
path holds either the old recording or the complete new one.

Entity paths
------------
``world/bodies/<body>`` body pose (world frame, per tick) with its geoms below it (static);
``world/thrust`` one arrow per rotor (length ``THRUST_ARROW_M_PER_N`` per N); ``world/wind`` the wind vector at
the airframe (``WIND_ARROW_M_PER_MPS``); ``world/tendons/<name>`` the rope path when the model has one;
``signals/<group>/<column>`` the log columns, grouped by unit: ``angle`` (deg), ``rate`` (deg/s), ``command``
(%), ``angular_accel`` (deg/s^2), ``position`` (m), ``velocity`` (m/s), ``disturbance`` (everything else).
Timeline: ``sim_time`` (duration, s).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import mujoco
import numpy as np

from rotorlab import atomic
from rotorlab.errors import ConfigError
from rotorlab.logformat import read_parquet
from rotorlab.scenes import build_scene

# rerun is imported where a recording is written: a heavy import that only recordings need.

TIMELINE = "sim_time"
THRUST_ARROW_M_PER_N = 0.02
WIND_ARROW_M_PER_MPS = 0.2
GROUPS = {"deg": "angle", "deg/s": "rate", "%": "command", "deg/s^2": "angular_accel", "m": "position",
          "m/s": "velocity"}


def check_rrd_path(path) -> Path:
    """Fail early (before a run) when ``path`` cannot receive a recording: not ``.rrd``, a directory, or a folder
    that does not exist or is not writable."""
    p = Path(path)
    if p.suffix != ".rrd":
        raise ConfigError("a rerun recording is a .rrd file", field="--rerun", expected="a path ending in .rrd", got=str(p))
    if p.is_dir():
        raise ConfigError("the recording path is a directory", field="--rerun", expected="a file path", got=str(p))
    # a probe file is the only reliable test (permissions, read-only or virtual file systems, running as root)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=p.parent, prefix=f".{p.name}.", suffix=".probe"):
            pass
        if p.exists() and not os.access(p, os.W_OK):
            raise PermissionError(f"{p} is read-only")
    except OSError as exc:
        raise ConfigError(f"cannot write the recording there ({exc.strerror or exc})", field="--rerun",
                          expected="a writable location", got=str(p)) from None
    return p


def _quat_xyzw(wxyz) -> np.ndarray:
    q = np.asarray(wxyz, dtype=float)
    return q[..., [1, 2, 3, 0]]


def _geometry(rec, model, body_paths) -> None:
    """Log every visible geom of ``model`` as static rerun primitives, one batch per body and shape kind (each
    ``log`` call has a fixed cost far above that of a longer batch)."""
    import rerun as rr

    G = mujoco.mjtGeom
    batches: dict = {}
    for g in range(model.ngeom):
        rgba = model.geom_rgba[g]
        kind = model.geom_type[g]
        if rgba[3] <= 0:
            continue
        size = model.geom_size[g]
        pos = np.array(model.geom_pos[g], dtype=float)
        quat = model.geom_quat[g]
        if kind == G.mjGEOM_BOX:
            key, dims = "boxes", size.copy()
        elif kind == G.mjGEOM_PLANE:
            key, dims = "boxes", np.array([size[0] or 5.0, size[1] or 5.0, 0.001])
        elif kind == G.mjGEOM_SPHERE:
            key, dims = "ellipsoids", np.full(3, size[0])
        elif kind == G.mjGEOM_ELLIPSOID:
            key, dims = "ellipsoids", size.copy()
        elif kind == G.mjGEOM_CAPSULE:
            key, dims = "capsules", size[:2].copy()
            # MuJoCo's capsule is centred on its frame; rerun's starts at its origin and runs along its +z
            start = np.zeros(3)
            mujoco.mju_rotVecQuat(start, np.array([0.0, 0.0, -size[1]]), quat)
            pos = pos + start
        elif kind == G.mjGEOM_CYLINDER:
            key, dims = "cylinders", size[:2].copy()
        else:  # meshes, height fields: the shipped twins have none
            continue
        b = batches.setdefault((model.geom_bodyid[g], key), {"pos": [], "quat": [], "dims": [], "rgba": []})
        b["pos"].append(pos)
        b["quat"].append(_quat_xyzw(quat))
        b["dims"].append(dims)
        b["rgba"].append(np.round(rgba * 255).astype(np.uint8))
    for (body, key), b in batches.items():
        path, d = f"{body_paths[body]}/{key}", np.array(b["dims"])
        common = dict(quaternions=b["quat"], colors=b["rgba"])
        if key == "boxes":
            shape = rr.Boxes3D(half_sizes=d, centers=b["pos"], fill_mode="solid", **common)
        elif key == "ellipsoids":
            shape = rr.Ellipsoids3D(half_sizes=d, centers=b["pos"], fill_mode="solid", **common)
        elif key == "capsules":
            shape = rr.Capsules3D(radii=d[:, 0], lengths=2 * d[:, 1], translations=b["pos"], **common)
        else:
            shape = rr.Cylinders3D(radii=d[:, 0], lengths=2 * d[:, 1], centers=b["pos"], fill_mode="solid", **common)
        rec.log(path, shape, static=True)


class TableLog:
    """A run log read back from its Parquet file: what :func:`record_run` reads (``units`` and ``log[name]``)
    and the run's information (``meta``)."""

    def __init__(self, path):
        self._cols, units, self.meta = read_parquet(path)
        self.units = units or {c: "" for c in self._cols}

    def __getitem__(self, name):
        return self._cols[name]


def _log_columns(rec, log) -> dict:
    """Send every log column as a scalar time series; returns ``group -> [entity paths]``."""
    import rerun as rr

    t = np.asarray(log["t"], dtype=float)
    groups: dict = {}
    for name, unit in log.units.items():
        if name == "t":
            continue
        vals = np.asarray(log[name], dtype=float)
        if not np.any(np.isfinite(vals)):
            continue
        group = GROUPS.get(unit, "disturbance")
        path = f"signals/{group}/{name}"
        rec.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=t)], columns=rr.Scalars.columns(scalars=vals))
        groups.setdefault(group, []).append(path)
    return groups


def _log_poses(rec, poses) -> None:
    import rerun as rr

    t = poses.t
    idx = [rr.TimeColumn(TIMELINE, duration=t)]
    for b in range(1, poses.model.nbody):
        rec.send_columns(f"world/bodies/{_safe(poses.body_names[b])}", indexes=idx,
                         columns=rr.Transform3D.columns(translation=poses.xpos[:, b],
                                                        quaternion=_quat_xyzw(poses.xquat[:, b])))
    n, nr = poses.thrust_N.shape
    if nr:
        vec = poses.rotor_axis * (poses.thrust_N[:, :, None] * THRUST_ARROW_M_PER_N)
        rec.send_columns("world/thrust", indexes=idx,
                         columns=rr.Arrows3D.columns(origins=poses.rotor_pos.reshape(-1, 3),
                                                     vectors=vec.reshape(-1, 3)).partition([nr] * n))
        rec.log("world/thrust", rr.Arrows3D.from_fields(colors=[[230, 120, 40]]), static=True)
    if np.any(poses.wind):
        air = [i for i, nm in enumerate(poses.body_names) if nm.endswith("airframe")]
        origin = poses.xpos[:, air[0]] if air else np.zeros((n, 3))
        rec.send_columns("world/wind", indexes=idx,
                         columns=rr.Arrows3D.columns(origins=origin, vectors=poses.wind * WIND_ARROW_M_PER_MPS))
        rec.log("world/wind", rr.Arrows3D.from_fields(colors=[[60, 140, 230]]), static=True)
    for i in range(poses.model.ntendon):
        name = mujoco.mj_id2name(poses.model, mujoco.mjtObj.mjOBJ_TENDON, i) or f"tendon{i}"
        num = poses.tendon_wrapnum[:, i]
        if not np.any(num):
            continue
        pts = [poses.tendon_path[k, i, :num[k]] for k in range(n)]
        rec.send_columns(f"world/tendons/{_safe(name)}", indexes=idx,
                         columns=rr.LineStrips3D.columns(strips=pts).partition([1] * n))


def _safe(name: str) -> str:
    return name.replace("/", "_")


def record_run(result_or_log, path, *, scene: str | None = None, vehicle=None, info: dict | None = None,
               application_id: str = "rotorlab") -> Path:
    """Write a rerun recording of a run to ``path`` (``.rrd``) and return the path.

    Parameters
    ----------
    result_or_log : RunResult or RunLog
        A :class:`~rotorlab.sim.runner.RunResult` (with ``poses`` when run with ``record_poses=True``: the 3D
        scene is then animated) or a bare :class:`~rotorlab.sim.log.RunLog` (time series only, plus the static
        scene when ``scene`` and ``vehicle`` are given).
    path : str or Path
    scene, vehicle : optional
        Scene name and vehicle (name, path or VehicleSpec) for the static geometry when there are no poses;
        taken from ``result.info`` otherwise.
    info : dict, optional
        Run metadata (``run.json``); its scenario/vehicle/seed name the recording.
    """
    import rerun as rr
    import rerun.blueprint as rrb

    p = check_rrd_path(path)
    log = getattr(result_or_log, "log", result_or_log)
    if not hasattr(log, "units"):
        raise ConfigError(field="result_or_log", expected="a RunResult or a RunLog", got=type(result_or_log).__name__)
    poses = getattr(result_or_log, "poses", None)
    info = dict(info or getattr(result_or_log, "info", {}) or {})
    model = poses.model if poses is not None else None
    if model is None and (scene or info.get("scene")) and (vehicle or info.get("vehicle")):
        model = build_scene(scene or info["scene"], vehicle or info["vehicle"]).model
    name = "-".join(str(info[k]) for k in ("scenario", "vehicle", "seed") if k in info) or "run"
    rec = rr.RecordingStream(application_id, recording_id=name)
    mem = rec.memory_recording()
    try:
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if model is not None:
            body_paths = ["world"] + [
                f"world/bodies/{_safe(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or f'body{b}')}"
                for b in range(1, model.nbody)]
            _geometry(rec, model, body_paths)
        if poses is not None:
            _log_poses(rec, poses)
        groups = _log_columns(rec, log)
        units = {v: k for k, v in GROUPS.items()}
        panels = [rrb.TimeSeriesView(origin=f"signals/{g}", name=f"{g} [{units[g]}]" if g in units else g)
                  for g in groups]
        main = [rrb.Spatial3DView(origin="world", name="scene")] if model is not None else []
        rec.send_blueprint(rrb.Blueprint(rrb.Horizontal(*main, rrb.Vertical(*panels)) if main else rrb.Vertical(*panels),
                                         collapse_panels=True))
        rec.flush()
        data = mem.drain_as_bytes()
    finally:
        rec.disconnect()
    try:
        atomic.write_bytes(p, data)
    except OSError as exc:
        raise ConfigError(f"cannot write the recording ({exc.strerror or exc})", field="--rerun",
                          expected="a writable location with room for the file", got=str(p)) from None
    return p


__all__ = ["record_run", "check_rrd_path", "TableLog", "TIMELINE", "GROUPS"]
