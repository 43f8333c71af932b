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
                            "type, position, direction, cutoff, exponent, color, attenuation)")


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
