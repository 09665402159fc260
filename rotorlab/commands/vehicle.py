"""Make a twin of your own multirotor: vehicle new writes a vehicle TOML from a few physical numbers (mass, arm,
propeller; motor kv and cells, thrust-stand coefficients, inertia when you have them), every estimated number
with its formula in the file; vehicle calibrate fits a twin's inertia, motor poles and delays to per-axis rate
models (model JSON files, or another twin's true linearisation) and prints the residual over 1-30 rad/s.
"""

from __future__ import annotations

from pathlib import Path

from rotorlab.cli import CLIError, HelpFormatter, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.

FRAMES = ("quad-plus", "quad-x", "hexa-x")  # rotorlab.vehicles.spec.FRAMES, without importing numpy for --help


def add_parser(sub):
    p = sub.add_parser("vehicle", help="make a twin of your own multirotor (new) and calibrate it (calibrate)",
                       **describe(__doc__))
    vs = p.add_subparsers(dest="vehicle_command", required=True, metavar="{new,calibrate}",
                          help="new: write a vehicle TOML; calibrate: fit it to per-axis models")
    n = vs.add_parser("new", formatter_class=HelpFormatter,
                      help="write a generic multirotor vehicle TOML from physical numbers",
                      description="Write a generic variable-RPM multirotor twin; estimates are marked in the file.")
    n.add_argument("name", help="vehicle name ([vehicle] name)")
    n.add_argument("--frame", choices=FRAMES, required=True, help="rotor layout (quad-x, hexa-x: PX4 numbering)")
    n.add_argument("--mass-kg", type=float, required=True, help="take-off mass, kg")
    n.add_argument("--arm-m", type=float, required=True, help="CG-to-hub distance, m")
    n.add_argument("--prop-in", type=float, required=True, help="propeller diameter, inch")
    n.add_argument("--kv", type=float, default=None, help="motor velocity constant, rpm/V (with --cells)")
    n.add_argument("--cells", type=int, default=None, help="LiPo cell count (with --kv)")
    n.add_argument("--max-speed-rad-s", type=float, default=None, help="maximum rotor speed, rad/s (thrust stand)")
    n.add_argument("--thrust-coefficient", type=float, default=None,
                   help="C_T of T = C_T rho pi R^4 Omega^2 (thrust stand)")
    n.add_argument("--torque-coefficient", type=float, default=None,
                   help="C_Q of Q = C_Q rho pi R^5 Omega^2 (thrust stand)")
    n.add_argument("--thrust-stand", default=None, metavar="CSV",
                   help="thrust-stand sweep, columns command (0-1), speed_rad_s, thrust_N[, torque_Nm]: C_T, C_Q and "
                        "the speed map are fitted to it (instead of --kv/--cells/--max-speed-rad-s/coefficients)")
    n.add_argument("--motor-tau-s", type=float, default=None, help="motor time constant, s")
    n.add_argument("--delay-s", type=float, default=None, help="command-to-rotor transport delay, s")
    n.add_argument("--inertia", type=float, nargs=3, default=None, metavar=("IXX", "IYY", "IZZ"),
                   help="principal moments of inertia about the CG, kg m^2")
    n.add_argument("--rotor-inertia-kgm2", type=float, default=0.0,
                   help="propeller + motor bell about the spin axis, kg m^2 (0 leaves the spin-up yaw reaction out)")
    n.add_argument("--rate-hz", type=float, default=250.0, help="flight-software rate, Hz (1000 / whole number)")
    n.add_argument("--out", required=True, help="vehicle TOML to write")
    n.add_argument("--gains-out", default=None,
                   help="also write a hand-designed baseline cascade (gains TOML) for rotorlab run --gains")
    c = vs.add_parser("calibrate", formatter_class=HelpFormatter,
                      help="fit inertia, motor poles and delays to per-axis rate models",
                      description="Fit a twin's inertia, motor poles and delays to per-axis rate models "
                                  "(axis command % -> rate deg/s) and print the residual over 1-30 rad/s.")
    c.add_argument("vehicle", help="vehicle TOML (or shipped name) to calibrate")
    c.add_argument("--model", action="append", default=[], metavar="AXIS=FILE",
                   help="model JSON of an axis (roll, pitch, yaw), axis command % -> rate deg/s; repeatable")
    c.add_argument("--to-twin", default=None, metavar="VEHICLE",
                   help="calibrate to another twin's true linearisation in the same scene (all three axes)")
    c.add_argument("--scene", choices=("gimbal", "free-flight"), default="gimbal",
                   help="where the twin is linearised: gimbal (rotation about the CG, as per-axis rotational "
                        "models) or free-flight (translation feeding back too)")
    c.add_argument("--out", required=True, help="calibrated vehicle TOML to write (comments kept)")
    return p


def run(args) -> int:
    try:
        return _new(args) if args.vehicle_command == "new" else _calibrate(args)
    except RotorlabError as exc:
        raise CLIError(str(exc)) from None


def _new(args) -> int:
    from rotorlab.gains import save_gains
    from rotorlab.vehicles.generic import baseline_gains, write_new_vehicle

    stand = _read_thrust_stand(args.thrust_stand) if args.thrust_stand else None
    v = write_new_vehicle(
        args.out, args.name, thrust_stand=stand, frame=args.frame, mass_kg=args.mass_kg, arm_m=args.arm_m,
        prop_in=args.prop_in,
        kv=args.kv, cells=args.cells, max_speed_rad_s=args.max_speed_rad_s,
        thrust_coefficient=args.thrust_coefficient, torque_coefficient=args.torque_coefficient,
        motor_tau_s=args.motor_tau_s, delay_s=args.delay_s, inertia_kgm2=args.inertia,
        rotor_inertia_kgm2=args.rotor_inertia_kgm2, rate_hz=args.rate_hz)
    print(f"wrote {args.out}: {v.frame}, {v.n_rotors} rotors, hover command {v.rotor.hover_command:.4f}, "
          f"inertia {', '.join(f'{x:.4g}' for x in v.inertia_kgm2)} kg m^2")
    if args.gains_out:
        save_gains(baseline_gains(v, name=Path(args.gains_out).stem), args.gains_out)
        print(f"wrote {args.gains_out}: baseline cascade (a starting point for rotorlab tune)")
    return 0


def _read_thrust_stand(path) -> dict:
    """The columns of a thrust-stand CSV (pyarrow's reader), with the file name as the source."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from rotorlab.errors import ConfigError

    try:
        table = pacsv.read_csv(path)
    except FileNotFoundError:
        raise ConfigError("thrust-stand file not found", file=path) from None
    except pa.ArrowInvalid as exc:
        raise ConfigError(f"not a CSV table: {exc}", file=path) from None
    out = {"source": f"thrust stand {Path(path).name}"}
    for name in table.column_names:
        col = table[name]
        if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)) or col.null_count:
            raise ConfigError("thrust-stand columns are numbers", file=path, field=name,
                              expected="a complete numeric column", got=str(col.type))
        out[name] = col.to_numpy()
    return out


def _calibrate(args) -> int:
    from rotorlab.ident.modelio import load_model
    from rotorlab.sim.linearize import linearize
    from rotorlab.vehicles import load_vehicle, vehicle_path
    from rotorlab.vehicles.fit_axes import AXES, calibrate_axes, twin_scene, write_calibrated

    v = load_vehicle(args.vehicle)
    targets = {}
    if args.to_twin:
        truth = load_vehicle(args.to_twin)
        targets = {a: linearize(twin_scene(truth, args.scene), truth, a, f"gyro_{a}") for a in AXES}
    for item in args.model:
        axis, sep, path = item.partition("=")
        if not sep or axis not in AXES:
            raise CLIError(f"--model: expected AXIS=FILE with AXIS one of {', '.join(AXES)}, got {item!r}")
        sys, delay_s, _ = load_model(path)
        targets[axis] = (sys, delay_s)
    if not targets:
        raise CLIError("nothing to calibrate to: give --model AXIS=FILE (repeatable) or --to-twin VEHICLE")
    result = calibrate_axes(v, targets, scene=args.scene)
    out = write_calibrated(vehicle_path(args.vehicle), result, args.out)
    print(f"wrote {out}")
    print(f"inertia {', '.join(f'{x:.5g}' for x in result.inertia_kgm2)} kg m^2; "
          f"motor lag {', '.join(f'{x * 1e3:.2f}' for x in result.lag_s)} ms; "
          f"delay {', '.join(f'{x * 1e3:.0f}' for x in result.delay_s)} ms")
    if result.rotor_inertia_kgm2 is not None:
        print(f"rotor inertia {result.rotor_inertia_kgm2:.4g} kg m^2; rotor in-plane drag "
              f"{result.hforce_N_per_mps:.4g} N/(m/s)")
    for note in result.at_bounds:
        print(f"note: {note} (the model asks for more than the physical range there)")
    print("residual twin / model (dB, deg):")
    print(result.table())
    for a, r in result.residual.items():
        s = result.residual_start[a]
        print(f"{a}: max {r.max_db:.3f} dB, {r.max_deg:.3f} deg (start {s.max_db:.3f} dB, {s.max_deg:.3f} deg)")
    return 0
