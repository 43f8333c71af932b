"""The scene → arrays stage (raytrace/tables.py): the analytic shapes numbered kind by kind
with their rows, the camera-relative triangle tables, the material columns declared once in
``material.COLUMNS``, and the accelerator and integrator both reading this stage."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import aimed_camera, make_scene, pixel, unit

import raytrace
from raytrace.accel import Accelerator
from raytrace.kernels import accel as ak
from raytrace.kernels import shading as sk
from raytrace.kernels.records import MATERIAL_COLUMNS, Materials
from raytrace.material import COLUMNS
from raytrace.rays import NO_SHAPE
from raytrace.tables import MaterialTable, scene_arrays

CAMERA = raytrace.Camera(position=[1.0, 2.0, 8.0], look_at=[0, 0, 0])


def mixed_scene() -> raytrace.Scene:
    """Objects listed plane, sphere, mesh, plane, sphere (scene order is not kind order)."""
    tri = raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                        translate=[3, 0, -2], material="brass")
    return make_scene([raytrace.Plane([0, -1, 0], [0, 1, 0], material="brass"),
                       raytrace.Sphere([0, 0, -5], 2.0),
                       tri,
                       raytrace.Plane([0, 0, -30], [0, 0, 1]),
                       raytrace.Sphere([-4, 1, -6], 0.5, material="brass")], camera=CAMERA)


def test_shapes_are_numbered_kind_by_kind_in_scene_order():
    arrays = scene_arrays(mixed_scene())
    shapes = arrays.shapes
    np.testing.assert_array_equal(shapes.kind, [ak.SPHERE, ak.SPHERE, ak.PLANE, ak.PLANE])
    np.testing.assert_array_equal(shapes.object, [1, 4, 0, 3])
    np.testing.assert_array_equal(arrays.geom_object, [2])
    # rows: camera-relative parameters, zero-padded to ROW floats (worked out by hand)
    assert shapes.rows.shape == (4, ak.ROW)
    np.testing.assert_array_equal(shapes.rows[0], [-1, -2, -13, 2, 13, 0, 0, 0])
    np.testing.assert_array_equal(shapes.rows[1], [-5, -1, -14, 0.5, 14, 0, 0, 0])
    np.testing.assert_array_equal(shapes.rows[2], [-1, -3, -8, 0, 1, 0, 8, 0])
    np.testing.assert_array_equal(shapes.rows[3], [-1, -2, -38, 0, 0, 1, 38, 0])
    # materials: brass on objects 0, 2 and 4, the default on 1 and 3
    names = [arrays.materials[i].name for i in shapes.material]
    assert names == ["default", "brass", "brass", "default"]


def test_the_accelerator_reports_the_stages_numbering():
    # A ray straight down from the camera meets the plane listed first in the scene: shape 2
    # in kind order, whose object is 0.
    arrays = scene_arrays(mixed_scene())
    acc = Accelerator(arrays)
    hits = acc.intersect(np.zeros((2, 3)), np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
                         np.full(2, NO_SHAPE))
    assert hits.shape[0] == 2 and arrays.shapes.object[hits.shape[0]] == 0
    assert hits.t[0] == pytest.approx(3.0)  # camera at y = 2, plane at y = −1
    s = acc.surface(hits, np.zeros((2, 3)), np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(s.geometric[0], [0, 1, 0])


def test_triangle_tables_are_camera_relative_float64():
    arrays = scene_arrays(mixed_scene())
    t = arrays.triangles
    world = np.array([[3, 0, -2], [4, 0, -2], [3, 1, -2]], float)
    np.testing.assert_array_equal(t.corners[0], world - CAMERA.position)
    np.testing.assert_array_equal(t.normal[0], [0, 0, 1])
    np.testing.assert_array_equal(t.geom_first, [0])
    assert arrays.materials[t.material[0]].name == "brass"
    assert t.texcoords.shape == (0, 3, 2)  # no material has a texture
    v, faces = arrays.meshes[0]
    np.testing.assert_array_equal(v, world - CAMERA.position)
    assert arrays.n_triangles == 1


def test_material_columns_come_from_one_declaration():
    table = MaterialTable([raytrace.Material(highlight="blinn", shininess=7.0, kr=0.5),
                           raytrace.Material(kd=0.0, ks=0.0, ior=1.33, opacity=0.25)])
    rec = table.record
    assert list(COLUMNS) == list(MATERIAL_COLUMNS) and set(COLUMNS) <= set(Materials._fields)
    for name, (dtype, _) in MATERIAL_COLUMNS.items():
        assert getattr(rec, name).dtype == dtype and getattr(rec, name).shape == (2,)
    np.testing.assert_array_equal(rec.highlight, [sk.BLINN, sk.PHONG])
    np.testing.assert_array_equal(rec.shininess, [7.0, 32.0])
    np.testing.assert_array_equal(rec.ior, [1.5, 1.33])
    np.testing.assert_array_equal(rec.opacity, [1.0, 0.25])
    np.testing.assert_array_equal(rec.lit, [True, False])
    np.testing.assert_array_equal(rec.reflects, [True, False])


def test_the_integrator_reads_the_stage_not_the_accelerator():
    # The integrator's scene record is the stage's, and of the accelerator it uses only the
    # queries (intersect, occluded, surface) and the Embree scene the compiled loop's queries
    # traverse, never its tables.
    from raytrace import integrator

    src = Path(integrator.__file__).read_text("utf-8")
    assert set(re.findall(r"\baccel\.(\w+)", src)) <= {"intersect", "occluded", "surface",
                                                       "embree"}
    integ = integrator.WhittedIntegrator(mixed_scene(), integrator.RenderOptions(
        width=8, height=6))
    assert integ.tables is integ.arrays.record
    assert integ.tables.triangles is integ.accel.triangles is integ.arrays.triangles


def test_every_shape_type_has_a_kernel_kind():
    # A shape's two registrations agree: its record in scene.SHAPE_TYPES (scene-file type,
    # keys, row) and its kind code in accel_kernels.SHAPE_KINDS (the dispatchers' cases),
    # each code once, so a record without kernels fails here and not at its first render.
    from raytrace.scene import SHAPE_TYPES

    assert set(SHAPE_TYPES) == set(ak.SHAPE_KINDS)
    assert sorted(ak.SHAPE_KINDS.values()) == list(range(len(ak.SHAPE_KINDS)))
    assert all(cls.type == name for name, cls in SHAPE_TYPES.items())


# -- the normals a mesh is shaded with (tables.shading_of) -------------------------------------
#: A directional light from the upper left front, ambient 0.1, a matte-plus-Blinn material:
#: a pixel is ka·Ia + I·[kd·max(N·L, 0) + ks·max(N·H, 0)ⁿ] (docs/shading.md), N·L > 0.
LIGHT = unit([-0.4, 0.9, 0.7])
KD, KS, SHININESS, IA = 0.6, 0.3, 20.0, 0.1


def lit(normal, view) -> float:
    """The hand-worked pixel of a unit shading ``normal`` seen along ``view`` (towards the
    eye), float64: ka·Ia + kd·N·L + ks·(N·H)ⁿ, ka = kd, I = 1, H = (L + V)/|L + V|."""
    n, v = unit(normal), unit(view)
    h = unit(LIGHT + v)
    return KD * IA + KD * max(n @ LIGHT, 0.0) + KS * max(n @ h, 0.0) ** SHININESS


def look_at(mesh: raytrace.Mesh, target, eye) -> float:
    """The one pixel of ``mesh`` seen from ``eye`` through ``target`` (red channel)."""
    scene = make_scene([mesh], [raytrace.DirectionalLight(-LIGHT, 1.0)],
                       camera=aimed_camera(eye, target), ambient=IA)
    return float(pixel(scene)[0])


def shaded(path, **kw) -> raytrace.Mesh:
    material = raytrace.Material(kd=KD, ks=KS, shininess=SHININESS, highlight="blinn")
    return raytrace.Mesh(file=path, material=material, **kw)


def cube_obj(path: Path) -> Path:
    """The cube |x|, |y|, |z| ≤ 1 as 12 triangles over 8 shared positions whose corners name
    24 ``vn``, each face's own normal at its 4 corners (Wings 3D and Blender write hard edges
    so)."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    lines = [f"v {x:g} {y:g} {z:g}" for x, y, z in corners]
    faces, k = [], 0
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            quad = [i for i, c in enumerate(corners) if c[axis] == sign]
            # counter-clockwise seen from outside: sort the quad's corners by angle about n
            u = np.roll(n, 1)
            w = np.cross(n, u)
            quad.sort(key=lambda i: np.arctan2((corners[i] - n) @ w, (corners[i] - n) @ u))
            lines += [f"vn {n[0]:g} {n[1]:g} {n[2]:g}"] * 4
            c = [f"{q + 1}//{k + j + 1}" for j, q in enumerate(quad)]
            faces += [f"f {c[0]} {c[1]} {c[2]}", f"f {c[0]} {c[2]} {c[3]}"]
            k += 4
    path.write_text("\n".join(lines + faces) + "\n")
    return path


def test_a_cube_with_24_file_normals_stays_hard_edged(tmp_path):
    # A point 0.02 from an edge, on each of the three faces the eye sees, shades with its own
    # face's normal (the flat value, worked by hand from that normal), as in the face's middle:
    # the 24 vn are kept per corner through the merge of the 8 positions. shading = "smooth"
    # (vertex normals averaged over the merged positions, as before) rounds the edge instead.
    mesh = shaded(cube_obj(tmp_path / "cube.obj"))
    assert mesh.shading == "file" and len(mesh.vertices) == 8 and mesh.normals.shape == (12, 3, 3)
    eye = np.array([4.0, 5.0, 6.0])
    for n, points in (([1, 0, 0], ([1, 0.98, 0.3], [1, 0.2, 0.98], [1, 0.0, 0.0])),
                      ([0, 1, 0], ([0.98, 1, -0.5], [0.3, 1, 0.98], [0.0, 1, 0.0])),
                      ([0, 0, 1], ([0.98, 0.1, 1], [-0.4, 0.98, 1], [0.0, 0.0, 1]))):
        for p in points:
            p = np.array(p)
            want = lit(n, eye - p)
            assert look_at(mesh, p, eye) == pytest.approx(want, rel=1e-5), (n, p)
    p = np.array([1, 0.98, 0.3])
    rounded = look_at(shaded(tmp_path / "cube.obj", shading="smooth"), p, eye)
    assert abs(rounded - lit([1, 0, 0], eye - p)) > 0.05


def sphere_obj(path: Path, with_normals: bool = True) -> tuple[Path, trimesh.Trimesh]:
    """An 80-face icosphere of radius 1 whose ``vn`` are the sphere's exact normals (the unit
    positions), as a modeller exports a smooth sphere."""
    ico = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    v, f = np.asarray(ico.vertices), np.asarray(ico.faces)
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in v.tolist()]
    if with_normals:
        n = v / np.linalg.norm(v, axis=1, keepdims=True)
        lines += [f"vn {x!r} {y!r} {z!r}" for x, y, z in n.tolist()]
        lines += ["f " + " ".join(f"{i}//{i}" for i in face) for face in (f + 1).tolist()]
    else:
        lines += ["f " + " ".join(str(i) for i in face) for face in (f + 1).tolist()]
    path.write_text("\n".join(lines) + "\n")
    return path, ico


@pytest.mark.parametrize("bary", [(0.2, 0.3, 0.5), (0.6, 0.25, 0.15), (0.05, 0.05, 0.9)])
def test_a_sphere_with_file_normals_matches_the_hand_interpolation(tmp_path, bary):
    # At the point with barycentrics b of a triangle that faces the eye and the light, the
    # shading normal is N = Σ b_k·n_k / |Σ b_k·n_k|, n_k the file's normals at its corners
    # (Phong 1975), worked here in float64 from the file's numbers, not by the renderer.
    path, ico = sphere_obj(tmp_path / "sphere.obj")
    mesh = shaded(path)
    v = np.asarray(ico.vertices)
    centres = v[ico.faces].mean(axis=1)
    tri = int(np.argmax(centres @ unit([-0.1, 0.4, 1.0])))  # a face towards eye and light
    corners = v[ico.faces[tri]]
    p = np.asarray(bary) @ corners
    normal = np.asarray(bary) @ (corners / np.linalg.norm(corners, axis=1, keepdims=True))
    eye = p + 3.0 * unit(p + [0.1, 0.2, 0.3])
    want = lit(normal, eye - p)
    assert look_at(mesh, p, eye) == pytest.approx(want, rel=1e-5)
    # without vn the same file is flat: the face normal's value
    flat_path, _ = sphere_obj(tmp_path / "flat.obj", with_normals=False)
    face = unit(np.cross(corners[1] - corners[0], corners[2] - corners[0]))
    assert shaded(flat_path).shading == "flat"
    assert look_at(shaded(flat_path), p, eye) == pytest.approx(lit(face, eye - p), rel=1e-5)
    assert abs(want - lit(face, eye - p)) > 1e-3  # the two differ: the test can tell them


def test_shading_overrides_the_file_normals(tmp_path):
    # shading = "flat" shades the face normal although the file gives normals.
    path, ico = sphere_obj(tmp_path / "sphere.obj")
    v = np.asarray(ico.vertices)
    tri = int(np.argmax(v[ico.faces].mean(axis=1) @ unit([-0.1, 0.4, 1.0])))
    corners = v[ico.faces[tri]]
    p = np.array([0.2, 0.3, 0.5]) @ corners
    eye = p + 3.0 * unit(p)
    face = unit(np.cross(corners[1] - corners[0], corners[2] - corners[0]))
    assert look_at(shaded(path, shading="flat"), p, eye) == pytest.approx(
        lit(face, eye - p), rel=1e-5)


def test_file_shading_needs_normals_from_the_file():
    with pytest.raises(raytrace.SceneError, match="shading.*gives normals"):
        raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                      shading="file")


def test_file_normals_below_the_surface_are_turned_over(tmp_path):
    # The stiff case: one triangle in z = 0 wound counter-clockwise (N_g = +z) whose file
    # normals n = (0.05, 0, −1)/|…| point nearly opposite N_g, seen at grazing incidence
    # (V·N_g ≈ 0.03). The rule (docs/shading.md, "Shading normals below the surface"): the
    # corner normals are turned over, N = −n = (−0.05, 0, 1)/|…|. Worked by hand, kd = ka =
    # 0.6, Ia = 0.1, one directional light of 1, no highlight:
    # * a light in front (towards it L = (0.3, −0.2, 1)/|…|): 0.06 + 0.6·(N·L), N·L ≈ 0.94;
    #   taken as given, n·L < 0 and the pixel was ambient only (a black hole);
    # * a light behind (L = (0.3, −0.2, −1)/|…|): N·L < 0, ambient only, 0.06; taken as given,
    #   n·L > 0 and the open triangle was lit from behind (a light leak).
    # Every pixel of a small grazing render is finite.
    path = tmp_path / "below.obj"
    path.write_text("v -50 -50 0\nv 50 -50 0\nv 0 50 0\nvn 0.05 0 -1\nf 1//1 2//1 3//1\n")
    mesh = raytrace.Mesh(file=path, material=raytrace.Material(kd=0.6))
    camera = aimed_camera([0.0, -10.0, 0.3], [0.0, 0.0, 0.0])
    turned = unit([-0.05, 0.0, 1.0])
    for towards, want in (([0.3, -0.2, 1.0], 0.06 + 0.6 * (turned @ unit([0.3, -0.2, 1.0]))),
                          ([0.3, -0.2, -1.0], 0.06)):
        scene = make_scene([mesh], [raytrace.DirectionalLight(-unit(towards), 1.0)],
                           camera=camera, ambient=0.1)
        assert pixel(scene)[0] == pytest.approx(want, rel=1e-6), towards
        image = raytrace.render(scene, width=16, height=12)
        assert np.isfinite(image.rgb).all()
