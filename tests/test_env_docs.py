"""Every registered rotorlab env documents itself in Gymnasium's form (the module docstring of its entry point):
description, action and observation tables with units and bounds, rewards, starting state, episode end,
arguments and version history; and the tables agree with the spaces the env builds."""

import importlib
import re

import gymnasium as gym
import pytest

import rotorlab  # noqa: F401  (registers the envs)

ENVS = sorted(k for k in gym.registry if k.startswith("rotorlab/"))
SECTIONS = ("Description", "Action space", "Observation space", "Rewards", "Starting state", "Episode end",
            "Arguments", "Version history")


def _module(env_id):
    entry = gym.registry[env_id].entry_point
    return importlib.import_module(entry.split(":")[0] if isinstance(entry, str) else entry.__module__)


@pytest.mark.parametrize("env_id", ENVS)
def test_env_docstring_follows_the_gymnasium_template(env_id):
    doc = _module(env_id).__doc__
    for s in SECTIONS:
        assert f"**{s}.**" in doc, f"{env_id}: no '{s}' section"
    assert env_id.split("/")[1] in doc
    # two tables with a unit column: actions and observations
    assert len(re.findall(r"^Num\s+(Action|Observation).*\bUnit$", doc, re.M)) >= 2


@pytest.mark.parametrize("env_id", ENVS)
def test_observation_table_matches_the_space(env_id):
    env = gym.make(env_id, disable_env_checker=True)
    doc = _module(env_id).__doc__
    table = doc[doc.index("**Observation space.**"):doc.index("**Rewards.**")]
    rows = [ln.split()[0] for ln in table.splitlines() if re.match(r"^\d+(-\d+)?\s", ln)]
    last = max(int(r.split("-")[-1]) for r in rows)
    privileged = gym.make(env_id, privileged=True, disable_env_checker=True)
    assert last + 1 == privileged.observation_space.shape[0] > env.observation_space.shape[0]
    hi = privileged.observation_space.high
    for ln in table.splitlines():
        m = re.match(r"^(\d+)(?:-(\d+))?\s+.*?\s(-?[\w.]+)\s+(-?[\w.]+)\s+\S+$", ln)
        if m and re.fullmatch(r"-?\d+(\.\d+)?", m.group(4)):
            a, b = int(m.group(1)), int(m.group(2) or m.group(1))
            assert all(hi[k] == float(m.group(4)) for k in range(a, b + 1)), ln
    env.close()
    privileged.close()
