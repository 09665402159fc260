"""The registries a new building block is added to, walked entry by entry: goal types
(``rotorlab.tune.goals.GOAL_TYPES``, read by ``Goal.from_toml``), scenarios x the scenes each declares,
and the vehicle folders. (Identification methods: tests/test_ident_methods.py; disturbances:
tests/test_disturbances.py.)"""

import math

import numpy as np
import pytest
from helpers import published_tf

from rotorlab import scenes
from rotorlab.config import Table
from rotorlab.errors import ConfigError
from rotorlab.gains import load_gains
from rotorlab.sim import scenarios
from rotorlab.sim.runner import run_scenario
from rotorlab.tune import PlantModel, evaluate
from rotorlab.tune.goals import GOAL_TYPES, Goal
from rotorlab.tune.spec import Spec
from rotorlab.vehicles import VEHICLES_DIR, gains_path, list_gains, list_vehicles, load_vehicle

# one TOML table per goal type; a type added to GOAL_TYPES without an entry here fails the walk
GOAL_TABLES = {
    "crossover": {"loop": "theta", "band_rad_s": [3.5, 14.0]},
    "tracking": {"response_time_s": 0.5},
    "rejection": {"from": "d_u", "to": "theta", "weight": 1.0},
    "gain": {"from": "n_q", "to": "u", "weight": 100.0},
    "sensitivity": {"point": "u", "weight": 2.0},
    "effort": {"max_gain": 50.0},
    "margins": {"point": "u", "gm_db": 4.0, "pm_deg": 25.0},
    "poles": {"min_damping": 0.1},
}
PUBLISHED = PlantModel(*published_tf("anteos-p2a2", "testbed"), name="test-bed")


def test_every_goal_type_is_walked():
    assert set(GOAL_TABLES) == set(GOAL_TYPES)


@pytest.mark.parametrize("typ", sorted(GOAL_TYPES))
def test_goal_type_reads_its_table_and_evaluates(typ):
    table = Table("spec.toml", {"type": typ, **GOAL_TABLES[typ]}, "goal[0].")
    goal = Goal.from_toml(table)
    table.check_unknown()  # the reader consumed every key of its table
    assert type(goal) is GOAL_TYPES[typ][0]
    spec = Spec(name=typ, dt=0.02, axis="pitch", two_dof=False, tune=[], goals=[goal])
    res = evaluate(spec, load_gains(gains_path("anteos-p2a2", "standard")), [PUBLISHED])
    assert res and all(math.isfinite(r.value) and r.value >= 0 for r in res)


def test_unknown_goal_type_lists_the_registry():
    with pytest.raises(ConfigError) as exc:
        Goal.from_toml(Table("spec.toml", {"type": "bandwidth"}, "goal[2]."))
    assert "goal[2].type" in str(exc.value) and all(t in str(exc.value) for t in GOAL_TYPES)


def test_every_vehicle_folder_is_a_vehicle():
    folders = sorted(p.name for p in VEHICLES_DIR.iterdir() if p.is_dir() and not p.name.startswith(("_", ".")))
    assert folders == list_vehicles() and len(folders) >= 3
    for name in folders:
        v = load_vehicle(name)
        assert v.mass_kg > 0 and (VEHICLES_DIR / name / "README.md").exists(), name
        assert "standard" in list_gains(name), name


SCENARIO_SCENES = [(name, scene) for name in scenarios.SCENARIOS for scene in scenarios.get(name).SCENES]
# scenarios that refuse a 2 s run get options for a short one: prbs-periodic needs two PRBS periods (31 bits here)
SHORT_RUN = {"prbs-periodic": ({"order": 5}, 2.6)}


def test_every_scenario_declares_known_scenes():
    for name in scenarios.SCENARIOS:
        mod = scenarios.get(name)
        assert mod.SCENES and set(mod.SCENES) <= set(scenes.SCENES), name


@pytest.mark.parametrize("name,scene", SCENARIO_SCENES, ids=[f"{n}@{s}" for n, s in SCENARIO_SCENES])
def test_every_scenario_runs_in_every_scene_it_declares(name, scene):
    # 2 s: long enough for the bench sweeps to hold two levels (1 s each), short enough to walk every pair
    options, duration_s = SHORT_RUN.get(name, ({}, min(scenarios.get(name).DURATION_S, 2.0)))
    r = run_scenario(name, "anteos-p2a2", scene=scene, seed=0, duration_s=duration_s, options=options)
    assert r.info["scene"] == scene and len(r.log["t"]) > 0
    assert np.all(np.isfinite(r.log["t"]))
