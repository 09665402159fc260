"""The log pipeline's refinement of a calibrated twin on the flight itself
(:func:`rotorlab.pipeline.stages.log_calibrate.refine_on_flight`), against ground truth: the x500 twin (quad X: one
motor lag and one delay for roll and pitch) flies PX4's laws with autotune-like excitation on roll and pitch and
writes a ULog; a copy of the x500 with its inertia, motor lag and delay off is refined on that log and must come back
to the x500's own numbers."""

import dataclasses

import numpy as np
import pytest

from rotorlab.ident.flightlogs import read_flight_log
from rotorlab.ident.flightlogs.windows import Window
from rotorlab.pipeline.stages.log_calibrate import flight_loop, refine_on_flight, twin_prediction
from rotorlab.scenes import PHYSICS_DT_S
from rotorlab.vehicles import load_vehicle

AXES = ("roll", "pitch")


@pytest.fixture(scope="module")
def x500_flight(tmp_path_factory):
    from rotorlab.twinlogs import fly_twin_log

    path = fly_twin_log(tmp_path_factory.mktemp("flightfit") / "x500.ulg", "x500", autopilot="px4", axes=AXES,
                        duration_s=12.0, seed=0)
    log = read_flight_log(path)
    loops = {}
    for axis in AXES:
        rec = log.record(axis, ("rate_sp", "rate"))
        loops[axis] = (flight_loop(log, axis, rec.dt), [Window(float(rec.t_s[0]), float(rec.t_s[-1]), "all")])
    return log, loops


def _off(v):
    """``v`` with roll's moment +4 %, pitch's -4 %, the motor lag +6 % and the delay one physics step longer."""
    rotor = dataclasses.replace(v.rotor, lag_s=tuple(x * 1.06 for x in v.rotor.lag_s),
                                delay_s=tuple(x + PHYSICS_DT_S for x in v.rotor.delay_s))
    i = v.inertia_kgm2
    return dataclasses.replace(v, inertia_kgm2=(i[0] * 1.04, i[1] * 0.96, i[2]), rotor=rotor)


@pytest.fixture(scope="module")
def refined(x500_flight):
    start = _off(load_vehicle("x500"))
    return start, refine_on_flight(start, x500_flight[1])


def test_refinement_on_the_flight_recovers_the_twin(refined):
    """From the x500 with its inertia 4 % off (opposite ways on roll and pitch), the shared motor lag 6 % and the
    delay one step off, the refinement on the x500's own flight returns its moments within 1 %, its lag within 4 %
    and its delay to the step (the log is the nonlinear twin in free flight with sensor noise; the refinement's
    model is the linearisation on the gimbal), and the fit on the flight improves on both axes."""
    true = load_vehicle("x500")
    res = refined[1]
    v = res.vehicle
    assert np.allclose(v.inertia_kgm2[:2], true.inertia_kgm2[:2], rtol=0.01), v.inertia_kgm2
    assert v.inertia_kgm2[2] == true.inertia_kgm2[2]  # not refined, and the triangle inequality holds
    assert len(set(v.rotor.lag_s)) == 1 and v.rotor.lag_s[0] == pytest.approx(true.rotor.lag_s[0], rel=0.04)
    assert v.rotor.delay_s == true.rotor.delay_s
    for axis in AXES:
        assert res.vaf_after[axis] > res.vaf_before[axis], axis
    assert res.notes == ()


def test_refinement_reports_the_twins_predictions(x500_flight, refined):
    """The VAFs the refinement reports are the free-run predictions of the twin it started from and of the twin it
    returns, on the windows it was given."""
    start, res = refined
    for axis in AXES:
        loop, windows = x500_flight[1][axis]
        assert res.vaf_before[axis] == twin_prediction(loop, start, windows)[0]
        assert res.vaf_after[axis] == twin_prediction(loop, res.vehicle, windows)[0]


def test_refinement_takes_the_identifications_sample_budget():
    """The pipeline refines on the first identification windows holding at most the identification's MAX_FIT_SAMPLES
    samples together (the last one cut, a remainder under MIN_SAMPLES dropped), so a long log costs no more than a
    short one."""
    from rotorlab.ident.flightlogs.identify import MAX_FIT_SAMPLES, MIN_SAMPLES
    from rotorlab.pipeline.stages.log_calibrate import _fit_windows

    dt = 0.004
    budget = MAX_FIT_SAMPLES * dt
    assert [(w.start_s, w.stop_s) for w in _fit_windows([(0.0, 8.0), (10.0, 12.0)], dt)] == [(0.0, 8.0), (10.0, 12.0)]
    got = _fit_windows([(0.0, budget - 1.0), (30.0, 40.0), (50.0, 60.0)], dt)
    assert [(w.start_s, w.stop_s) for w in got] == [(0.0, budget - 1.0), (30.0, 31.0)]
    short = _fit_windows([(0.0, budget - 0.5 * MIN_SAMPLES * dt), (30.0, 40.0)], dt)
    assert len(short) == 1
