"""Plain helpers shared by test modules (fixtures live in conftest.py): the published identified models read
from the vehicle specs (their one source), a ground-truth plant built from one of them independently of the
library's cascade code, a reader of a pipeline summary's claim metrics and the walk of a one-file-per-class
registry package."""

import importlib
import pkgutil
import re

import control as ct
import numpy as np

from rotorlab.lti import c2d_zoh
from rotorlab.vehicles import load_vehicle


def published_tf(vehicle: str, which: str) -> tuple[ct.TransferFunction, float]:
    """A published identified model (reference 000) as its vehicle spec stores it, ``[published.WHICH]`` of
    ``vehicles/VEHICLE/vehicle.toml``: the continuous rate response ``u (%) -> q (deg/s)``, delay removed, and
    its input delay (s). Tests read the coefficients here rather than typing them again."""
    pm = load_vehicle(vehicle).published[which]
    return ct.tf(list(pm.num), list(pm.den)), pm.delay_s


def p2a2_testbed_angle_rate(dt: float) -> ct.StateSpace:
    """The P2-A2 test-bed pitch model (reference 000, PBSID) ``q/u = 12.517 (s + 2.906) / (s^2 + 5.583 s +
    21.3)``, integrated to the angle in continuous time: ``u`` (%) -> ``[theta (deg), q (deg/s)]``, ZOH at ``dt``
    (s). The 3-sample input delay is the caller's."""
    G = ct.tf2ss(published_tf("anteos-p2a2", "testbed")[0])
    A = np.block([[G.A, np.zeros((2, 1))], [G.C, np.zeros((1, 1))]])
    B = np.vstack([G.B, G.D])
    C = np.vstack([np.hstack([np.zeros((1, 2)), np.ones((1, 1))]), np.hstack([G.C, np.zeros((1, 1))])])
    return c2d_zoh(ct.ss(A, B, C, np.zeros((2, 1))), dt)


def claim_metrics(summary: dict):
    """``m(scenario, metric, set)``: the metric's magnitude in a pipeline summary, infinite where the set has
    none (never settled, never recovered: the summary leaves it out or stores None). A metric that no gain set
    of the scenario has is a KeyError, so a misspelt key cannot pass as infinity against infinity."""
    v = summary["validation"]

    def m(sc, key, name):
        if not any(key in r for r in v[sc].values()):
            raise KeyError(f"no gain set of {sc!r} has the metric {key!r}")
        x = v[sc][name].get(key)
        return np.inf if x is None else abs(x)

    return m


def classes_defined_in(pkg, base: type) -> list[tuple[str, type]]:
    """``(module file name, class)`` for every subclass of ``base`` defined (not only imported) in a module of
    package ``pkg``: what a registry's one-file-per-class rule is checked against."""
    found = []
    for info in pkgutil.iter_modules(pkg.__path__):
        mod = importlib.import_module(f"{pkg.__name__}.{info.name}")
        found += [(info.name, obj) for obj in vars(mod).values()
                  if isinstance(obj, type) and issubclass(obj, base) and obj is not base and obj.__module__ == mod.__name__]
    return found


def snake_case(class_name: str) -> str:
    """``InputDisturbanceStep`` -> ``input_disturbance_step``: the file name a registered class lives in."""
    return re.sub(r"(?<!^)(?=[A-Z])", "_", class_name).lower()
