"""rotorlab: a virtual rotorcraft lab.

Sub-packages: ``rotorlab.vehicles`` (digital twins), ``rotorlab.scenes`` (rigs, thrust stand, free
flight), ``rotorlab.sim`` (physics stepping, flight software, scenarios, logs), ``rotorlab.ident``
(system identification), ``rotorlab.tune`` (structured H-inf tuning and robustness).

Importing this package stays light: nothing here imports MuJoCo, so ``rotorlab.ident`` and
``rotorlab.tune`` can be used on flight logs without a simulator.
"""

__version__ = "0.1.0"

# Gymnasium environments (rotorlab issue 7): registered by entry-point string, so MuJoCo loads only on make().
try:
    import gymnasium as _gym
except ImportError:  # gymnasium is a dependency; a stripped install still imports rotorlab
    pass
else:
    # max_episode_steps: the default episode_s (10 s) at the 50 Hz agent step; the env truncates at its own
    # episode_s too, so a make(..., episode_s=...) with a longer episode also passes max_episode_steps=...
    for _id, _entry, _kw in (
        ("rotorlab/PitchRig-v0", "rotorlab.sim.env_rig:RigEnv", {"axis": "pitch"}),
        ("rotorlab/RollRig-v0", "rotorlab.sim.env_rig:RigEnv", {"axis": "roll"}),
        ("rotorlab/Hover-v0", "rotorlab.sim.env_hover:HoverEnv", {}),
    ):
        if _id not in _gym.registry:
            _gym.register(id=_id, entry_point=_entry, kwargs=_kw, max_episode_steps=500)
    del _id, _entry, _kw, _gym
