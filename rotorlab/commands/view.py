"""``rotorlab view RUN_DIR|FILE.rrd [--print]``: open a run's rerun recording in the rerun viewer.

A run folder without a recording (a run made without ``--rerun``) gets ``recording.rrd`` written from its
``log.parquet`` and ``run.json``: the signals and the static scene, without the animated poses (those need the
run itself, ``rotorlab run ... --rerun FILE.rrd``).
"""

from __future__ import annotations

from pathlib import Path

RECORDING = "recording.rrd"


def add_parser(sub):
    p = sub.add_parser("view", help="open a run's rerun recording (.rrd) in the rerun viewer")
    p.add_argument("path", help="run folder (with a .rrd, or log.parquet + run.json) or a .rrd file")
    p.add_argument("--print", dest="print_only", action="store_true",
                   help="only print the viewer command, do not start the viewer")
    return p


class _TableLog:
    """The two things :func:`record_run` reads from a log (``units`` and ``log[name]``), over a Parquet table."""

    def __init__(self, path: Path):
        import pyarrow.parquet as pq

        from rotorlab.logformat import decode_metadata

        tbl = pq.read_table(path)
        units, _ = decode_metadata(tbl.schema.metadata)
        self.units = units or {c: "" for c in tbl.column_names}
        self._cols = {c: tbl.column(c).to_numpy() for c in tbl.column_names}

    def __getitem__(self, name):
        return self._cols[name]


def find_recording(path) -> Path:
    """The ``.rrd`` to open for ``path``, writing ``recording.rrd`` from the run's log when there is none."""
    import json

    from rotorlab.cli import CLIError

    p = Path(path)
    if p.suffix == ".rrd":
        if not p.is_file():
            raise CLIError(f"recording {p} not found")
        return p
    if not p.is_dir():
        raise CLIError(f"{p} is neither a run folder nor a .rrd file")
    found = sorted(p.glob("*.rrd"), key=lambda f: (f.name != RECORDING, f.name))
    if found:
        return found[0]
    log_path, info_path = p / "log.parquet", p / "run.json"
    if not log_path.is_file():
        raise CLIError(f"{p} has no .rrd recording and no log.parquet to make one from")
    from rotorlab.errors import RotorlabError
    from rotorlab.sim.rerun_log import record_run

    info = json.loads(info_path.read_text()) if info_path.is_file() else {}
    try:
        return record_run(_TableLog(log_path), p / RECORDING, info=info)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None


def run(args) -> int:
    import shlex
    import shutil
    import subprocess

    rrd = find_recording(args.path)
    exe = shutil.which("rerun")
    cmd = [exe or "rerun", str(rrd)]
    if args.print_only or exe is None:
        if exe is None:
            print("the rerun viewer is not on PATH (pip install rerun-sdk provides it); open the recording with:")
        print(shlex.join(cmd))
        return 0
    print(f"opening {rrd} in the rerun viewer")
    rc = subprocess.run(cmd, check=False).returncode
    if rc != 0:
        print(f"the viewer exited with status {rc}; open the recording with: {shlex.join(cmd)}")
    return rc
