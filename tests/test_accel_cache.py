"""A scene rendered again keeps its acceleration structure (raytrace/accel_cache.py): reused
for the same geometry and eye, rebuilt when either changes, and never a different picture from
a fresh build."""

from __future__ import annotations

import numpy as np
from helpers import make_scene

import raytrace
from raytrace import accel_cache


def _scene() -> raytrace.Scene:
    """A tetrahedron (Embree) over a floor (analytic) under one point light."""
    verts = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 1.5, 0.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
    return make_scene([raytrace.Mesh(vertices=verts, faces=faces, material="brass"),
                       raytrace.Plane([0, 0, 0], [0, 1, 0], material="white_plastic")],
                      lights=[raytrace.PointLight([3, 5, 4])],
                      camera=raytrace.Camera(position=[0, 1.5, 5], look_at=[0, 0.5, 0]),
                      ambient=0.1, width=24, height=18)


def _builds_during(fn) -> int:
    before = accel_cache.builds
    fn()
    return accel_cache.builds - before


def test_the_same_geometry_is_built_once_and_gives_the_same_pixels():
    scene = _scene()
    renders = []
    assert _builds_during(lambda: renders.append(raytrace.render(scene, threads=1))) == 1
    first = renders[0]
    again = []
    assert _builds_during(lambda: again.append(raytrace.render(scene, threads=2))) == 0
    assert np.array_equal(again[0].rgb, first.rgb)
    # Other settings, a turned camera (same eye), another material colour: still no build.
    assert _builds_during(lambda: raytrace.render(scene, spp=4, max_depth=1)) == 0
    scene.camera = raytrace.Camera(position=[0, 1.5, 5], look_at=[0.5, 0, 0], fov=30)
    turned = []
    assert _builds_during(lambda: turned.append(raytrace.render(scene))) == 0
    assert np.array_equal(turned[0].rgb, raytrace.render(
        make_scene(scene.objects, scene.lights, scene.camera, 0.1, width=24, height=18)).rgb)


def test_vertices_edited_in_place_are_rebuilt_as_a_fresh_scene_would_be():
    scene = _scene()
    before = raytrace.render(scene).rgb
    scene.objects[0].vertices[3, 1] = 0.8  # the apex lowered, in place: no setter sees it
    after = []
    assert _builds_during(lambda: after.append(raytrace.render(scene).rgb)) == 1
    assert not np.array_equal(after[0], before)
    fresh = _scene()
    fresh.objects[0].vertices[3, 1] = 0.8
    assert np.array_equal(after[0], raytrace.render(fresh).rgb)


def test_a_new_object_list_or_a_moved_eye_is_rebuilt():
    scene = _scene()
    raytrace.render(scene)
    scene.objects = scene.objects[:1]  # the floor removed
    assert _builds_during(lambda: raytrace.render(scene)) == 1
    scene.objects.append(raytrace.Sphere([1.5, 0.5, 0], 0.5, scene.objects[0].material))
    assert _builds_during(lambda: raytrace.render(scene)) == 1
    scene.camera = raytrace.Camera(position=[0, 1.5, 6], look_at=[0, 0.5, 0])
    assert _builds_during(lambda: raytrace.render(scene)) == 1


def test_the_fingerprint_sees_each_input_of_the_build():
    scene = _scene()
    materials = [scene.objects[0].material, scene.objects[1].material]
    key = accel_cache.fingerprint(scene, materials)
    assert accel_cache.fingerprint(scene, materials) == key
    assert accel_cache.fingerprint(scene, materials[::-1]) != key  # material indices
    scene.objects[0].shading = "smooth"
    assert accel_cache.fingerprint(scene, materials) != key
    scene.objects[0].shading = "flat"
    scene.objects[1].point = np.array([0.0, -0.5, 0.0])
    assert accel_cache.fingerprint(scene, materials) != key


def test_clear_makes_the_next_render_build():
    scene = _scene()
    raytrace.render(scene)
    accel_cache.clear()
    assert _builds_during(lambda: raytrace.render(scene)) == 1


def test_a_collected_scene_leaves_the_cache():
    import gc

    scene = _scene()
    raytrace.render(scene)
    key = id(scene)
    assert key in accel_cache._cache
    del scene
    gc.collect()
    assert key not in accel_cache._cache


def test_a_material_changed_between_renders_is_seen_without_a_build():
    # The kept accelerator brings its triangle tables; the colours come from this render's
    # material table, so the picture is a fresh scene's with the new material.
    scene = _scene()
    raytrace.render(scene)
    mesh = scene.objects[0]
    red = raytrace.Material(kd=[0.9, 0.05, 0.05], ks=0.3, shininess=20.0)
    mesh.material = red
    fresh = _scene()
    fresh.objects[0].material = red
    again = []
    assert _builds_during(lambda: again.append(raytrace.render(scene).rgb)) == 0
    expected = raytrace.render(fresh).rgb
    assert np.array_equal(again[0], expected)
    assert again[0][9, 12, 0] > 2 * again[0][9, 12, 1]  # the tetrahedron turned red


def test_a_model_file_mesh_given_a_material_of_its_own_renders_as_a_fresh_scene():
    # A mesh read with its MTL uses its file's materials; one assigned afterwards is not among
    # them: the fingerprint hashes the materials the mesh's faces use, as the stage tables them.
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scenes" / "obj_mtl.toml"
    scene = raytrace.load_scene(path)
    first = raytrace.render(scene, width=16, height=12).rgb
    mesh = next(o for o in scene.objects if isinstance(o, raytrace.Mesh) and o.file_materials)
    mesh.material = raytrace.Material(kd=0.9)
    again = raytrace.render(scene, width=16, height=12).rgb
    assert np.array_equal(again, first)  # the file's materials still colour the faces
