"""Scene files: every kind of bad input gives exit status 2 and one line naming the file, the
key and the problem, with no traceback and no output; JSON scenes are TOML's twins."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from helpers import write_text

import raytrace
from raytrace import cli

BASE = """\
[render]
width = 4
height = 3

[camera]
position = [0.0, 1.0, 5.0]
look_at = [0.0, 0.0, 0.0]

[ambient]
color = 0.1

[[lights]]
type = "point"
position = [2.0, 4.0, 3.0]

[[objects]]
type = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "brass"
"""


def _edit(old: str, new: str) -> str:
    assert old in BASE
    return BASE.replace(old, new, 1)


# (case id, scene text, the key the message must name, a piece of the problem)
BAD_TOML = [
    ("unknown-top-level", BASE + "\n[foo]\nx = 1\n", "foo", "unknown key"),
    ("unknown-nested", _edit("width = 4", "width = 4\nwidht = 5"), "render.widht",
     "unknown key"),
    ("unknown-in-camera", _edit("look_at = [0.0, 0.0, 0.0]",
                                "look_at = [0.0, 0.0, 0.0]\nzoom = 2"),
     "camera.zoom", "unknown key"),
    ("unknown-in-light", _edit("position = [2.0, 4.0, 3.0]",
                               "position = [2.0, 4.0, 3.0]\nintensity = 3"),
     "lights[0].intensity", "unknown key"),
    ("unknown-in-object", _edit("radius = 1.0", "radius = 1.0\nradios = 2"),
     "objects[0].radios", "unknown key"),
    ("unknown-in-material", BASE + "\n[materials.m]\nkd = 0.5\nshine = 3\n",
     "materials.m.shine", "unknown key"),
    ("unknown-in-inline-material", _edit('material = "brass"', 'material = { kdd = 0.5 }'),
     "objects[0].material.kdd", "unknown key"),
    ("wrong-type-number", _edit("radius = 1.0", 'radius = "big"'), "objects[0].radius",
     "must be a number"),
    ("wrong-type-vector", _edit("position = [0.0, 1.0, 5.0]", 'position = "here"'),
     "camera.position", "list of 3 numbers"),
    ("wrong-type-table", BASE + '\ncamera2 = 1\n', "camera2", "unknown key"),
    ("wrong-type-bool", _edit('type = "point"\nposition = [2.0, 4.0, 3.0]',
                              'type = "area"\nposition = [0, 4, 0]\nedge_u = [1, 0, 0]\n'
                              'edge_v = [0, 0, 1]\njitter = "yes"'),
     "lights[0].jitter", "true or false"),
    ("negative-radius", _edit("radius = 1.0", "radius = -1.0"), "objects[0].radius",
     "must be > 0"),
    ("fov-0", _edit("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 0.0]\nfov = 0"),
     "camera.fov", "must be > 0"),
    ("fov-180", _edit("look_at = [0.0, 0.0, 0.0]", "look_at = [0.0, 0.0, 0.0]\nfov = 180"),
     "camera.fov", "must be < 180"),
    ("kr-over-1", BASE + "\n[materials.m]\nkr = 1.5\n", "materials.m.kr", "must be <= 1"),
    ("kt-over-1-inline", _edit('material = "brass"', 'material = { kt = [0.5, 1.2, 0.5] }'),
     "objects[0].material.kt[1]", "must be <= 1"),
    ("negative-color", _edit('type = "point"', 'type = "point"\ncolor = -1'),
     "lights[0].color", "must be >= 0"),
    ("spot-cutoff-over-90", _edit('type = "point"\nposition = [2.0, 4.0, 3.0]',
                                  'type = "spot"\nposition = [0, 4, 0]\ndirection = [0, -1, 0]'
                                  '\ncutoff = 120'), "lights[0].cutoff", "must be <= 90"),
    ("missing-required", _edit("radius = 1.0\n", ""), "objects[0].radius", "is required"),
    ("missing-mesh-file", BASE + '\n[[objects]]\ntype = "mesh"\nfile = "nothere.obj"\n',
     "objects[1].file", "nothere.obj"),
    ("nan-in-mesh", BASE + '\n[[objects]]\ntype = "mesh"\nvertices = [[0, 0, 0], [1, 0, 0], '
     '[0, nan, 0]]\nfaces = [[0, 1, 2]]\n', "objects[1].vertices", "not finite"),
    ("invalid-toml", BASE + "\n[[objects\n", "line", "invalid TOML"),
    ("unknown-material-name", _edit('"brass"', '"unobtainium"'), "objects[0].material",
     "unknown material 'unobtainium'"),
    ("unknown-light-type", _edit('type = "point"', 'type = "laser"'), "lights[0].type",
     "'laser'"),
    ("unknown-object-type", _edit('type = "sphere"', 'type = "torus"'), "objects[0].type",
     "'torus'"),
    ("unknown-highlight", BASE + '\n[materials.m]\nhighlight = "cook"\n',
     "materials.m.highlight", "'cook'"),
    ("bad-base", BASE + '\n[materials.m]\nbase = "nothing"\n', "materials.m.base",
     "unknown material 'nothing'"),
    ("base-cycle", BASE + '\n[materials.a]\nbase = "b"\n[materials.b]\nbase = "a"\n',
     "base", "cycle"),
    ("base-self", BASE + '\n[materials.a]\nbase = "a"\n', "materials.a.base", "cycle"),
    ("area-samples-not-square", _edit('type = "point"\nposition = [2.0, 4.0, 3.0]',
                                      'type = "area"\nposition = [0, 4, 0]\nedge_u = [1, 0, 0]'
                                      '\nedge_v = [0, 0, 1]\nsamples = 8'),
     "lights[0].samples", "perfect square"),
]


def _run_bad(tmp_path: Path, scene: Path, capsys, extra=()) -> str:
    """Render ``scene`` expecting bad input; return the single stderr line."""
    out = tmp_path / "out.exr"
    before = set(os.listdir(tmp_path))
    rc = cli.main(["render", str(scene), "-o", str(out), "--png", str(tmp_path / "p.png"),
                   "--stats", str(tmp_path / "stats.json"), "-q", *extra])
    captured = capsys.readouterr()
    assert rc == 2
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    assert set(os.listdir(tmp_path)) == before, "an output file was written"
    assert lines[0].startswith("raytrace: error: ")
    return lines[0]


@pytest.mark.parametrize("case,text,key,problem", BAD_TOML, ids=[c[0] for c in BAD_TOML])
def test_bad_toml_scene(tmp_path, capsys, case, text, key, problem):
    scene = write_text(tmp_path / "bad scene.toml", text)
    line = _run_bad(tmp_path, scene, capsys)
    assert str(scene) in line
    assert key in line
    assert problem in line


def test_missing_scene_file(tmp_path, capsys):
    line = _run_bad(tmp_path, tmp_path / "nowhere.toml", capsys)
    assert str(tmp_path / "nowhere.toml") in line and "not found" in line


def test_failed_render_leaves_an_existing_output_untouched(tmp_path, capsys):
    out = tmp_path / "out.exr"
    out.write_bytes(b"previous render")
    scene = write_text(tmp_path / "s.toml", _edit("radius = 1.0", "radius = -2"))
    line = _run_bad(tmp_path, scene, capsys)
    assert "objects[0].radius" in line
    assert out.read_bytes() == b"previous render"


def test_bad_input_in_a_real_subprocess(tmp_path):
    scene = write_text(tmp_path / "s.toml", _edit("radius = 1.0", "radius = 1.0\nradios = 2"))
    proc = subprocess.run([sys.executable, "-m", "raytrace", "render", str(scene), "-o",
                           str(tmp_path / "o.exr")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert str(scene) in lines[0] and "objects[0].radios" in lines[0]
    assert "unknown key" in lines[0]
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


# -- JSON ------------------------------------------------------------------------------------------

def _json_twin(tmp_path: Path, text: str, name: str = "s.json") -> Path:
    return write_text(tmp_path / name, json.dumps(tomllib.loads(text), indent=1))


BAD_JSON = [c for c in BAD_TOML if c[0] in (
    "unknown-top-level", "unknown-nested", "unknown-in-light", "unknown-in-material",
    "wrong-type-number", "fov-180", "base-cycle", "unknown-object-type", "nan-in-mesh")]


@pytest.mark.parametrize("case,text,key,problem", BAD_JSON, ids=[c[0] for c in BAD_JSON])
def test_bad_json_scene(tmp_path, capsys, case, text, key, problem):
    scene = _json_twin(tmp_path, text)
    line = _run_bad(tmp_path, scene, capsys)
    assert str(scene) in line and key in line and problem in line


def test_invalid_json(tmp_path, capsys):
    scene = write_text(tmp_path / "s.json", '{"camera": {"fov": 40,}}')
    line = _run_bad(tmp_path, scene, capsys)
    assert str(scene) in line and "invalid JSON" in line and "line 1" in line


@pytest.mark.parametrize("name,text", [
    ("deep.json", '{"objects": ' + "[" * 100_000 + "]" * 100_000 + "}"),
    ("deep.toml", "objects = " + "[" * 100_000 + "]" * 100_000 + "\n"),
])
def test_a_scene_nested_deeper_than_the_parser_can_go_is_one_line(tmp_path, capsys, name, text):
    # was a RecursionError traceback from json/tomllib
    scene = write_text(tmp_path / name, text)
    line = _run_bad(tmp_path, scene, capsys)
    assert line == (f"raytrace: error: {scene}: nested too deep to read (a scene is at most "
                    "32 levels deep)")


def test_a_scene_nested_deeper_than_a_scene_needs_names_the_entry(tmp_path, capsys):
    deep = {"type": "sphere", "center": [0, 0, 0], "radius": 1.0}
    for _ in range(40):
        deep = {"a": deep}
    scene = write_text(tmp_path / "s.json", json.dumps({"objects": [{"material": deep}]}))
    line = _run_bad(tmp_path, scene, capsys)
    assert line == f"raytrace: error: {scene}: objects[0]: nested more than 32 levels deep"
    # Python dicts too, one that contains itself included (was a RecursionError)
    looped: dict = {"kd": 0.5}
    looped["base"] = looped
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.scene_from_dict({"materials": {"loop": looped}})
    assert str(e.value) == "materials.loop: nested more than 32 levels deep"


def test_json_scene_renders_the_same_pixels_as_its_toml_twin(tmp_path):
    text = BASE + """
[materials.floor]
kd = { pattern = "checker", colors = [[0.9, 0.9, 0.9], [0.1, 0.1, 0.1]], scale = 0.5 }
kr = 0.2

[[objects]]
type = "plane"
point = [0.0, -1.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"

[[objects]]
type = "mesh"
vertices = [[-1, 0, -1], [1, 0, -1], [0, 2, -1.5]]
faces = [[0, 1, 2]]
material = { base = "polished_silver", kr = 0.3 }
"""
    toml_path = write_text(tmp_path / "s.toml", text)
    json_path = _json_twin(tmp_path, text)
    a = raytrace.render(raytrace.load_scene(toml_path), width=12, height=9)
    b = raytrace.render(raytrace.load_scene(json_path), width=12, height=9)
    assert a.rgb.max() > 0.1 and (a.rgb[..., 0] > 0).mean() > 0.5   # something is there
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert a.stats["rays"] == b.stats["rays"]


# -- good files ------------------------------------------------------------------------------

def test_defaults_of_an_empty_scene(tmp_path):
    # A file of nothing but a comment: every table takes its defaults. (A file with no text at
    # all is an error: test_an_empty_scene_file_is_an_error.)
    scene = raytrace.load_scene(write_text(tmp_path / "e.toml", "# all defaults\n"))
    r = scene.render
    assert (r.width, r.height, r.spp, r.max_depth, r.min_weight, r.seed) == (640, 480, 1, 5,
                                                                            0.0, 0)
    assert r.background.tolist() == [0, 0, 0] and scene.ambient.tolist() == [0, 0, 0]
    cam = scene.camera
    assert cam.position.tolist() == [0, 0, 0] and cam.look_at.tolist() == [0, 0, -1]
    assert cam.fov == 40.0
    assert scene.objects == [] and scene.lights == []


def test_an_empty_scene_file_is_an_error(tmp_path):
    for text in ("", "\n  \n"):
        with pytest.raises(raytrace.SceneError, match="the scene file is empty"):
            raytrace.load_scene(write_text(tmp_path / "e.toml", text))


def test_an_unknown_material_in_a_scene_file_suggests_the_closest(tmp_path):
    path = write_text(tmp_path / "s.toml", '[materials.gold_leaf]\nbase = "polished_gld"\n')
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.load_scene(path)
    assert ("unknown material 'polished_gld' (did you mean 'polished_gold' or "
            "'polished_silver'?)") in str(e.value)
    assert e.value.key == "materials.gold_leaf.base"


def test_a_scene_material_may_refine_the_library_one_of_its_name(tmp_path):
    from raytrace.material import library

    scene = raytrace.load_scene(write_text(tmp_path / "s.toml", """
[materials.brass]
base = "brass"
kr = 0.3
[[objects]]
type = "sphere"
center = [0, 0, -3]
radius = 1
material = "brass"
"""))
    mine, lib = scene.objects[0].material, library["brass"]
    assert mine is scene.materials["brass"] and mine is not lib
    assert mine.kr.tolist() == [0.3, 0.3, 0.3] and lib.kr.tolist() == [0, 0, 0]
    for k in ("ka", "kd", "ks", "shininess", "highlight", "ior", "opacity"):
        assert np.array_equal(getattr(mine, k), getattr(lib, k)), k
    # Without a library material of that name it stays a cycle, and says why.
    with pytest.raises(raytrace.SceneError, match=r"cycle: mine -> mine \(a material may take "
                                                  r"only the library material of its own name"):
        raytrace.load_scene(write_text(tmp_path / "t.toml", '[materials.mine]\nbase = "mine"\n'))


def test_the_documented_air_bubble_states_its_index_relative_to_the_glass():
    # docs/scene_format.md says where `ior` is defined that it is relative to the medium
    # outside, and its example of an air bubble in glass must follow that rule: 1.0 / 1.5.
    import re
    import textwrap

    from raytrace.material import library

    doc = (Path(__file__).resolve().parents[1] / "docs" / "scene_format.md").read_text()
    row = next(line for line in doc.splitlines() if line.startswith("| `ior` |"))
    assert "Relative to the medium just outside the surface" in row
    block = next(b for b in re.findall(r"```toml\n(.*?)```", doc, re.S)
                 if "[materials.bubble]" in b)
    scene = raytrace.scene_from_dict(tomllib.loads(textwrap.dedent(block)))
    glass, bubble = (o.material for o in scene.objects)
    assert glass is library["glass"]
    assert bubble.ior == pytest.approx(1.0 / glass.ior, abs=1e-4)


def test_light_and_object_defaults(tmp_path):
    scene = raytrace.load_scene(write_text(tmp_path / "d.toml", """
[[lights]]
position = [0, 1, 0]
[[lights]]
type = "spot"
position = [0, 1, 0]
direction = [0, -2, 0]
[[lights]]
type = "area"
position = [0, 1, 0]
edge_u = [1, 0, 0]
edge_v = [0, 0, 1]
[[objects]]
type = "mesh"
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
faces = [[0, 1, 2]]
"""))
    point, spot, area = scene.lights
    assert point.type == "point" and point.color.tolist() == [1, 1, 1]
    assert point.attenuation.tolist() == [1, 0, 0]
    assert spot.exponent == 0 and spot.direction.tolist() == [0, -1, 0]
    assert area.samples == 16 and area.jitter is False
    mesh = scene.objects[0]
    assert mesh.shading == "flat" and mesh.material.kd.tolist() == [0.5] * 3


def test_mesh_file_is_relative_to_the_scene_folder(tmp_path):
    (tmp_path / "models").mkdir()
    write_text(tmp_path / "models" / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    write_text(tmp_path / "s.toml", """
[[objects]]
type = "mesh"
file = "models/tri.obj"
scale = 2.0
translate = [1, 0, 0]
""")
    cwd = os.getcwd()
    try:
        os.chdir("/")
        scene = raytrace.load_scene(tmp_path / "s.toml")
    finally:
        os.chdir(cwd)
    np.testing.assert_allclose(scene.objects[0].vertices, [[1, 0, 0], [3, 0, 0], [1, 2, 0]])


def test_mesh_transform_order_scale_rotate_translate(tmp_path):
    # (1, 0, 0) scaled by 2 → (2, 0, 0), rotated 90° about y → (0, 0, −2), translated by
    # (0, 5, 0) → (0, 5, −2).
    m = raytrace.Mesh(vertices=[[1, 0, 0], [0, 1, 0], [0, 0, 1]], faces=[[0, 1, 2]], scale=2.0,
                      rotate=[0, 90, 0], translate=[0, 5, 0])
    np.testing.assert_allclose(m.vertices, [[0, 5, -2], [0, 7, 0], [2, 5, 0]], atol=1e-12)


QUAD_PLY = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n")


@pytest.mark.parametrize("name,text", [
    ("quad.ply", QUAD_PLY), ("quad.off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n"
                                          "3 1 3 2\n"),
    ("quad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")])
def test_a_mesh_file_without_materials_renders_alone_with_the_default_material(
        tmp_path, name, text):
    # A PLY, an OFF and an OBJ naming no MTL file, given as the scene: the default material
    # (kd 0.5, ka following it, no highlight) under the model ambient 0.1 and the reported
    # directional light: the quad (normal +z) at the image centre is 0.5·0.1 + 0.5·(N·L).
    path = write_text(tmp_path / name, text)
    with pytest.warns(raytrace.RenderWarning, match="no camera in the file"):
        scene = raytrace.load_scene(path)
    (mesh,), (light,) = scene.objects, scene.lights
    assert len(mesh.faces) == 2 and mesh.material.name == "default"
    to_light = -np.asarray(light.direction) / np.linalg.norm(light.direction)
    image = raytrace.render(scene, width=9, height=9, threads=1)
    assert image.rgb[4, 4] == pytest.approx([0.05 + 0.5 * to_light[2]] * 3, rel=1e-6)


def _box_obj(lo, hi, open_front: bool = False) -> str:
    """An OBJ (no MTL) of the box lo..hi: its six faces, or five with the +z side open (a
    Cornell box: floor, ceiling, back and side walls)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]  # index 4x + 2y + z
    quads = [(1, 3, 2, 4), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 2, 4, 3)]
    quads += [] if open_front else [(2, 6, 8, 4)]
    return ("".join(f"v {x} {y} {z}\n" for x, y, z in v)
            + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in quads))


def _view(camera, points, aspect=4 / 3):
    """Image coordinates in [−1, 1] (x right, y up) of ``points`` seen by ``camera``, by the
    pinhole's projection written out here: forward f = unit(look_at − position), right =
    unit(f × up), true up = right × f; x = (p·right)/(p·f)/(aspect·tan(fov/2)), y =
    (p·up)/(p·f)/tan(fov/2); and the depths p·f."""
    f = np.subtract(camera.look_at, camera.position)
    f /= np.linalg.norm(f)
    right = np.cross(f, camera.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    p = np.asarray(points) - camera.position
    t = np.tan(np.radians(camera.fov) / 2)
    return np.column_stack([p @ right / (p @ f) / (aspect * t), p @ up / (p @ f) / t]), p @ f


def _corners(lo, hi):
    return [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


@pytest.mark.parametrize("lo,hi,open_front,want", [
    # a cube of half side 1, level: D = hz + hy/(0.9·tan 20°) = 1 + 1/(0.9·0.363970) = 4.05275
    ((-1, -1, -1), (1, 1, 1), False, (0, 0, 4.05275)),
    # a Cornell box (open at +z; x −1..1, y 0..2, z −1..1): in front of its opening, level
    # with its centre, not behind a side wall: (0, 1, 4.05275) as the cube
    ((-1, 0, -1), (1, 2, 1), True, (0, 1, 4.05275)),
    # a flat wide panel 4 × 1 at z = 0 binds across: D = 2/(0.9·0.363970·4/3) = 4.57913
    ((0, 0, 0), (4, 1, 0), False, (2, 0.5, 4.57913)),
])
def test_the_default_camera_is_in_front_of_a_model_and_frames_its_box(
        tmp_path, lo, hi, open_front, want):
    """A model without a camera is seen from the front (+z, glTF's front), and its bounding
    box fills 90 % of the 640 × 480 view across or up: every corner in the image, none
    behind the camera, and the box spanning at least 0.89 of the width or the height. The
    former camera (a bounding sphere from (0.35, 0.3, 1)) stood at x = 1.69 behind the
    Cornell box's right wall and framed the panel at 0.68 of the width."""
    path = write_text(tmp_path / "box.obj", _box_obj(lo, hi, open_front))
    with pytest.warns(raytrace.RenderWarning, match="no camera in the file"):
        scene = raytrace.load_scene(path)
    np.testing.assert_allclose(scene.camera.position, want, atol=1e-5)
    xy, depth = _view(scene.camera, _corners(lo, hi))
    assert (depth > 0).all() and (np.abs(xy) <= 0.9 + 1e-9).all()
    span = xy.max(axis=0) - xy.min(axis=0)
    assert max(span) >= 2 * 0.89


def test_a_model_lying_flat_is_seen_from_above_the_front(tmp_path):
    """A plate 2 × 0.01 × 2 (its height under a tenth of its depth) is seen from 30° above
    its front, not edge-on: the camera's direction from the centre is (0, sin 30°, cos 30°),
    the plate's corners are in the image and it spans at least 0.89 of the width."""
    lo, hi = (-1, -0.005, -1), (1, 0.005, 1)
    path = write_text(tmp_path / "plate.obj", _box_obj(lo, hi))
    with pytest.warns(raytrace.RenderWarning, match="no camera in the file"):
        scene = raytrace.load_scene(path)
    w = scene.camera.position / np.linalg.norm(scene.camera.position)
    np.testing.assert_allclose(w, [0, 0.5, np.sqrt(3) / 2], atol=1e-12)
    xy, depth = _view(scene.camera, _corners(lo, hi))
    assert (depth > 0).all() and (np.abs(xy) <= 0.9 + 1e-9).all()
    assert xy[:, 0].max() - xy[:, 0].min() >= 2 * 0.89
