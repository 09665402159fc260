"""Plain helpers shared by test modules (fixtures live in conftest.py): the published identified models read
from the vehicle specs (their one source), a ground-truth plant built from one of them independently of the
library's cascade code, a reader of a pipeline summary's claim metrics, the walk of a one-file-per-class
registry package, and the tolerances of the reproducibility contract (docs/reproducibility.md) for tests that
compare two code paths."""

import importlib
import pkgutil
import re

import control as ct
import numpy as np

from rotorlab.lti import c2d_zoh
from rotorlab.vehicles import load_vehicle

# The reproducibility contract, docs/reproducibility.md: one code path run twice on one machine gives the same
# floats (tests assert that with ==); two code paths agree within these bounds, which hold on any CPU whatever
# SIMD kernels numpy, OpenBLAS and MuJoCo pick there.

#: an elementary function (atan2, asin, exp, ...) of the same float from two libraries, scaled by the same
#: constant: glibc (1-2 ulp for these on x86-64, its manual says) and numpy's SIMD loops (SVML's on AVX-512) are
#: each a few ulp from the exact value and the scaling rounds once more; 2 measured between math.atan2 and
#: numpy's AVX-512 arctan2 in degrees, so twice that
ELEMENTARY_ULPS = 4


def sum_gap_bound(terms_abs, n_ops: int):
    """How far two evaluations of a sum of products (a dot product, a matrix-vector product, einsum, or such
    sums nested) may lie apart when they add in another order or with fused multiply-adds: each is within
    ``gamma_n sum|products|`` of the exact value, ``gamma_n = n u / (1 - n u)``, ``u = eps / 2``, ``n`` the
    roundings on the longest path (``n`` for a sum of ``n`` products; Higham, Accuracy and Stability of
    Numerical Algorithms, 2nd ed., section 3.1), so two within twice that. ``terms_abs``: each value's sum of
    the magnitudes of its products, nested sums expanded."""
    u = np.finfo(float).eps / 2
    return 2.0 * n_ops * u / (1.0 - n_ops * u) * np.asarray(terms_abs, dtype=float)


def assert_within_ulps(got, want, ulps: float = ELEMENTARY_ULPS, err_msg: str = ""):
    """``got`` and ``want`` (arrays of one shape) differ by at most ``ulps`` units in the last place of ``want``
    (docs/reproducibility.md: the same elementary function from two libraries)."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape, err_msg
    gap = np.abs(got - want) / np.spacing(np.abs(want))
    assert np.all(gap <= ulps), f"{err_msg}: {gap.max():.1f} ulp apart (allowed {ulps}): {got} vs {want}"


def assert_sums_agree(got, want, terms_abs, n_ops: int, err_msg: str = ""):
    """``got`` and ``want``, two evaluations of the same sums of products, lie within :func:`sum_gap_bound`
    (docs/reproducibility.md: the same sums in another order or with fused multiply-adds)."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    bound = sum_gap_bound(terms_abs, n_ops)
    assert np.all(np.abs(got - want) <= bound), f"{err_msg}: {got} vs {want}, allowed {bound}"


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
