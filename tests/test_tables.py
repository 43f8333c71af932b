"""The scene → arrays stage (raytrace/tables.py): the analytic shapes numbered kind by kind
with their rows, the camera-relative triangle tables, the material columns declared once in
``material.COLUMNS``, and the accelerator and integrator both reading this stage."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from helpers import make_scene

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
