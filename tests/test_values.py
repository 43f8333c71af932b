"""Checked scene values (raytrace/values.py): suggestions for misspelt names, and ranges printed
as they were written."""

from __future__ import annotations

import numpy as np
import pytest

import raytrace
from raytrace import cli, values


@pytest.mark.parametrize("word,choices,expected", [
    ("bras", ["brass", "bronze", "glass"], " (did you mean 'brass'?)"),
    ("cutof", ["type", "position", "direction", "cutoff", "exponent"],
     " (did you mean 'cutoff'?)"),
    ("glas", ["glass", "gloss", "brass"], " (did you mean 'glass' or 'gloss'?)"),
    ("teapot", ["brass", "glass"], ""),
    (3, ["brass"], ""),
])
def test_did_you_mean_offers_the_closest_names(word, choices, expected):
    assert values.did_you_mean(word, choices) == expected


def test_an_unknown_key_suggests_the_closest():
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.scene_from_dict({"lights": [{"type": "spot", "position": [0, 1, 0],
                                              "direction": [0, -1, 0], "cutof": 30}]})
    assert str(e.value) == ("lights[0].cutof: unknown key (did you mean 'cutoff'?) (valid keys: "
                            "type, position, direction, cutoff, exponent, color, attenuation, "
                            "inner_cutoff, range)")


def test_an_unknown_choice_suggests_the_closest():
    with pytest.raises(raytrace.SceneError, match=r"got 'blin' \(did you mean 'blinn'\?\)"):
        raytrace.Material(highlight="blin")


def test_integer_ranges_print_as_integers(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text("[render]\nwidth = 2\nheight = 2\n")
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "--seed", "-1"]) == 2
    assert capsys.readouterr().err == ("raytrace: error: --seed: must be >= 0 (the range is "
                                       "[0, 9223372036854775807]), got -1\n")
    with pytest.raises(raytrace.SceneError, match=r"\(the range is \(0, 90\]\), got 0\.0"):
        raytrace.SpotLight([0, 1, 0], [0, -1, 0], cutoff=0.0)  # float bounds: %g, as before


def test_unit_normalises_once_and_then_keeps_the_direction_bit_for_bit():
    # A record's check runs again before every render: normalising an already normalised
    # direction again would move a third of them by an ulp (and the picture with them).
    rng = np.random.default_rng(28)
    for v in rng.normal(size=(2000, 3)) * 10.0 ** rng.uniform(-3, 3, size=(2000, 1)):
        u = values.unit(v, "normal")
        assert abs(np.linalg.norm(u) - 1) <= values.UNIT_TOLERANCE
        assert values.unit(u, "normal").tobytes() == u.tobytes()
    assert values.unit([0, 0, 2], "normal").tolist() == [0.0, 0.0, 1.0]
    with pytest.raises(raytrace.SceneError, match="^normal: must not be the zero vector$"):
        values.unit([0, 0, 0], "normal")


# -- bounds on positions, lengths and directions ---------------------------------------------
LENGTH_LINE = ("radius: must be within [1e-12, 1e+12] (the lengths at which a scene renders as "
               "it does at unit size), got {}")


@pytest.mark.parametrize("value,index,shown", [([1e200, 1, 5], 0, "1e+200"),
                                               ([0, -1.000001e12, 0], 1, "-1000001000000.0"),
                                               ([0, 0, 1e308], 2, "1e+308")])
def test_a_position_beyond_the_coordinate_bound_names_its_component_and_the_limit(
        value, index, shown):
    with pytest.raises(raytrace.SceneError) as e:
        values.position(value, "camera.position")
    assert str(e.value) == (f"camera.position[{index}]: must be within ±1e+12 (where every ray "
                            f"meets every mesh in Embree's float32), got {shown}")


def test_positions_up_to_the_bound_are_kept():
    assert values.position([1e12, -1e12, 1e-300], "p").tolist() == [1e12, -1e12, 1e-300]


@pytest.mark.parametrize("value", [1e155, 1e308, 1.01e12, 9.9e-13, 1e-200, 5e-324])
def test_a_length_outside_the_bounds_is_refused_with_the_limit(value):
    with pytest.raises(raytrace.SceneError) as e:
        values.length(value, "radius")
    assert str(e.value) == LENGTH_LINE.format(repr(value))


def test_a_negative_length_still_says_it_must_be_positive():
    with pytest.raises(raytrace.SceneError, match=r"^radius: must be > 0, got -1$"):
        values.length(-1, "radius")


def test_lengths_at_the_bounds_are_kept():
    assert [values.length(v, "r") for v in (1e-12, 1.0, 1e12)] == [1e-12, 1.0, 1e12]


@pytest.mark.parametrize("v", [[1e-160, 0, 0], [0, 5e-324, 0], [1e-155, -1e-155, 0]])
def test_a_direction_whose_squared_length_underflows_is_refused(v):
    # np.linalg.norm of [1e-160, 0, 0] is a subnormal 1e-160 good to 3 digits (or 0): the
    # "unit" vector would be off unit length, or NaN.
    with pytest.raises(raytrace.SceneError, match=r"^normal: is too short to normalise"):
        values.unit(v, "normal")


def test_the_smallest_direction_that_normalises_is_unit():
    v = values.unit([1.5e-154, 0, 0], "normal")
    assert v.tolist() == [1.0, 0.0, 0.0]


def test_the_doctests():
    import doctest

    assert doctest.testmod(values).failed == 0


@pytest.mark.parametrize("key,value", [("radius", 10**400), ("render.width", -(10**309))],
                         ids=["10**400", "-10**309"])
def test_an_integer_beyond_float64_is_refused_in_one_line(key, value):
    """A JSON integer of 400 digits is a Python int that float() cannot convert: it was an
    OverflowError traceback."""
    with pytest.raises(raytrace.SceneError) as e:
        values.number(value, key)
    assert str(e.value) == (f"{key}: must be within float64's range (±1.8e308), got an integer "
                            f"of {value.bit_length()} bits")
