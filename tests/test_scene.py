"""The scene's dataclasses built in Python (raytrace/scene.py): a wrong argument is a clear
SceneError naming it when the Scene is made, never an AttributeError from deep inside a render;
mesh paths that are not files say what they are; the disk, the shape added by the recipe of
docs/architecture.md, against closed forms and rendered from TOML and Python."""

from __future__ import annotations

import math
import resource
import subprocess
import sys
import tomllib
import warnings

import numpy as np
import pytest
from helpers import aimed_camera, make_scene, pixel

import raytrace


@pytest.mark.parametrize("kwargs,message", [
    ({"camera": None}, "camera: must be a raytrace.Camera, got NoneType"),
    ({"camera": {"position": [0, 0, 0]}}, "camera: must be a raytrace.Camera, got a table"),
    ({"render": {"width": 4}}, "render: must be a raytrace.RenderSettings, got a table"),
    ({"objects": raytrace.Sphere([0, 0, -3], 1)},
     "objects: must be a list, got Sphere (a single one goes in a list: objects=[...])"),
    ({"lights": raytrace.PointLight([0, 1, 0])},
     "lights: must be a list, got PointLight (a single one goes in a list: lights=[...])"),
    ({"materials": [raytrace.Material()]},
     "materials: must be a dict of name → Material, got a list"),
])
def test_wrong_scene_arguments_are_named_at_construction(kwargs, message):
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Scene(**kwargs)
    assert str(e.value) == message


def test_a_tuple_of_objects_is_a_list_and_a_list_is_kept():
    scene = raytrace.Scene(objects=(raytrace.Sphere([0, 0, -3], 1),))
    assert isinstance(scene.objects, list) and len(scene.objects) == 1
    objects = [raytrace.Sphere([0, 0, -3], 1)]
    assert raytrace.Scene(objects=objects).objects is objects


def _edited_scene() -> raytrace.Scene:
    """A scene of one of each record, for the edits below."""
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
        objects=[raytrace.Sphere([0, 0, 0], 1.0, material="brass"),
                 raytrace.Plane([0, -1, 0], [0, 1, 0]),
                 raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]])],
        lights=[raytrace.PointLight([5, 5, 5]),
                raytrace.AreaLight([0, 4, 0], [1, 0, 0], [0, 0, 1], samples=4)],
        path="edited.toml")


def _set(path: str, value):
    """An edit: ``path`` is ``attribute.attribute…`` from the scene, an index as a number."""
    def edit(scene):
        *parents, last = path.split(".")
        target = scene
        for p in parents:
            target = target[int(p)] if p.isdigit() else getattr(target, p)
        setattr(target, last, value)
    return edit


def _nan_vertex(scene):
    scene.objects[2].vertices[1, 2] = np.nan  # in place: no setter sees it


def _face_past_the_end(scene):
    scene.objects[2].faces[0, 1] = 3


# Each edit made after construction, as issue 28 tried them: before Scene.check every one
# rendered silently or failed deep in the render (AttributeError, TypeError, UFuncTypeError).
@pytest.mark.parametrize("edit,message", [
    (lambda s: s.objects.append(3),
     "objects[3]: must be a Sphere, Plane, Disk or Mesh, got int"),
    (lambda s: s.lights.append("sun"), "lights[2]: must be a light, got str"),
    (_set("lights", None), "lights: must be a list, got NoneType (a single one goes in a list: "
                           "lights=[...])"),
    (_set("objects.0.center", "x"), "objects[0].center: must be a list of 3 numbers, got 'x'"),
    (_set("objects.0.radius", -1), "objects[0].radius: must be > 0, got -1"),
    (_set("objects.1.normal", [0, 0, 0]), "objects[1].normal: must not be the zero vector"),
    (_nan_vertex, "objects[2].vertices: vertex 1 is not finite ([1.0, 0.0, nan]); Embree "
                  "would silently drop its triangles"),
    (_face_past_the_end, "objects[2].faces: index out of range 0..2"),
    (_set("objects.2.scale", 2), "objects[2].scale: was applied to the vertices when the mesh "
                                 "was made (then [1.0, 1.0, 1.0], now 2); transform the "
                                 "vertices, or make a new Mesh"),
    (_set("objects.2.file", "bunny.obj"), "objects[2].file: was read when the mesh was made; "
                                          "make a new Mesh to change it"),
    (_set("objects.2.shading", "phong"), "objects[2].shading: must be one of 'flat', 'smooth', "
                                         "'gouraud', 'fast_phong', 'file', got 'phong'"),
    (_set("objects.0.material", "emerlad"), "objects[0].material: unknown material 'emerlad' "
                                            "(did you mean 'emerald'?)"),
    (_set("lights.0.attenuation", [0, 0, 0]), "lights[0].attenuation: needs a0, a1, a2 >= 0, not "
                                              "all zero (1/(a0 + a1·d + a2·d²)), got "
                                              "[0.0, 0.0, 0.0]"),
    (_set("lights.1.samples", 5), "lights[1].samples: must be a perfect square k² (a k×k grid), "
                                  "got 5; try 4 or 9"),
    (_set("camera.fov", 180), "camera.fov: must be < 180 (the range is (0, 180)), got 180"),
    (_set("ambient", -1), "ambient.color: must be >= 0, got -1"),
])
def test_an_edit_after_construction_is_refused_by_check_as_at_construction(edit, message):
    scene = _edited_scene()
    edit(scene)
    with pytest.raises(raytrace.SceneError) as e:
        scene.check()
    assert str(e.value).startswith(f"edited.toml: {message}")


def test_check_resolves_a_material_name_set_after_construction_and_keeps_what_is_checked():
    scene = _edited_scene()
    scene.objects.append(raytrace.Sphere([2, 0, 0], 0.5, material="emerald"))
    plane, mesh = scene.objects[1], scene.objects[2]
    plane.normal = [0, 2, 0]
    vertices, faces = mesh.vertices, mesh.faces
    scene.check()
    assert scene.objects[3].material is raytrace.materials["emerald"]
    assert plane.normal.tolist() == [0.0, 1.0, 0.0]
    # checked arrays stay the same objects: nothing is copied at every render
    assert mesh.vertices is vertices and mesh.faces is faces


def test_check_moves_no_direction_a_construction_normalised():
    # v/|v| has a length of 1 ± an ulp for a third of directions; normalising it again at
    # every check would move it (and the picture) by an ulp.
    rng = np.random.default_rng(28)
    planes = [raytrace.Plane([0, 0, 0], d) for d in rng.normal(size=(200, 3))]
    lights = [raytrace.DirectionalLight(d) for d in rng.normal(size=(200, 3))]
    before = [p.normal.copy() for p in planes] + [light.direction.copy() for light in lights]
    raytrace.Scene(objects=planes, lights=lights).check()
    after = [p.normal for p in planes] + [light.direction for light in lights]
    assert all(np.array_equal(a, b) for a, b in zip(after, before, strict=True))


def test_a_mesh_path_that_is_a_folder_says_so(tmp_path):
    (tmp_path / "models").mkdir()
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=tmp_path / "models")
    assert str(e.value) == f"file: is a folder, not a mesh file: {tmp_path / 'models'}"
    with pytest.raises(raytrace.SceneError, match="mesh file not found"):
        raytrace.Mesh(file=tmp_path / "nothing.obj")


def test_an_unknown_material_name_suggests_the_closest():
    with pytest.raises(raytrace.SceneError, match=r"unknown material 'bras' \(did you mean "
                                                  r"'brass'\?\)"):
        raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1, material="bras")])


def test_input_files_are_the_scene_its_meshes_and_its_library_materials(tmp_path):
    from raytrace.material import library

    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('[materials.mine]\nbase = "glass"\n'
                                     '[[objects]]\ntype = "mesh"\nfile = "m.obj"\n'
                                     'material = "mine"\n'
                                     '[[objects]]\ntype = "sphere"\ncenter = [0, 0, 0]\n'
                                     'radius = 1\nmaterial = "brass"\n')
    files = raytrace.load_scene(tmp_path / "s.toml").input_files()
    paths = {p for p, _ in files}
    assert paths == {tmp_path / "s.toml", tmp_path / "m.obj", library._files["glass"],
                     library._files["brass"]}


# -- the disk: an analytic shape added by the recipe (scene.py + kernels/accel.py) ----------------
def _disk_pixel(target, disk, light, **render) -> np.ndarray:
    """The one pixel of a camera 3 above ``target`` looking straight down at it."""
    scene = make_scene([disk], [light], aimed_camera(np.add(target, [0, 0, 3.0]), target),
                       ambient=0.5, background=0.25, **render)
    return pixel(scene)


def test_a_disk_facing_the_camera_is_lit_by_lambert_s_law_inside_its_radius():
    # A disk of radius 1 at the origin facing +z (the camera), a point light of colour
    # I_l = (1, 0.5, 0.25) at P + (1.2, 0, 1.6) with f = 1/d², P = (0.3, 0.4, 0) on the disk:
    # d = 2, N·L = 1.6/2 = 0.8, so I = ka·Ia + kd·(N·L)·I_l/d² = 0.2·0.5 + 0.7·0.8·I_l/4
    # = 0.1 + 0.14·I_l = (0.24, 0.17, 0.135).
    disk = raytrace.Disk([0, 0, 0], [0, 0, 1], 1.0, raytrace.Material(ka=0.2, kd=0.7))
    light = raytrace.PointLight([1.5, 0.4, 1.6], [1.0, 0.5, 0.25], attenuation=[0, 0, 1])
    np.testing.assert_allclose(_disk_pixel([0.3, 0.4, 0.0], disk, light),
                               [0.24, 0.17, 0.135], rtol=1e-6)
    # On the rim's radius at (0.6, 0.8): 1e-9 inside it is lit, 1e-9 outside it is the
    # background (0.25) seen past it.
    inside = _disk_pixel(np.multiply([0.6, 0.8, 0.0], 1 - 1e-9), disk, light)
    outside = _disk_pixel(np.multiply([0.6, 0.8, 0.0], 1 + 1e-9), disk, light)
    assert np.all(inside > 0.1) and not np.allclose(inside, 0.25)
    np.testing.assert_array_equal(outside, [0.25, 0.25, 0.25])


def test_a_disk_casts_a_round_shadow():
    # A disk of radius 0.5 at height 1 between a floor and a point light at (0, 3, 0): floor
    # points whose ray to the light crosses y = 1 within 0.5 of the axis get ka·Ia only;
    # (0.4, 0, 0) crosses it at x = 0.4·2/3 ≈ 0.27 (shadowed), (0.9, 0, 0) at 0.6 (lit:
    # ka·Ia + kd·N·L with N·L = 3/√(0.81 + 9)). The disk is seen from below: two-sided.
    floor = raytrace.Plane([0, 0, 0], [0, 1, 0], raytrace.Material(ka=0.2, kd=0.7))
    disk = raytrace.Disk([0, 1, 0], [0, 1, 0], 0.5)
    light = raytrace.PointLight([0, 3, 0])
    for x, lit in ((0.0, False), (0.4, False), (0.9, True)):
        scene = make_scene([floor, disk], [light],
                           aimed_camera([x + 0.3, 0.5, 2.0], [x, 0.0, 0.0]), ambient=0.5)
        want = 0.1 + (0.7 * 3 / np.sqrt(x * x + 9) if lit else 0.0)
        np.testing.assert_allclose(pixel(scene), np.full(3, want), rtol=1e-6)


@pytest.mark.parametrize(("table", "key", "says"), [
    ({"radius": 0}, "radius", "must be"),
    ({"radius": -1}, "radius", "must be"),
    ({"radius": "big"}, "radius", "number"),
    ({"normal": [0, 0, 0]}, "normal", "zero"),
    ({"radius": float("inf")}, "radius", "must be finite"),
    ({"normal": [0, 1]}, "normal", "a list of 3 numbers"),
    ({"center": [0, "a", 0]}, "center[1]", "must be a number"),
    ({"center": None}, "center", "is required"),
    ({"radus": 1}, "radus", "unknown key (did you mean 'radius'?)"),
    ({"material": "brss"}, "material", "did you mean 'brass'?"),
])
def test_a_disk_s_bad_keys_are_one_line_errors_naming_the_key(table, key, says):
    disk = {"type": "disk", "center": [0, 0, -3], "normal": [0, 0, 1], "radius": 1, **table}
    disk = {k: v for k, v in disk.items() if v is not None}
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.scene_from_dict({"objects": [{"type": "sphere", "center": [0, 0, -5],
                                               "radius": 1}, disk]})
    text = str(e.value)
    assert text.startswith(f"objects[1].{key}: ") and says in text and "\n" not in text


def test_a_disk_from_python_is_checked_as_from_a_file():
    with pytest.raises(raytrace.SceneError, match=r"^radius: must be"):
        raytrace.Disk([0, 0, 0], [0, 0, 1], 0.0)
    with pytest.raises(raytrace.SceneError, match=r"^normal: "):
        raytrace.Disk([0, 0, 0], [0, 0, 0], 1.0)


DISK_SCENE = """
[render]
width = 32
height = 24
max_depth = 3
background = [0.3, 0.4, 0.6]

[camera]
position = [0.5, 2.0, 4.0]
look_at = [0.0, 0.6, 0.0]

[ambient]
color = 0.1

[[lights]]
type = "point"
position = [2.0, 4.0, 3.0]

[[lights]]
type = "area"
position = [-1.5, 3.0, 0.0]
edge_u = [0.5, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.5]
samples = 4
jitter = true
color = 0.5

[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = { kd = { pattern = "checker", colors = [0.8, 0.2], scale = 0.5 } }

[[objects]]
type = "disk"                       # a table top, a ball on it
center = [0.0, 0.6, 0.0]
normal = [0.0, 1.0, 0.0]
radius = 0.9
material = "polished_gold"

[[objects]]
type = "sphere"
center = [0.2, 0.9, -0.1]
radius = 0.3
material = "red_plastic"

[[objects]]
type = "disk"                       # a mirror behind
center = [0.0, 1.2, -2.0]
normal = [0.1, 0.0, 1.0]
radius = 1.3
material = "mirror"

[[objects]]
type = "disk"                       # a glass lens in front
center = [-0.7, 0.9, 1.0]
normal = [0.3, 0.2, 1.0]
radius = 0.45
material = "glass"
"""


def _disk_scene_in_python() -> raytrace.Scene:
    floor = raytrace.Material(kd=raytrace.Checker(([0.8] * 3, [0.2] * 3), 0.5))
    return make_scene(
        [raytrace.Plane([0, 0, 0], [0, 1, 0], floor),
         raytrace.Disk([0, 0.6, 0], [0, 1, 0], 0.9, "polished_gold"),
         raytrace.Sphere([0.2, 0.9, -0.1], 0.3, "red_plastic"),
         raytrace.Disk([0, 1.2, -2], [0.1, 0, 1], 1.3, "mirror"),
         raytrace.Disk([-0.7, 0.9, 1], [0.3, 0.2, 1], 0.45, "glass")],
        [raytrace.PointLight([2, 4, 3]),
         raytrace.AreaLight([-1.5, 3, 0], [0.5, 0, 0], [0, 0, 0.5], samples=4, jitter=True,
                            color=0.5)],
        raytrace.Camera([0.5, 2, 4], [0, 0.6, 0]), ambient=0.1, width=32, height=24,
        max_depth=3, background=[0.3, 0.4, 0.6])


@pytest.fixture(scope="module")
def disk_renders(tmp_path_factory) -> dict:
    path = tmp_path_factory.mktemp("disk") / "disks.toml"
    path.write_text(DISK_SCENE)
    scene = raytrace.load_scene(path)
    return {"scene": scene,
            "toml": raytrace.render(scene, threads=1, aovs=["id"]),
            "python": raytrace.render(_disk_scene_in_python(), threads=1),
            "threads": raytrace.render(scene, threads=2, pass_samples=36),
            "crop": raytrace.render(scene, threads=2, crop=(5, 4, 27, 19), aovs=["id"])}


def test_disks_render_the_same_from_toml_and_python_at_any_threads_and_crop(disk_renders):
    full = disk_renders["toml"]
    assert np.isfinite(full.rgb).all() and full.rgb.max() > 0.2
    np.testing.assert_array_equal(disk_renders["python"].rgb, full.rgb)
    np.testing.assert_array_equal(disk_renders["threads"].rgb, full.rgb)
    np.testing.assert_array_equal(disk_renders["crop"].rgb, full.rgb[4:19, 5:27])
    np.testing.assert_array_equal(disk_renders["crop"].aov("id"), full.aov("id")[4:19, 5:27])


def test_disks_are_in_the_id_aov_lit_shadowed_mirrored_and_seen_through(disk_renders):
    # Every disk is seen (its object index in the id AOV), and plays its part where it is
    # seen: the table top changes without the ball (its shadow, and the ball's image in the
    # gold), the mirror disk and the glass disk change when made matte (what they reflect
    # and refract).
    full, ids = disk_renders["toml"].rgb, disk_renders["toml"].aov("id")
    assert {1, 3, 4} <= set(np.unique(ids).tolist())
    matte = raytrace.Material(kd=0.5)
    for change, disk in ((lambda s: s.objects.pop(2), 1),
                         (lambda s: setattr(s.objects[3], "material", matte), 3),
                         (lambda s: setattr(s.objects[4], "material", matte), 4)):
        scene = raytrace.scene_from_dict(tomllib.loads(DISK_SCENE))
        change(scene)
        differ = np.abs(raytrace.render(scene, threads=2).rgb - full).max(axis=2) > 1e-3
        assert differ[ids == disk].sum() > 3, disk


# -- bounds: every position and length within values' limits ---------------------------------
RUNAWAY_SCENE = """[camera]
position = [1e200, 1, 5]
look_at = [0, 0, 0]
[render]
width = 32
height = 24
[[objects]]
type = "sphere"
center = [0, 0, 0]
radius = 1
[[lights]]
type = "point"
position = [2, 2, 2]
"""


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


def render_command(scene) -> subprocess.CompletedProcess:
    """``raytrace render SCENE -o SCENE.exr`` in a child process with 4 GiB of address space
    that must end within 60 s (a runaway fails the test, never the machine)."""
    return subprocess.run([sys.executable, "-m", "raytrace", "render", str(scene), "-o",
                           str(scene.with_suffix(".exr"))], capture_output=True, text=True,
                          timeout=60, preexec_fn=_limit_memory, cwd=scene.parent)


def test_a_camera_at_1e200_is_refused_in_one_line_by_the_command(tmp_path):
    """It used to render without end, growing ~140 MB/s (issue #28)."""
    scene = tmp_path / "far.toml"
    scene.write_text(RUNAWAY_SCENE)
    run = render_command(scene)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [
        f"raytrace: error: {scene}: camera.position[0]: must be within ±1e+12 (where every ray "
        "meets every mesh in Embree's float32), got 1e+200"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.toml"]


def test_a_mesh_transform_that_overflows_is_refused_in_one_line_by_the_command(tmp_path):
    """The overflow's RuntimeWarning, raised while the scene was read, sent the command into
    an endless loop that grew its memory; the transform is now checked without warnings."""
    scene = tmp_path / "huge.toml"
    scene.write_text('[[objects]]\ntype = "mesh"\nvertices = [[0, 0, 0], [1e10, 0, 0], '
                     '[0, 1, 0]]\nfaces = [[0, 1, 2]]\nscale = 1e300\n')
    run = render_command(scene)
    assert run.returncode == 2
    assert run.stderr.splitlines() == [
        f"raytrace: error: {scene}: objects[0].scale: transformed vertices exceed ±1e+12 "
        "(where every ray meets every mesh in Embree's float32)"]


@pytest.mark.parametrize("radius", [1e155, 1e308])
def test_a_sphere_too_large_for_float64_squares_is_refused(radius):
    """r² overflows from ~1.3e154: the sphere vanished, and at 1e308 with the camera inside
    the image was black with no warning."""
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.scene_from_dict({"camera": {"position": [0, 0, 0], "look_at": [0, 0, -1]},
                                  "objects": [{"type": "sphere", "center": [0, 0, 0],
                                               "radius": radius}]})
    assert str(e.value) == (f"objects[0].radius: must be within [1e-12, 1e+12] (the lengths at "
                            f"which a scene renders as it does at unit size), got {radius!r}")


@pytest.mark.parametrize("make,key", [
    (lambda: raytrace.Sphere([0, 0, 2e12], 1), "center[2]"),
    (lambda: raytrace.Disk([0, -1e13, 0], [0, 1, 0], 1), "center[1]"),
    (lambda: raytrace.Disk([0, 0, 0], [0, 1, 0], 1e-13), "radius"),
    (lambda: raytrace.Plane([1e300, 0, 0], [0, 1, 0]), "point[0]"),
    (lambda: raytrace.Camera([0, 0, 0], [0, 0, -1e15]), "camera.look_at[2]"),
    (lambda: raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                           translate=[0, 0, 5e12]), "translate[2]"),
])
def test_positions_and_lengths_beyond_the_bounds_name_their_key(make, key):
    with pytest.raises(raytrace.SceneError) as e:
        make()
    assert e.value.key == key
    assert e.value.problem.startswith(("must be within ±1e+12 (",
                                       "must be within [1e-12, 1e+12] ("))


def test_a_camera_whose_look_at_is_too_close_to_normalise_is_refused():
    """|look_at − position|² underflowed: the camera's basis was NaN and the render silent."""
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Camera([0, 0, 0], [0, 0, -1e-200])
    assert str(e.value) == ("camera.look_at: its distance to camera.position must be at least "
                            "1e-12 (the lengths at which a scene renders as it does at unit "
                            "size), got 1e-200")


@pytest.mark.parametrize("scale,vanished", [(1e13, "exceed ±1e+12"), (1e-13, "at least 1e-12")])
def test_a_mesh_scaled_where_embree_loses_it_is_refused(scale, vanished):
    """Measured: a unit-size mesh 1e13 across seen from 1e13 away vanishes in Embree's float32
    (L²·D overflows), and so does one whose edges are ~1e-19 (L² underflows)."""
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                      scale=scale)
    assert e.value.key == "scale"
    assert vanished in e.value.problem


@pytest.mark.parametrize("index,says", [(1e308, "index out of range 0..2"),
                                        (-1e308, "index out of range 0..2"),
                                        (math.inf, "must hold whole vertex indices"),
                                        (math.nan, "must hold whole vertex indices")])
def test_a_face_index_beyond_int64_is_refused_without_a_warning(index, says):
    """Cast to int64 first, 1e308 raised numpy's 'invalid value encountered in cast' (and inf
    an 'invalid value in remainder') before the error: two lines from the command."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(raytrace.SceneError) as e:
            raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[index, 1, 2]])
    assert str(e.value) == f"faces: {says}"


def test_a_mesh_shrunk_in_place_below_the_smallest_length_is_refused_at_render():
    scene = raytrace.Scene(objects=[raytrace.Mesh(vertices=[[0, 0, -3], [1, 0, -3], [0, 1, -3]],
                                                  faces=[[0, 1, 2]])])
    scene.objects[0].vertices *= 1e-20
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.render(scene, width=4, height=3)
    assert str(e.value) == ("objects[0].vertices: the mesh's size (its bounding box's longest "
                            "side) must be at least 1e-12 (the lengths at which a scene renders "
                            "as it does at unit size), got 1e-20")


def test_a_mesh_file_face_out_of_range_is_one_line(tmp_path):
    """An ASCII PLY (read by trimesh) whose face names vertex 9 of 3: one line naming the file,
    the face and the index, not trimesh's IndexError while it merges vertices."""
    path = tmp_path / "m.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                    "property float y\nproperty float z\nelement face 2\n"
                    "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                    "3 0 1 2\n3 0 1 9\n")
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=str(path))
    assert str(e.value) == f"file: {path}: face 1 names vertex 9, out of range 0..2"


def test_file_normals_transform_by_the_inverse_transpose(tmp_path):
    # scale (2, 1, 1), then rotate 90° about z: a file normal (1, 0, 1)/√2 becomes
    # R·S⁻¹·n ∝ Rz90·(1/2, 0, 1) = (0, 1/2, 1), unit (0, 1, 2)/√5 (worked by hand), which is
    # perpendicular to the transformed surface. A mirroring scale reverses each face's
    # corners, normals with them; a non-finite normal is one line naming the file.
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 -1\nv 0 1 0\nvn 0.7071067811865476 0 0.7071067811865476\n"
                    "vn 0 0 1\nf 1//1 2//2 3//2\n")
    mesh = raytrace.Mesh(file=path, scale=[2, 1, 1], rotate=[0, 0, 90])
    np.testing.assert_allclose(mesh.normals[0, 0], np.array([0, 1, 2]) / np.sqrt(5),
                               atol=1e-15)
    np.testing.assert_allclose(mesh.normals[0, 1:], [[0, 0, 1]] * 2, atol=1e-15)
    mirrored = raytrace.Mesh(file=path, scale=[-1, 1, 1])
    np.testing.assert_allclose(mirrored.normals[0], [[0, 0, 1], [0, 0, 1],
                                                     [-0.5 ** 0.5, 0, 0.5 ** 0.5]], atol=1e-15)
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 1\nf 1//1 2//1 3//1\n")
    with pytest.raises(raytrace.SceneError, match="normal of face 1, corner 1 is not finite"):
        raytrace.Mesh(file=path)


@pytest.mark.parametrize("name", ["m.obj", "m.off", "m.stl"])
def test_binary_bytes_in_a_text_mesh_format_are_one_line_naming_the_byte(tmp_path, name):
    """Random bytes in a text format (an OBJ, an OFF, an STL whose size is not a binary STL's
    84 + 50·n) are refused by raytrace's own text check, naming the first byte that is no
    text (here 0x00 on line 1), where trimesh reached for its optional charset_normalizer
    ('No module named ...' where it is not installed)."""
    path = tmp_path / name
    path.write_bytes(bytes(range(256)) * 8)  # 2048 bytes: no 84 + 50·n
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Mesh(file=str(path))
    assert str(e.value).startswith(f"file: cannot read mesh {path}: byte 0x00 on line 1 is "
                                   "not text")
    assert "charset_normalizer" not in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("name,text", [
    # a quad (trimesh's reading: read_mesh leaves polygons to it) with a Latin-1 comment
    ("q.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n# caf\xe9\nf 1 2 3 4\n"),
    ("q.off", b"OFF\n# caf\xe9\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"),
    ("q.stl", b"solid caf\xe9\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
              b"vertex 1 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
              b"vertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n"),
])
def test_a_text_mesh_with_latin1_bytes_is_read_without_guessing_its_encoding(
        tmp_path, name, text):
    """A byte that is not UTF-8 (é in Latin-1) in a comment or a name reads as U+FFFD, as
    the OBJ + MTL reader reads it: the unit square's two triangles, four vertices after the
    merge, with no encoding guessed (charset_normalizer, which raytrace does not need)."""
    path = tmp_path / name
    path.write_bytes(text)
    mesh = raytrace.Mesh(file=str(path))
    assert len(mesh.faces) == 2
    assert sorted(map(tuple, mesh.vertices.tolist())) == [(0, 0, 0), (0, 1, 0), (1, 0, 0),
                                                          (1, 1, 0)]
