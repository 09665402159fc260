"""Write a twin's MuJoCo model as an MJCF file: the vehicle in one scene, as the simulator builds it from the
vehicle's TOML, at full numeric precision (MuJoCo loads it into the same model, array for array).

Open it with MuJoCo's viewer (python -m mujoco.viewer --mjcf FILE.xml).
"""

from __future__ import annotations

from rotorlab.cli import describe

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("export-mjcf", help="write a twin (vehicle in a scene) as an MJCF file for MuJoCo's viewer",
                       **describe(__doc__))
    p.add_argument("vehicle", metavar="VEHICLE", help="vehicle name (rotorlab list) or vehicle TOML path")
    p.add_argument("--scene", default="free-flight",
                   help="pitch-rig, roll-rig, thrust-stand or free-flight (default: free-flight)")
    p.add_argument("--out", required=True, metavar="FILE.xml", help="MJCF file to write")
    return p


def run(args) -> int:
    from rotorlab.scenes.export import export

    model = export(args.vehicle, args.scene, args.out)
    print(f"wrote {args.out}: {model.nbody} bodies, {model.njnt} joints, {model.nu} actuators; "
          f"open it with: python -m mujoco.viewer --mjcf {args.out}")
    return 0
