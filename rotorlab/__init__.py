"""rotorlab: a virtual rotorcraft lab.

Sub-packages: ``rotorlab.vehicles`` (digital twins), ``rotorlab.scenes`` (rigs, thrust stand, free
flight), ``rotorlab.sim`` (physics stepping, flight software, scenarios, logs), ``rotorlab.ident``
(system identification), ``rotorlab.tune`` (structured H-inf tuning and robustness).

Importing this package stays light: nothing here imports MuJoCo, so ``rotorlab.ident`` and
``rotorlab.tune`` can be used on flight logs without a simulator.
"""

__version__ = "0.1.0"

# One BLAS thread per process, set before numpy or scipy load their BLAS (this package's import is the earliest
# point rotorlab controls). Parallel work goes through rotorlab.executor, one task per process; a task's numbers
# must not depend on where it ran, and a multi-threaded BLAS splits its reductions by thread count: the main
# process and forked pool workers (threads = cores) and Dask workers (one thread) differed by up to 1.6e-10.
# setdefault: a user may ask for more threads and give up bit-identical numbers across executors.
import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
del _os, _var

# MuJoCo's OpenGL backend is fixed when mujoco is first imported, and every module that imports it is under this
# package: a headless machine gets EGL or OSMesa here (rotorlab.glbackend), before any of them
from rotorlab import glbackend as _glbackend  # noqa: E402

_glbackend.select()
del _glbackend

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

# the per-tick modules a build compiled, imported only where built from the source beside them (rotorlab.compiled)
from rotorlab import compiled as _compiled  # noqa: E402

_compiled.install()
del _compiled
