"""``rotorlab list [--json]``: vehicles, scenes, scenarios and shipped gain sets."""

from __future__ import annotations

import json


def add_parser(sub):
    p = sub.add_parser("list", help="list vehicles, scenes, scenarios and gain sets")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    return p


def catalogue() -> dict:
    from rotorlab.scenes import list_scenes
    from rotorlab.sim.scenarios import get, list_scenarios
    from rotorlab.vehicles import list_gains, list_vehicles, load_vehicle

    vehicles = {}
    for name in list_vehicles():
        v = load_vehicle(name)
        vehicles[name] = {"description": v.description, "kind": v.kind, "mass_kg": v.mass_kg, "gains": list_gains(name)}
    scen = {}
    for name in list_scenarios():
        mod = get(name)
        scen[name] = {"description": mod.DESCRIPTION, "scenes": list(mod.SCENES), "duration_s": mod.DURATION_S}
    return {"vehicles": vehicles, "scenes": list_scenes(), "scenarios": scen}


def run(args) -> int:
    cat = catalogue()
    if args.json:
        print(json.dumps(cat, indent=2))
        return 0
    print("vehicles:")
    for name, v in cat["vehicles"].items():
        print(f"  {name:16s} {v['kind']:15s} {v['mass_kg']:5.2f} kg  gains: {', '.join(v['gains']) or '-'}")
    print("scenes:")
    for name in cat["scenes"]:
        print(f"  {name}")
    print("scenarios:")
    for name, s in cat["scenarios"].items():
        print(f"  {name:14s} {s['description']}  [{', '.join(s['scenes'])}]")
    return 0
