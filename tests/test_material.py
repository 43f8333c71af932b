"""Materials: the named library, the seed table's exact values, ``base =`` inheritance,
inline materials and the 3-D checker pattern."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import RTOL, aimed_camera, make_scene, pixel, write_gltf, write_png, write_text

import raytrace
from raytrace import cli, shading
from raytrace.kernels.core import checker_box_rows, checker_rows
from raytrace.kernels.mip import footprint_rows
from raytrace.material import Checker, Material, library

# The classic material table of seed 001 (Hill & Kelley Fig. 8.17, after McReynolds & Blythe):
#   Material         ka (r g b)                    kd (r g b)                    ks (r g b)     n
SEED_TABLE = {
    "black_plastic": ([0.0, 0.0, 0.0], [0.01, 0.01, 0.01], [0.5, 0.5, 0.5], 32.0),
    "brass": ([0.329412, 0.223529, 0.027451], [0.780392, 0.568627, 0.113725],
              [0.992157, 0.941176, 0.807843], 27.8974),
    "polished_silver": ([0.23125, 0.23125, 0.23125], [0.2775, 0.2775, 0.2775],
                        [0.773911, 0.773911, 0.773911], 89.6),
}


def test_every_library_material_loads():
    names = list(library)
    assert len(names) >= 30 and names == sorted(names)
    for name in names:
        m = library[name]
        assert isinstance(m, Material) and m.name == name
        for k in ("kd", "ks", "kr", "kt"):
            c = getattr(m, k)
            assert isinstance(c, Checker) or (c.shape == (3,) and np.all(c >= 0))
        assert np.all(np.asarray(m.kr) + np.asarray(m.kt) <= 1.0 + 1e-12), name
        assert m.ior > 0 and 0 <= m.opacity <= 1 and m.highlight in ("phong", "blinn")
        info = library.describe(name)
        assert info["description"] and info["source"], f"{name} lacks description/source"


@pytest.mark.parametrize("name", sorted(SEED_TABLE))
def test_seed_table_values_are_exact(name):
    ka, kd, ks, n = SEED_TABLE[name]
    m = library[name]
    assert m.ka.tolist() == ka and m.kd.tolist() == kd and m.ks.tolist() == ks
    assert m.shininess == n and m.highlight == "phong"
    assert not m.reflects and not m.transmits


def test_library_is_usable_by_name_in_scenes_and_from_the_package():
    assert raytrace.materials["brass"] is library["brass"]
    assert "brass" in raytrace.materials and "unobtainium" not in raytrace.materials
    with pytest.raises(KeyError):
        raytrace.materials["unobtainium"]


def _scene_materials(tmp_path, text: str) -> raytrace.Scene:
    return raytrace.load_scene(write_text(tmp_path / "m.toml", text + """
[[objects]]
type = "sphere"
center = [0, 0, -3]
radius = 1
material = "x"
"""))


def test_base_inheritance_ka_follows_a_new_kd_when_the_base_had_none(tmp_path):
    scene = _scene_materials(tmp_path, """
[materials.plain]
kd = 0.3
ks = 0.4
shininess = 7
[materials.x]
base = "plain"
kd = [0.9, 0.1, 0.2]
""")
    x = scene.materials["x"]
    assert x.ka is None and x.ambient.tolist() == [0.9, 0.1, 0.2]
    assert x.ks.tolist() == [0.4] * 3 and x.shininess == 7          # inherited


def test_base_inheritance_keeps_an_explicit_base_ka(tmp_path):
    scene = _scene_materials(tmp_path, """
[materials.x]
base = "brass"
kd = 0.5
""")
    x = scene.materials["x"]
    assert x.ka.tolist() == SEED_TABLE["brass"][0]       # brass's own ka, not the new kd
    assert x.kd.tolist() == [0.5] * 3 and x.shininess == 27.8974
    assert library["brass"].kd.tolist() == SEED_TABLE["brass"][1]   # the library is untouched


def test_base_chain_through_scene_materials(tmp_path):
    scene = _scene_materials(tmp_path, """
[materials.x]
base = "y"
ks = 0.25
[materials.y]
base = "polished_silver"
shininess = 5
""")
    x = scene.materials["x"]
    assert x.shininess == 5 and x.ks.tolist() == [0.25] * 3
    assert x.kd.tolist() == SEED_TABLE["polished_silver"][1]


def test_inline_material_renders_its_coefficients():
    # An inline table on the object; no lights: I = ka·Ia with ka = kd (omitted ka).
    scene = make_scene([raytrace.Sphere([0, 0, 0], 1.0, material={"kd": [0.2, 0.4, 0.6]})],
                       camera=aimed_camera([0, 0, 4], [0, 0, 0]), ambient=0.5)
    np.testing.assert_allclose(pixel(scene), [0.1, 0.2, 0.3], rtol=RTOL)
    m = scene.objects[0].material
    assert m.kd.tolist() == [0.2, 0.4, 0.6] and m.ks.tolist() == [0, 0, 0]


def test_inline_material_with_base():
    scene = make_scene([raytrace.Sphere([0, 0, 0], 1.0,
                                        material={"base": "brass", "kd": 0.1})])
    m = scene.objects[0].material
    assert m.kd.tolist() == [0.1] * 3 and m.ka.tolist() == SEED_TABLE["brass"][0]


def test_material_defaults():
    # SCENE_FORMAT.md: kd 0.5, ka = kd, ks 0, shininess 32, phong, kr 0, kt 0, ior 1.5, opacity 1.
    m = Material()
    assert m.kd.tolist() == [0.5] * 3 and m.ambient.tolist() == [0.5] * 3
    assert m.ks.tolist() == [0.0] * 3 and m.shininess == 32 and m.highlight == "phong"
    assert m.ior == 1.5 and m.opacity == 1.0 and not m.reflects and not m.transmits


# -- the checker pattern --------------------------------------------------------------------------

A, B = np.array([0.9, 0.8, 0.7]), np.array([0.1, 0.2, 0.3])


def test_checker_parity_at_known_points():
    # colors[0] where floor(x/s + 1e-4) + floor(y/s + 1e-4) + floor(z/s + 1e-4) is even.
    c = Checker((A, B), scale=2.0)
    pts = np.array([[0.5, 0.5, 0.5],      # 0+0+0 even
                    [2.5, 0.5, 0.5],      # 1+0+0 odd
                    [-0.5, 0.5, 0.5],     # −1+0+0 odd
                    [-2.5, -0.5, 3.0],    # −2−1+1 even
                    [4.1, 2.1, -0.1]])    # 2+1−1 even
    np.testing.assert_array_equal(shading.checker(c, pts), [A, B, B, A, A])


def test_checker_bias_picks_a_side_on_a_cell_boundary():
    # A point a hair below y = 0 or y = 1 (rounding noise of a plane lying on the boundary)
    # counts as on the boundary's upper cell, exactly like the boundary itself.
    c = Checker((A, B), scale=1.0)
    for y in (0.0, -1e-12, 1e-12, -1e-6):
        np.testing.assert_array_equal(shading.checker(c, np.array([[0.5, y, 0.5]])), [A])
    for y in (1.0, 1.0 - 1e-12, 1.0 + 1e-12):
        np.testing.assert_array_equal(shading.checker(c, np.array([[0.5, y, 0.5]])), [B])
    # Beyond the bias the side really changes.
    np.testing.assert_array_equal(shading.checker(c, np.array([[0.5, -1e-3, 0.5]])), [B])


@pytest.mark.parametrize("plane_y", [0.0, 1.0, -3.0])
@pytest.mark.parametrize("xz", [(0.5, 0.5), (1.5, 0.5), (-0.5, 0.25), (-1.5, -2.5),
                                (0.999, 0.5)])
def test_checker_on_a_plane_lying_on_a_cell_boundary(plane_y, xz):
    # The plane y = k (an integer) lies exactly on a boundary; the bias puts it in cell k.
    # kd is the checker and ka is omitted (follows kd); no light, Ia = 1: the pixel is the
    # checker colour itself.
    x, z = xz
    cells = math.floor(x + 1e-4) + round(plane_y) + math.floor(z + 1e-4)
    expected = A if cells % 2 == 0 else B
    mat = raytrace.Material(kd={"pattern": "checker", "colors": [A.tolist(), B.tolist()],
                                "scale": 1.0})
    target = np.array([x, plane_y, z])
    scene = make_scene([raytrace.Plane([0.0, plane_y, 0.0], [0, 1, 0], material=mat)],
                       camera=aimed_camera(target + [0.7, 2.3, 3.1], target), ambient=1.0)
    np.testing.assert_allclose(pixel(scene), expected, rtol=RTOL)


def test_bad_checker_tables_name_the_key():
    with pytest.raises(raytrace.SceneError, match="colors") as e:
        Material(kd={"pattern": "checker", "colors": [1.0]})
    assert "kd.colors" in str(e.value)
    with pytest.raises(raytrace.SceneError, match="checker"):
        Material(kd={"pattern": "stripes", "colors": [1.0, 0.0]})


@pytest.mark.parametrize(("make", "key", "table"), [
    # Refused where the value enters, Checker() itself, with the table form's message:
    (lambda: Checker(([0.5, 0.5, 0.5], [-1.0, 0.0, 0.0])), "Checker.colors[1]",   # negative
     {"kd": {"pattern": "checker", "colors": [[0.5, 0.5, 0.5], [-1.0, 0.0, 0.0]]}}),
    (lambda: Checker(([0.5, 0.5, 0.5], [np.nan, 0.0, 0.0])), "Checker.colors[1]",  # NaN
     {"kd": {"pattern": "checker", "colors": [[0.5, 0.5, 0.5], [np.nan, 0.0, 0.0]]}}),
    (lambda: Checker((0.5, 0.2), scale=0.0), "Checker.scale",                     # no cell size
     {"ks": {"pattern": "checker", "colors": [0.5, 0.2], "scale": 0.0}}),
    (lambda: Checker((0.5,)), "Checker.colors",                                  # one colour
     {"kd": {"pattern": "checker", "colors": [0.5]}}),
    # kr above 1 is a fine checker but not a fine kr: refused by the Material.
    (lambda: Material(kr=Checker((0.5, 1.5))), "kr.colors[1]",
     {"kr": {"pattern": "checker", "colors": [0.5, 1.5]}}),
])
def test_a_checker_built_in_python_is_validated_like_a_table(make, key, table):
    with pytest.raises(raytrace.SceneError) as e:
        make()
    assert key in str(e.value)
    with pytest.raises(raytrace.SceneError) as t:
        Material(**table)
    assert e.value.problem == t.value.problem  # the same message either way


def test_a_valid_python_checker_is_kept_with_rgb_colours():
    m = Material(kd=Checker((0.25, [0.1, 0.2, 0.3]), scale=2.0))
    assert isinstance(m.kd, Checker) and m.kd.scale == 2.0
    np.testing.assert_array_equal(m.kd.colors[0], [0.25, 0.25, 0.25])
    np.testing.assert_array_equal(m.kd.colors[1], [0.1, 0.2, 0.3])


# -- the box-filtered checker (filter = "box") ----------------------------------------------------

def _box_share(points, extents, scale=1.0):
    points = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
    extents = np.ascontiguousarray(np.broadcast_to(np.asarray(extents, np.float64),
                                                   points.shape))
    out = np.empty(len(points))
    checker_box_rows(points, extents, scale, out)
    return out


def test_a_box_across_one_cell_edge_holds_the_odd_share_worked_by_hand():
    # x = 0.25 ± 0.5 with the bias: [−0.2499, 0.7501] in cells, s = −1 on its 0.2499 below 0
    # and +1 on its 0.7501 above: mean 0.5002; y = z = 0.5 lie in cell 0 (s = +1), width 0.
    # Odd share (1 − 0.5002·1·1)/2 = 0.2499.
    np.testing.assert_allclose(_box_share([0.25, 0.5, 0.5], [0.5, 0.0, 0.0]), [0.2499],
                               rtol=1e-12)
    # Two axes: x as above, z = 0.5 ± 1 spans [−0.4999, 1.5001]: −1 over 0.4999, +1 over 1,
    # −1 over 0.5001, mean (1 − 0.4999 − 0.5001)/2 = 0: the product is 0, the share 1/2.
    np.testing.assert_allclose(_box_share([0.25, 0.5, 0.5], [0.5, 0.0, 1.0]), [0.5],
                               atol=1e-12)
    # With scale 2, a box of half-width 1 around x = 1 covers [0.0001, 1.0001] in cells:
    # +1 over 0.9999, −1 over 0.0001: mean 0.9998, odd share 0.0001.
    np.testing.assert_allclose(_box_share([1.0, 1.0, 1.0], [1.0, 0.0, 0.0], scale=2.0),
                               [0.0001], rtol=1e-9)


def test_a_box_inside_one_cell_is_the_cells_parity_exactly():
    rng = np.random.default_rng(7)
    points = rng.uniform(-50.0, 50.0, (400, 3))
    frac = points - np.floor(points + 1e-4)  # where each lies in its cell
    extents = 0.9 * np.minimum(frac + 1e-4, 1.0 - (frac + 1e-4))  # not reaching an edge
    odd = np.empty(len(points), np.int64)
    checker_rows(points, 1.0, odd)
    assert np.array_equal(_box_share(points, extents), odd.astype(np.float64))


def test_the_box_share_is_the_mean_parity_over_the_box():
    # A midpoint sum of checker1's parity over a 200³-cell grid inside each box.
    rng = np.random.default_rng(3)
    for _ in range(6):
        centre, half = rng.uniform(-3.0, 3.0, 3), rng.uniform(0.05, 2.5, 3)
        ticks = [c + h * ((np.arange(200) + 0.5) / 100.0 - 1.0)
                 for c, h in zip(centre, half, strict=True)]
        grid = np.stack(np.meshgrid(*ticks, indexing="ij"), axis=-1).reshape(-1, 3)
        odd = np.empty(len(grid), np.int64)
        checker_rows(grid, 1.0, odd)
        np.testing.assert_allclose(_box_share(centre, half), odd.mean(), atol=0.012)


def test_an_infinite_box_is_half_odd_and_a_nan_point_is_nan():
    np.testing.assert_array_equal(_box_share([0.3, 0.2, 0.1], [np.inf, 0.0, 0.0]), [0.5])
    np.testing.assert_array_equal(_box_share([0.3, 0.2, 0.1], [1e300, 1e300, 1e300]), [0.5])
    assert np.isnan(_box_share([np.nan, 0.2, 0.1], [0.5, 0.5, 0.5])[0])


def _receding_floor(kind, spp):
    """A checkered floor seen at a slant to the horizon, 96 × 72: ambient 1 and no light, so
    a pixel is the pixel filter's mean of kd over it (sky 0.5)."""
    mat = raytrace.Material(kd={"pattern": "checker", "colors": [A.tolist(), B.tolist()],
                                "scale": 1.0, "filter": kind})
    return make_scene([raytrace.Plane([0.0, 0.0, 0.0], [0, 1, 0], material=mat)],
                      camera=aimed_camera(np.array([0.3, 1.0, 0.2]), np.array([-2.0, 0.0, -10.0])),
                      ambient=1.0, width=96, height=72, spp=spp, background=0.5)


def test_one_box_filtered_sample_is_the_pixels_mean_of_the_checker():
    # The pixel's mean: 256 stratified samples of the unfiltered checker. One box-filtered
    # sample a pixel: RMSE 0.0093, largest error 0.091 (measured); one plain sample beats
    # into moiré (RMSE 0.126) and four stratified ones still show it (0.061).
    mean = raytrace.render(_receding_floor("none", 256)).rgb
    box = raytrace.render(_receding_floor("box", 1)).rgb - mean
    plain = raytrace.render(_receding_floor("none", 1)).rgb - mean
    rmse = np.sqrt(np.mean(box ** 2))
    assert rmse < 0.015 and np.abs(box).max() < 0.15
    assert np.sqrt(np.mean(plain ** 2)) > 8.0 * rmse


def test_a_filtered_checker_mixes_its_colours_by_the_share():
    c = Checker((A, B), scale=1.0, filter="box")
    view, normal = np.array([[-3.0, -1.0, -8.0]]), np.array([[0.0, 1.0, 0.0]])
    share = np.empty(1)
    footprint_rows(view, normal, 0.3, view, 1.0, share)
    assert 0.0 < share[0] < 1.0
    np.testing.assert_allclose(shading.filtered_checker(c, view, view, normal, 0.3),
                               [(1.0 - share[0]) * A + share[0] * B], rtol=1e-15)
    # No boundary inside the footprint: the cell's colour, bit for bit.
    inside = np.array([[0.5, 0.5, -7.5]])
    assert np.array_equal(shading.filtered_checker(c, inside, inside, [[0.0, 0.0, 1.0]], 1e-4),
                          shading.checker(c, inside))


def test_a_checkers_filter_is_checked_like_its_other_keys():
    with pytest.raises(raytrace.SceneError) as e:
        Material(kd={"pattern": "checker", "colors": [0.2, 0.8], "filter": "gauss"})
    assert "kd.filter: must be one of 'none', 'box', got 'gauss'" in str(e.value)
    with pytest.raises(raytrace.SceneError) as p:
        Checker((0.2, 0.8), filter="gauss")
    assert "Checker.filter" in str(p.value) and p.value.problem == e.value.problem
    assert Material(kd=Checker((0.2, 0.8), filter="box")).kd.filter == "box"


# -- `raytrace materials` -------------------------------------------------------------------------

def test_materials_command_lists_the_library(capsys):
    assert cli.main(["materials"]) == 0
    out = capsys.readouterr().out.splitlines()
    listed = [line.split()[0] for line in out]
    assert listed == list(library)
    brass = next(line for line in out if line.startswith("brass "))
    assert library.describe("brass")["description"] in brass
    glass = next(line for line in out if line.startswith("glass "))
    assert "ior=1.5" in glass


@pytest.mark.parametrize("scale", [1e-300, 1e-13, 1e13, 1e300])
def test_a_checker_cell_outside_the_length_bounds_is_refused(scale):
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.scene_from_dict({"materials": {"floor": {"kd": {
            "pattern": "checker", "colors": [0.2, 0.8], "scale": scale}}}})
    assert str(e.value) == (f"materials.floor.kd.scale: must be within [1e-12, 1e+12] (the "
                            f"lengths at which a scene renders as it does at unit size), "
                            f"got {scale!r}")


# -- model-file materials: a rough one stays matte (material.file_shininess) -----------------
#: A unit sphere at the origin seen, and lit by a unit point light, from E = (0, 0, 5).
EYE = np.array([0.0, 0.0, 5.0])
#: The point Q = (sin θ, 0, cos θ) of the sphere where N·L = 0.2 for the light at E: with
#: N = Q and L = (E − Q)/|E − Q|, N·L = (5c − 1)/√(26 − 10c) for c = cos θ. Setting it to 0.2
#: and squaring: (5c − 1)² = 0.04·(26 − 10c), i.e. 25c² − 9.6c − 0.04 = 0, whose root with
#: 5c − 1 > 0 is c = (9.6 + √(9.6² + 4·25·0.04))/50 = (9.6 + √96.16)/50 = 0.388122.
COS_Q = (9.6 + math.sqrt(96.16)) / 50
GRAZING = np.array([math.sqrt(1 - COS_Q**2), 0.0, COS_Q])


def _front_and_grazing(material: Material) -> tuple[np.ndarray, np.ndarray]:
    """The sphere's pixel where N·L = 1 (Q = (0, 0, 1)) and where N·L = 0.2 (GRAZING): one
    point light at the camera, ambient 0, black background, depth 0."""
    def at(q):
        scene = make_scene([raytrace.Sphere([0, 0, 0], 1.0, material=material)],
                           [raytrace.PointLight(EYE)], aimed_camera(EYE, q), ambient=0.0,
                           background=0.0, max_depth=0)
        return pixel(scene)
    return at([0.0, 0.0, 1.0]), at(GRAZING)


def _gltf_material(tmp_path, metallic: float, roughness: float) -> Material:
    quad = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 2]],
            "material": 0}
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.5, 0.05, 1.0],
                                    "metallicFactor": metallic, "roughnessFactor": roughness}}
    path = write_gltf(tmp_path / "m.gltf", [{"mesh": 0}], [quad], [mat])
    return raytrace.Mesh(file=path, material="from_file").material


def _mtl_material(tmp_path, ns: float) -> Material:
    write_text(tmp_path / "m.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    write_text(tmp_path / "m.mtl", f"newmtl m\nKd 0.05\nKs 1\nNs {ns}\nillum 2\n")
    return raytrace.Mesh(file=tmp_path / "m.obj", material="from_file").material


@pytest.mark.parametrize("source,make", [
    *((f"glTF metallic {m} roughness {r}", lambda p, m=m, r=r: _gltf_material(p, m, r))
      for m in (0.0, 1.0) for r in (0.9, 1.0)),
    *((f"MTL Ks 1 Ns {n}", lambda p, n=n: _mtl_material(p, n)) for n in (0, 0.5, 1))])
def test_a_rough_model_material_stays_matte(tmp_path, source, make):
    """docs/scene_format.md's mapping: no term is constant over the lit surface. Where
    N·L = 0.2 a pixel is at most 0.35 of its value where N·L = 1 (Lambert alone gives 0.2;
    the old mapping, shininess 0 and ks = F0 = 1, gave 1: flat white)."""
    front, grazing = _front_and_grazing(make(tmp_path))
    assert np.all(front > 0.01), source
    assert np.all(grazing <= 0.35 * front), (source, grazing / front)


def test_interior_keys_from_a_scene_file_give_beers_sigma(tmp_path):
    # σ = −ln(c)/D per channel: c = (0.5, 0.25, 1), D = 2 → (ln 2/2, ln 4/2, 0) =
    # (0.34657, 0.69315, 0); thin_walled and inf (TOML's `inf`) as written.
    scene = _scene_materials(tmp_path, """
[materials.x]
kt = 1.0
attenuation_color = [0.5, 0.25, 1.0]
attenuation_distance = 2.0
[materials.pane]
kt = 1.0
thin_walled = true
attenuation_distance = inf
""")
    x, pane = scene.materials["x"], scene.materials["pane"]
    np.testing.assert_allclose(x.sigma, [math.log(2) / 2, math.log(4) / 2, 0.0], rtol=1e-15)
    assert x.absorbs and not x.thin_walled
    assert pane.thin_walled and not pane.absorbs and pane.sigma.tolist() == [0.0] * 3
    assert Material().sigma.tolist() == [0.0] * 3 and not Material().absorbs


@pytest.mark.parametrize(("table", "key", "problem"), [
    ('attenuation_color = [0.5, 0.0, 0.5]', "attenuation_color", "must be > 0 in every channel"),
    ('attenuation_color = 1.5', "attenuation_color", "must be <= 1"),
    ('attenuation_distance = 0.0', "attenuation_distance", "must be > 0"),
    ('attenuation_distance = -inf', "attenuation_distance", "must be finite"),
    ('thin_walled = 1', "thin_walled", "must be true or false"),
    ('thin_walled = true\nattenuation_distance = 3.0\nattenuation_color = 0.5', "thin_walled",
     "a thin wall has no inside to absorb in"),
])
def test_bad_interior_keys_are_one_line_naming_the_key(tmp_path, table, key, problem):
    with pytest.raises(raytrace.SceneError) as e:
        _scene_materials(tmp_path, f"[materials.x]\nkt = 1.0\n{table}\n")
    assert f"materials.x.{key}: {problem}" in str(e.value)
    assert "\n" not in str(e.value)


def test_normal_map_and_bump_tables_read_linear_texels_from_the_scene_folder(tmp_path):
    """``normal_map = { texture, scale, wrap }`` and ``bump = …``: the file relative to the
    scene's folder, its 8-bit codes read as linear c/255 (a normal map's are vectors, not
    colours: 204 → 0.8, where sRGB would give 0.6038), the scale kept."""
    write_png(tmp_path / "n.png", np.tile(np.array([204, 128, 230], np.uint8), (2, 2, 1)))
    scene = _scene_materials(tmp_path, """
[materials.x]
kd = 0.5
normal_map = { texture = "n.png", scale = 0.5, wrap = "clamp" }
[materials.y]
bump = { texture = "n.png", scale = 0.02 }
""")
    m = scene.materials["x"]
    assert m.normal_map.scale == 0.5 and m.bump is None
    np.testing.assert_allclose(m.normal_map.texture.texels[0, 0, :3], [0.8, 128 / 255, 230 / 255],
                               rtol=1e-6)
    assert m.normal_map.texture.wrap == ("clamp", "clamp")
    assert scene.materials["y"].bump.scale == 0.02
    assert tmp_path / "n.png" in m.files


@pytest.mark.parametrize("text,key,problem", [
    ('normal_map = { texture = "n.png" }\nbump = { texture = "n.png" }', "materials.x.bump",
     "a material takes normal_map or bump, not both"),
    ('normal_map = { texture = "n.png", srgb = true }', "materials.x.normal_map.srgb",
     "unknown key"),
    ('bump = { texture = "n.png", scale = "big" }', "materials.x.bump.scale",
     "must be a number"),
    ('normal_map = "n.png"', "materials.x.normal_map", "must be a table"),
])
def test_a_bad_normal_map_or_bump_is_one_line_naming_the_key(tmp_path, text, key, problem):
    write_png(tmp_path / "n.png", np.full((2, 2, 3), 128, np.uint8))
    with pytest.raises(raytrace.SceneError) as e:
        _scene_materials(tmp_path, f"[materials.x]\n{text}\n")
    assert f"{key}: {problem}" in str(e.value)


def test_a_head_on_footprint_is_one_box_of_the_cones_half_width():
    # Seen head on (d = −n), the cone's footprint is a disc of radius r = ½·γ·|P|, one box of
    # half-widths r·√(1 − nᵢ²): on the wall z = −4 seen from the origin, γ = 0.5: r = 1 in x
    # and y, 0 in z.
    view, normal = np.array([[0.0, 0.0, -4.0]]), np.array([[0.0, 0.0, 1.0]])
    share = np.empty(1)
    footprint_rows(view, normal, 0.5, np.array([[0.25, 0.5, -3.5]]), 1.0, share)
    np.testing.assert_array_equal(share, _box_share([0.25, 0.5, -3.5], [1.0, 1.0, 0.0]))
    # x over [−0.7499, 1.2501]: −0.7499 + 1 − 0.2501 = 0, so half the cells are odd.
    np.testing.assert_allclose(share, [0.5], atol=1e-12)


def test_a_grazing_footprint_is_half_odd_at_any_angle_however_small():
    view = np.array([[3.0, -1e-30, -4.0], [0.0, -1e-300, -1.0]])
    normal = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    share = np.empty(2)
    footprint_rows(view, normal, 0.01, view + [0.3, 0.0, 0.3], 1.0, share)
    np.testing.assert_allclose(share, [0.5, 0.5], atol=1e-12)
