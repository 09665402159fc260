"""The gains TOML format: round trip, shipped published sets, and bad input naming the field."""

import pytest

from rotorlab.errors import ConfigError
from rotorlab.gains import load_gains, parse_gains, save_gains
from rotorlab.vehicles import gains_path, list_gains

PUBLISHED = {  # reference README tables: PD kp kd tf | PID kp ki kd tf (b, c for the A2-MINI/B)
    ("anteos-p2a2", "standard"): ((9.26, 1.11, 0.03), (0.257, 0.643, 0.0231, 0.0225)),
    ("anteos-p2a2", "optimal-testbed"): ((5.4631, 0.9376, 0.0380), (0.3539, 1.8562, 0.0084, 0.0430)),
    ("anteos-p2a2", "optimal-flight"): ((6.0491, 1.0320, 0.0377), (0.2986, 1.6150, 0.0075, 0.0415)),
    ("anteos-a2minib", "standard"): ((15.1515, 1.9697, 0.0325, 1, 0), (0.3691, 2.0504, 0.0183, 0.0124, 0.46, 1)),
    ("anteos-a2minib", "optimal"): ((19.8566, 1.5331, 0.0723, 0.9986, 0), (0.5253, 1.7525, 0.0144, 0.0206, 0.5787, 1)),
}


@pytest.mark.parametrize("vehicle,name", sorted(PUBLISHED))
def test_shipped_sets_are_the_published_numbers(vehicle, name):
    g = load_gains(gains_path(vehicle, name))
    outer, inner = PUBLISHED[(vehicle, name)]
    for axis in ("pitch", "roll"):  # roll reuses pitch by symmetry
        o, i = g[axis].outer, g[axis].inner
        assert (o.kp, o.kd, o.tf) == outer[:3] and o.ki == 0.0
        assert (i.kp, i.ki, i.kd, i.tf) == inner[:4]
        if len(outer) > 3:
            assert (o.b, o.c, i.b, i.c) == (*outer[3:], *inner[4:])
    assert set(list_gains(vehicle)) >= {n for v, n in PUBLISHED if v == vehicle}


def test_round_trip(tmp_path):
    g = load_gains(gains_path("anteos-a2minib", "optimal"))
    save_gains(g, tmp_path / "g.toml")
    assert load_gains(tmp_path / "g.toml").axes == g.axes


def _pitch(**inner):
    return {"pitch": {"outer": {"kp": 9.26, "kd": 1.11, "tf": 0.03}, "inner": {"kp": 0.257, "ki": 0.643, **inner}}}


@pytest.mark.parametrize("data,field,expected", [
    ({"pitch": {"outer": {"kp": 1.0}}}, "pitch.inner", "table"),
    (_pitch(kd=0.02, tf=-0.01), "pitch.inner.tf", ">= 0"),
    (_pitch(b=1.5), "pitch.inner.b", "[0.0, 1.0]"),
    (_pitch(c=-0.1), "pitch.inner.c", "[0.0, 1.0]"),
    (_pitch(kd=0.02), "pitch.inner.tf", "tf > 0"),
    (_pitch(kp="fast"), "pitch.inner.kp", "finite number"),
    (_pitch(kq=1.0), "pitch.inner.kq", "one of"),
    ({"roll": _pitch()["pitch"]}, "pitch", "[pitch.outer]"),
])
def test_bad_gains_name_the_field(data, field, expected):
    with pytest.raises(ConfigError) as exc:
        parse_gains(data, src="g.toml")
    msg = str(exc.value)
    assert "g.toml" in msg and f"'{field}'" in msg and expected in msg


def test_outer_loop_must_be_pd(tmp_path):
    p = tmp_path / "g.toml"
    p.write_text("[pitch.outer]\nkp = 1.0\nki = 0.5\n[pitch.inner]\nkp = 0.2\n")
    with pytest.raises(ConfigError, match=r"pitch.outer.ki.*outer loop is a PD|outer loop is a PD.*pitch.outer.ki"):
        load_gains(p)


def test_not_toml_and_missing_file(tmp_path):
    p = tmp_path / "g.toml"
    p.write_text("[pitch.outer\nkp = ")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_gains(p)
    with pytest.raises(ConfigError, match="not found"):
        load_gains(tmp_path / "none.toml")
