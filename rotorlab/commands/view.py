"""Open rerun recordings (.rrd) of a run in the rerun viewer: a native window where there is a display, the
web viewer served over HTTP with --web, or (on a machine without a display) instructions to do either.

PATH is a .rrd file, a run folder (rotorlab run --out DIR; a folder without a recording gets recording.rrd
written from its log.parquet and run.json: the signals and the static scene, without the animated poses,
which need rotorlab run ... --rerun FILE.rrd) or a pipeline folder (the .rrd files in its report/recordings, one per
validation run, all opened together).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from rotorlab.cli import CLIError, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.

RECORDING = "recording.rrd"
#: where a pipeline run folder keeps its recordings, relative to the folder
PIPELINE_RECORDINGS = ("report/recordings", "recordings")


def add_parser(sub):
    p = sub.add_parser("view", help="open a run's rerun recording(s) in the rerun viewer (native or web)",
                       **describe(__doc__))
    p.add_argument("path", help="run folder, pipeline folder or .rrd file")
    p.add_argument("--web", action="store_true",
                   help="serve the web viewer over HTTP instead of opening a window (works without a display; "
                        "Ctrl-C stops it)")
    p.add_argument("--web-port", type=int, default=9090, help="HTTP port of the web viewer (--web)")
    p.add_argument("--grpc-port", type=int, default=9876, help="port of the rerun data server the web viewer reads")
    p.add_argument("--print", dest="print_only", action="store_true",
                   help="only print the viewer command, do not start the viewer")
    return p


def find_recordings(path) -> list[Path]:
    """The ``.rrd`` files to open for ``path``: the file itself, a run folder's recording (written from its
    log when there is none), or a pipeline folder's ``report/recordings/*.rrd``."""
    p = Path(path)
    if p.suffix == ".rrd":
        if not p.is_file():
            raise CLIError(f"recording {p} not found")
        return [p]
    if not p.is_dir():
        raise CLIError(f"{p} is neither a run folder nor a .rrd file")
    found = sorted(p.glob("*.rrd"), key=lambda f: (f.name != RECORDING, f.name))
    if found:
        return found[:1] if (p / RECORDING).is_file() else found
    for sub in PIPELINE_RECORDINGS:
        found = sorted((p / sub).glob("*.rrd"))
        if found:
            return found
    log_path, info_path = p / "log.parquet", p / "run.json"
    if not log_path.is_file():
        raise CLIError(f"{p} has no .rrd recording (looked in {p}, " +
                       ", ".join(str(p / s) for s in PIPELINE_RECORDINGS) + ") and no log.parquet to make one from")
    from rotorlab.config import read_json_object
    from rotorlab.sim.rerun_log import TableLog, record_run

    try:
        info = read_json_object(info_path, "run record") if info_path.exists() else {}
        return [record_run(TableLog(log_path), p / RECORDING, info=info)]
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None


def find_recording(path) -> Path:
    """The first recording :func:`find_recordings` finds (the one a run folder holds)."""
    return find_recordings(path)[0]


def has_display() -> bool:
    """Whether a native viewer window can open: always on macOS and Windows, on Linux with X11 or Wayland."""
    if not sys.platform.startswith("linux"):
        return True
    return any(os.environ.get(k) for k in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"))


def web_command(exe: str, rrds, web_port: int, grpc_port: int) -> list[str]:
    return [exe, "--serve-web", "--web-viewer-port", str(web_port), "--port", str(grpc_port), *map(str, rrds)]


def find_viewer() -> str | None:
    """The rerun viewer executable: the one beside the running interpreter first (rerun-sdk's entry point in a
    virtual environment's ``bin``/``Scripts``, which is not on PATH when the environment is not activated: the
    viewer that matches the installed SDK), then the first on PATH; None where there is neither.

    Examples
    --------
    >>> from rotorlab.commands.view import find_viewer
    >>> exe = find_viewer()  # e.g. '/home/me/proj/.venv/bin/rerun'
    """
    here = Path(sys.executable).parent  # not resolved: a venv's python is a link to the base interpreter
    for name in ("rerun", "rerun.exe"):
        exe = here / name
        if exe.is_file() and os.access(exe, os.X_OK):
            return str(exe)
    return shutil.which("rerun")


def run(args) -> int:
    import shlex

    rrds = find_recordings(args.path)
    exe = find_viewer()
    native = [exe or "rerun", *map(str, rrds)]
    web = web_command(exe or "rerun", rrds, args.web_port, args.grpc_port)
    names = ", ".join(r.name for r in rrds)
    web_hint = (f"rotorlab view {shlex.quote(str(args.path))} --web   (serves the web viewer over HTTP, no display "
                f"needed; then open http://localhost:{args.web_port})")
    if exe is None:
        print(f"the rerun viewer is neither beside this Python ({Path(sys.executable).parent}) nor on PATH "
              "(pip install rerun-sdk provides it); once installed, open the recording(s) with:")
        print(f"  in a window:             {shlex.join(native)}")
        print(f"  or serve the web viewer: {web_hint}")
        return 0
    if args.print_only:
        print(shlex.join(web if args.web else native))
        return 0
    if args.web:
        url = f"http://localhost:{args.web_port}"
        print(f"serving {names} in the web viewer at {url} (from another machine: "
              f"ssh -L {args.web_port}:localhost:{args.web_port} -L {args.grpc_port}:localhost:{args.grpc_port} "
              f"HOST, then open {url}); Ctrl-C stops it")
        sys.stdout.flush()
        try:
            rc = subprocess.run(web, check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode
        except KeyboardInterrupt:
            return 0
        return 0 if rc in (0, -2, 130) else rc
    if not has_display():
        print(f"no display here (neither DISPLAY nor WAYLAND_DISPLAY is set), so no viewer window for {names}.")
        print(f"  serve the web viewer:    {web_hint}")
        print(f"  or, with a display:      {shlex.join(native)}")
        return 0
    print(f"opening {names} in the rerun viewer")
    rc = subprocess.run(native, check=False).returncode
    if rc != 0:
        print(f"the viewer exited with status {rc}; serve the web viewer instead: rotorlab view "
              f"{shlex.quote(str(args.path))} --web")
    return rc
