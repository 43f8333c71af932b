"""The scene's dataclasses built in Python (raytrace/scene.py): a wrong argument is a clear
SceneError naming it when the Scene is made, never an AttributeError from deep inside a render;
mesh paths that are not files say what they are."""

from __future__ import annotations

import pytest

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
