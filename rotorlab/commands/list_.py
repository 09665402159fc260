"""List the vehicles, scenes, scenarios and shipped gain sets; --scenario NAME shows one scenario's options.

Scenario options are passed to rotorlab run as --option KEY=VALUE (TOML values: 2.5, true, [1, 2], "text").
"""

from __future__ import annotations

import json
import re

from rotorlab.cli import CLIError, describe
from rotorlab.errors import RotorlabError

# Imports inside the functions: rotorlab.cli imports every command module to build its parser (for --help too),
# so what a command needs beyond the CLI loads only when that command runs.


def add_parser(sub):
    p = sub.add_parser("list", help="list vehicles, scenes, scenarios and gain sets; --scenario NAME: its options",
                       **describe(__doc__))
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--scenario", metavar="NAME", default=None,
                   help="show one scenario: description, scenes, duration and every option with its default")
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


def option_docs(doc: str) -> dict:
    """``{option: text}`` from the numpy-style ``Options`` section of a scenario module's docstring."""
    m = re.search(r"^Options\n-+\n(.*?)(?:\n\n[A-Z][^\n]*\n-+\n|\Z)", doc or "", re.S | re.M)
    out, cur = {}, None
    for line in (m.group(1).splitlines() if m else []):
        head = re.match(r"``([A-Za-z_0-9]+)``\s*(?::\s*[^ ]+(?: of [a-z]+)?)?\s*(.*)", line.strip())
        if head and not line.startswith((" ", "\t")):
            cur = head.group(1)
            out[cur] = head.group(2).strip()
        elif cur and line.strip():
            out[cur] = (out[cur] + " " + line.strip()).strip()
    # the default is shown in its own column: drop a bare "(default VALUE)" that only repeats it
    return {k: re.sub(r"\s*\(default [^;:()]*\)\.?$", "", v.replace("``", "")) for k, v in out.items()}


def scenario_info(name: str) -> dict:
    """One scenario's description, scenes, duration and options (default and meaning)."""
    from rotorlab.sim.scenarios import get

    mod = get(name)
    docs = option_docs(mod.__doc__)
    defaults = getattr(mod, "DEFAULTS", {})
    return {"name": name, "description": mod.DESCRIPTION, "scenes": list(mod.SCENES), "duration_s": mod.DURATION_S,
            "options": {k: {"default": v, "doc": docs.get(k, "")} for k, v in defaults.items()}}


def _toml(v) -> str:
    if v is None:
        return "(none)"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return f"{v:g}" if isinstance(v, float) else str(v)


def run(args) -> int:
    if args.scenario:
        try:
            info = scenario_info(args.scenario)
        except RotorlabError as exc:
            raise CLIError(str(exc)) from None
        if args.json:
            print(json.dumps(info, indent=2))
            return 0
        print(f"{info['name']}: {info['description']}")
        print(f"scenes: {', '.join(info['scenes'])} (first is the default); duration {info['duration_s']:g} s")
        if not info["options"]:
            print("options: none")
            return 0
        print("options (rotorlab run ... --option KEY=VALUE):")
        w = max(len(k) for k in info["options"])
        dw = max(len(_toml(o["default"])) for o in info["options"].values())
        for k, o in info["options"].items():
            print(f"  {k:<{w}}  default {_toml(o['default']):<{dw}}  {o['doc']}".rstrip())
        return 0
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
    print("scenarios (rotorlab list --scenario NAME shows the options):")
    for name, s in cat["scenarios"].items():
        print(f"  {name:14s} {s['description']}  [{', '.join(s['scenes'])}]")
    return 0
