"""glTF 2.0 scenes (raytrace/gltf.py): node transforms, the camera, KHR_lights_punctual
against the equivalent TOML lights, the material mapping and one-line errors."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import aimed_camera, make_scene, pixel, write_gltf, write_png

import raytrace
from raytrace.camera import camera_rays
from raytrace.errors import RenderWarning, SceneError

#: The square |x|, |y| ≤ 1 in z = 0, counter-clockwise from +z (normal +z).
SQUARE = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
          "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
          "material": 0}
MATTE = [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.4, 0.2, 1.0],
                                   "metallicFactor": 0.0, "roughnessFactor": 1.0}}]


def quaternion(axis, degrees):
    """Unit quaternion (x, y, z, w) of a rotation about ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    h = math.radians(degrees) / 2
    return [*(a * math.sin(h)), math.cos(h)]


def test_a_child_of_a_rotated_and_scaled_parent_lands_where_it_should(tmp_path):
    """Parent: translate (1, 0, 0) · rotate 90° about z · scale 2; child: translate (1, 0, 0).
    The child's local (0, 0, 0) → (1, 0, 0) → ×2 (2, 0, 0) → Rz90 (0, 2, 0) → (1, 2, 0);
    local (0.1, 0, 0) → (1, 2.2, 0); local (0, 0.1, 0) → (1.1 → ... ) = (0.8, 2, 0)."""
    tri = {"positions": [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], "indices": [[0, 1, 2]]}
    nodes = [{"translation": [1, 0, 0], "rotation": quaternion([0, 0, 1], 90),
              "scale": [2, 2, 2], "children": [1]},
             {"translation": [1, 0, 0], "mesh": 0, "_child": True}]
    path = write_gltf(tmp_path / "h.gltf", nodes, [tri])
    mesh = raytrace.Mesh(file=path, material="from_file")
    np.testing.assert_allclose(mesh.vertices, [[1, 2, 0], [1, 2.2, 0], [0.8, 2, 0]],
                               atol=1e-6)
    # the same through a column-major matrix on the parent
    m = np.array([[0, -2, 0, 1], [2, 0, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]], float)
    nodes = [{"matrix": m.T.reshape(-1).tolist(), "children": [1]},
             {"translation": [1, 0, 0], "mesh": 0, "_child": True}]
    path = write_gltf(tmp_path / "m.gltf", nodes, [tri])
    np.testing.assert_allclose(raytrace.Mesh(file=path, material="from_file").vertices,
                               [[1, 2, 0], [1, 2.2, 0], [0.8, 2, 0]], atol=1e-6)



def test_a_file_without_scenes_takes_the_nodes_that_are_no_nodes_child_as_roots(tmp_path):
    """No ``scenes``: the roots are the nodes no node names as a child, so the child is drawn
    once, under its parent's translation (0, 0, 1): its local (0, 0, 0) lands at (0, 0, 1).
    (Taking every node as a root met the child twice: "not a tree".)"""
    tri = {"positions": [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], "indices": [[0, 1, 2]]}
    path = write_gltf(tmp_path / "n.gltf", [{"translation": [0, 0, 1], "children": [1]},
                                            {"mesh": 0}], [tri])
    doc = json.loads(path.read_text())
    del doc["scene"], doc["scenes"]
    path.write_text(json.dumps(doc))
    np.testing.assert_allclose(raytrace.Mesh(file=path, material="from_file").vertices,
                               [[0, 0, 1], [0.1, 0, 1], [0, 0.1, 1]], atol=1e-6)

def test_the_gltf_camera_reproduces_a_known_pixel_ray(tmp_path):
    """A camera node at (1, 2, 5) turned 30° about y (its −z looks towards −x a little), yfov
    0.6 rad: pixel (row 1, col 6) of an 8×6 image goes along forward + x·right + y·up with
    x = (2·6.5/8 − 1)·tan(0.3)·8/6, y = (1 − 2·1.5/6)·tan(0.3), right = R x̂, up = R ŷ."""
    nodes = [{"translation": [1, 2, 5], "rotation": quaternion([0, 1, 0], 30), "camera": 0},
             {"mesh": 0}]
    path = write_gltf(tmp_path / "c.gltf", nodes, [SQUARE], MATTE, extra={"cameras": [
        {"type": "perspective", "perspective": {"yfov": 0.6, "znear": 0.1}}]})
    with pytest.warns(RenderWarning, match="no lights in the file"):
        scene = raytrace.load_scene(path)
    np.testing.assert_allclose(scene.camera.position, [1, 2, 5], atol=1e-12)
    frame = raytrace.RenderSettings(width=8, height=6)
    rays = camera_rays(scene.camera, frame, 0, 48).direction.reshape(6, 8, 3)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    right, up, forward = np.array([c, 0, -s]), np.array([0, 1.0, 0]), np.array([-s, 0, -c])
    t = math.tan(0.3)
    d = forward + (2 * 6.5 / 8 - 1) * t * 8 / 6 * right + (1 - 2 * 1.5 / 6) * t * up
    np.testing.assert_allclose(rays[1, 6], d / np.linalg.norm(d), atol=1e-12)


def _lit_square(tmp_path, light: dict, node: dict, name: str):
    """The square under one KHR light, seen from (0, 0, 3)."""
    node = {**node, "extensions": {"KHR_lights_punctual": {"light": 0}}}
    return write_gltf(tmp_path / f"{name}.gltf", [{"mesh": 0}, node], [SQUARE], MATTE, extra={
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [light]}}})


@pytest.mark.parametrize("kind", ["point", "spot", "directional"])
def test_each_khr_light_matches_the_equivalent_toml_light(tmp_path, kind):
    """The same square lit by the glTF light and by the TOML light docs/scene_format.md maps
    it to (colour × intensity; 1/d²; the spot's cutoff at the outer cone and its inner_cutoff
    at the inner one, the spec's falloff between them; range 2.2, which ends the light inside
    the square's corners, as range): the same pixels."""
    color, intensity = [1.0, 0.5, 0.25], 3.0
    down = {"translation": [0.2, 0.1, 1.5], "rotation": quaternion([1, 0, 0], -20)}
    light = {"type": kind, "color": color, "intensity": intensity}
    if kind == "spot":
        light["spot"] = {"innerConeAngle": 0.2, "outerConeAngle": 0.5}
    if kind != "directional":
        light["range"] = 2.2
    axis = [0, math.sin(math.radians(-20)), -math.cos(math.radians(20))]  # R(−20° x)·(−ẑ)
    toml = {"point": 'type = "point"\nposition = [0.2, 0.1, 1.5]\nattenuation = [0, 0, 1]\n'
                     'range = 2.2',
            "spot": f'type = "spot"\nposition = [0.2, 0.1, 1.5]\nattenuation = [0, 0, 1]\n'
                    f'direction = {axis}\ncutoff = {math.degrees(0.5)!r}\n'
                    f'inner_cutoff = {math.degrees(0.2)!r}\nrange = 2.2',
            "directional": f"type = \"directional\"\ndirection = {axis}"}[kind]
    path = _lit_square(tmp_path, light, down, kind)
    with pytest.warns(RenderWarning, match="no camera in the file"):  # the default framing
        gl = raytrace.load_scene(path)
    (tmp_path / "s.toml").write_text(
        f'[render]\nbackground = {gl.render.background.tolist()}\n[ambient]\ncolor = '
        f'{gl.ambient.tolist()}\n'
        f'[camera]\nposition = {gl.camera.position.tolist()}\nlook_at = '
        f'{gl.camera.look_at.tolist()}\n[[lights]]\n{toml}\ncolor = '
        f'{[c * intensity for c in color]}\n[[objects]]\ntype = "mesh"\nfile = "{kind}.gltf"\n'
        f'material = "from_file"\n')
    ref = raytrace.load_scene(tmp_path / "s.toml")
    a = raytrace.render(gl, width=24, height=18).rgb
    b = raytrace.render(ref, width=24, height=18).rgb
    assert a.max() > 0.05 and (a > 0).mean() > 0.1  # it is lit
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7)
    if kind != "directional":  # the window dims the square: without it, brighter
        assert gl.lights[0].range == 2.2
        gl.lights[0].range = None
        assert (raytrace.render(gl, width=24, height=18).rgb > a + 1e-3).any()


def test_metallic_roughness_maps_onto_kd_ks_shininess_kr(tmp_path):
    """baseColor (0.8, 0.4, 0.2), metallic 0, roughness 1: kd = baseColor, n = 2/1 − 2 = 0,
    ks = F0·(n + 8)/8 = 0.04, kr = 0, highlight ks·(N·H)^n·(N·L). Head-on under a unit light
    at the eye (N·H = N·L = 1): kd + ks."""
    path = write_gltf(tmp_path / "m.gltf", [{"mesh": 0}], [SQUARE], MATTE)
    mesh = raytrace.Mesh(file=path, material="from_file")
    cam = raytrace.Camera(position=(0, 0, 2), look_at=(0, 0, 0))
    got = pixel(make_scene([mesh], [raytrace.PointLight(position=(0, 0, 2))], cam))
    np.testing.assert_allclose(got, [0.84, 0.44, 0.24], rtol=1e-6)
    assert raytrace.Mesh(file=path, material="from_file").material.highlight == "blinn_cosine"
    gold = [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.8, 0.3, 1],
                                      "metallicFactor": 1.0, "roughnessFactor": 0.0},
             "emissiveFactor": [0.1, 0.0, 0.0]}]
    path = write_gltf(tmp_path / "g.gltf", [{"mesh": 0}], [SQUARE], gold)
    m = raytrace.Mesh(file=path, material="from_file").material
    np.testing.assert_allclose(m.kd, 0.0)
    np.testing.assert_allclose(m.kr, [1.0, 0.8, 0.3])  # a polished metal: a tinted mirror
    np.testing.assert_allclose(m.ke, [0.1, 0, 0])
    assert m.shininess == 10_000.0


def test_a_khr_spot_light_with_a_range_renders_the_hand_value(tmp_path):
    """A spot (KHR_lights_punctual) at (0, 0, 1.5) shining down its node's −z onto the square
    (normal +z), inner cone 0.2 rad, outer 0.5 rad, range 4, intensity 3 cd, colour
    (1, 0.5, 0.25); a matte material with no highlight (specularFactor 0: ks = 0). The pixel
    aims at P = (1.5·tan 0.35, 0, 0): α = 0.35 rad off the axis, d = 1.5/cos 0.35 = 1.596810,
    N·L = cos 0.35 = 0.9393727. The spec's recommended falloff: t = (cos 0.35 − cos 0.5)/
    (cos 0.2 − cos 0.5) = (0.9393727 − 0.8775826)/(0.9800666 − 0.8775826) = 0.602925,
    t² = 0.363518; its range window 1 − (d/4)⁴ = 1 − 0.399203⁴ = 0.974604; 1/d² = 0.392187.
    Pixel = kd·I·t²·window·N·L/d² = kd·I·0.1305225, I = 3·colour (candela at the 1/d²
    law)."""
    light = {"type": "spot", "color": [1.0, 0.5, 0.25], "intensity": 3.0, "range": 4.0,
             "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}
    plain = [{"pbrMetallicRoughness": MATTE[0]["pbrMetallicRoughness"],
              "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}]
    path = write_gltf(tmp_path / "spot.gltf", [{"mesh": 0}, {
        "translation": [0.0, 0.0, 1.5], "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        [SQUARE], plain, extra={"extensionsUsed": ["KHR_lights_punctual",
                                                   "KHR_materials_specular"],
                                "extensions": {"KHR_lights_punctual": {"lights": [light]}}})
    with pytest.warns(RenderWarning, match="no camera in the file"):
        gl = raytrace.load_scene(path)
    (spot,) = gl.lights
    assert (spot.cutoff, spot.inner_cutoff, spot.range) == pytest.approx(
        (math.degrees(0.5), math.degrees(0.2), 4.0))
    x = 1.5 * math.tan(0.35)
    got = pixel(make_scene(gl.objects, gl.lights, aimed_camera([x, -1.0, 3.0], [x, 0.0, 0.0])))
    kd_i = np.array([0.8, 0.4, 0.2]) * 3.0 * np.array([1.0, 0.5, 0.25])
    np.testing.assert_allclose(got, kd_i * 0.1305225, rtol=2e-6)



def test_an_unlit_textured_material_shows_its_texture_unlit(tmp_path):
    """KHR_materials_unlit with a baseColorTexture: the colour seen is texture × factor, with
    no light's share (the extension: "the base color ... as the final color"). Texel code 128
    everywhere, sRGB-decoded ((128/255 + 0.055)/1.055)^2.4 = 0.2158605; factor
    (1, 0.5, 0.25): the pixel is 0.2158605·(1, 0.5, 0.25), whatever the point light at the
    eye adds to a lit surface (it added the texture's kd·N·L before)."""
    write_png(tmp_path / "grey.png", np.full((2, 2, 3), 128, np.uint8))
    unlit = [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.5, 0.25, 1.0],
                                       "baseColorTexture": {"index": 0}},
              "extensions": {"KHR_materials_unlit": {}}}]
    path = write_gltf(tmp_path / "u.gltf", [{"mesh": 0}], [SQUARE], unlit, extra={
        "images": [{"uri": "grey.png"}], "textures": [{"source": 0}],
        "extensionsUsed": ["KHR_materials_unlit"]})
    scene = make_scene([raytrace.Mesh(file=path, material="from_file")],
                       [raytrace.PointLight(position=[0, 0, 3], color=[1, 1, 1])],
                       camera=aimed_camera([0, 0, 3], [0.1, 0.2, 0]), max_depth=0)
    np.testing.assert_allclose(pixel(scene), 0.2158605 * np.array([1, 0.5, 0.25]),
                               rtol=1e-5)

@pytest.mark.parametrize("change,key,problem", [
    ({"spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.5}}, "spot.innerConeAngle",
     "must be <= 0.5"),
    ({"spot": {"outerConeAngle": 2.0}}, "spot.outerConeAngle", "must be <= 1.5708"),
    ({"range": 0}, "range", "must be > 0"),
])
def test_a_bad_khr_spot_or_range_is_one_line_naming_the_field(tmp_path, change, key, problem):
    light = {"type": "spot", **change}
    path = _lit_square(tmp_path, light, {"translation": [0, 0, 1]}, "bad")
    with pytest.raises(SceneError) as e:
        raytrace.load_scene(path)
    assert str(e.value).startswith(f"{path}: KHR_lights_punctual.lights[0].{key}: {problem}")


def test_transmission_and_ior_make_fresnel_glass(tmp_path):
    glass = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0,
                                       "roughnessFactor": 0},
              "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                             "KHR_materials_ior": {"ior": 1.5}}}]
    path = write_gltf(tmp_path / "g.gltf", [{"mesh": 0}], [SQUARE], glass)
    mesh = raytrace.Mesh(file=path, material="from_file")
    assert mesh.material.fresnel == "dielectric" and mesh.material.ior == 1.5
    cam = raytrace.Camera(position=(0, 0, 2), look_at=(0, 0, 0))
    got = pixel(make_scene([mesh], [], cam, background=1.0))
    np.testing.assert_allclose(got, 1.0, rtol=1e-6)  # F + (1 − F)·1 head on, no absorption


def _glass(volume: dict | None = None, transmission: float = 1.0) -> list[dict]:
    ext: dict = {"KHR_materials_ior": {"ior": 1.5}}
    if transmission:
        ext["KHR_materials_transmission"] = {"transmissionFactor": transmission}
    if volume is not None:
        ext["KHR_materials_volume"] = volume
    return [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0,
                                      "roughnessFactor": 0}, "extensions": ext}]


@pytest.mark.parametrize(("volume", "thin", "color", "distance"), [
    (None, True, [1, 1, 1], math.inf),                     # transmission alone: a thin wall
    ({"thicknessFactor": 0.0, "attenuationColor": [0.5, 0.5, 0.5],
      "attenuationDistance": 1.0}, True, [1, 1, 1], math.inf),  # thickness 0: thin, clear
    ({"thicknessFactor": 0.3}, False, [1, 1, 1], math.inf),     # a clear closed volume
    ({"thicknessFactor": 0.3, "attenuationColor": [0.5, 0.8, 0.0],
      "attenuationDistance": 0.25}, False, [0.5, 0.8, 2.2250738585072014e-308], 0.25),
])
def test_transmission_with_and_without_volume(tmp_path, volume, thin, color, distance):
    """KHR_materials_transmission without KHR_materials_volume (or with thicknessFactor 0) is
    thin-walled; with a thickness it is a volume with the file's attenuationColor and
    attenuationDistance (defaults white and +∞); a channel of 0 is the smallest normal
    float64, 2⁻¹⁰²², so that σ = −ln(c)/D stays finite (708.4/D)."""
    path = write_gltf(tmp_path / "v.gltf", [{"mesh": 0}], [SQUARE], _glass(volume))
    m = raytrace.Mesh(file=path, material="from_file").material
    assert m.thin_walled is thin
    assert m.attenuation_color.tolist() == color and m.attenuation_distance == distance
    if distance < math.inf:
        np.testing.assert_allclose(m.sigma, [math.log(2) / 0.25, -math.log(0.8) / 0.25,
                                             1022 * math.log(2) / 0.25], rtol=1e-15)


def test_a_volume_without_transmission_changes_nothing(tmp_path):
    """KHR_materials_volume only acts through transmission (its spec): an opaque material
    keeps no interior."""
    path = write_gltf(tmp_path / "o.gltf", [{"mesh": 0}], [SQUARE], _glass(
        {"thicknessFactor": 1.0, "attenuationColor": [0.5, 0.5, 0.5],
         "attenuationDistance": 1.0}, transmission=0.0))
    m = raytrace.Mesh(file=path, material="from_file").material
    assert not m.thin_walled and not m.absorbs and not m.transmits


@pytest.mark.parametrize(("volume", "key", "problem"), [
    ({"thicknessFactor": 1.0, "attenuationDistance": 0}, "attenuationDistance", "must be > 0"),
    ({"thicknessFactor": -1.0}, "thicknessFactor", "must be >= 0"),
    ({"thicknessFactor": 1.0, "attenuationColor": [0.5, 2.0, 0.5]}, "attenuationColor[1]",
     "must be <= 1"),
    ({"thicknessFactor": 1.0, "attenuationColor": [0.5]}, "attenuationColor",
     "must be a list of three numbers"),
])
def test_a_bad_volume_is_one_line_naming_file_and_field(tmp_path, volume, key, problem):
    path = write_gltf(tmp_path / "bad.gltf", [{"mesh": 0}], [SQUARE], _glass(volume))
    with pytest.raises(SceneError) as e:
        raytrace.Mesh(file=path, material="from_file")
    assert str(e.value).startswith(
        f"{path}: materials[0].extensions.KHR_materials_volume.{key}: {problem}")
    assert "\n" not in str(e.value)


def test_unsupported_extensions_are_one_warning_and_required_ones_an_error(tmp_path):
    extra = {"extensionsUsed": ["KHR_materials_clearcoat", "KHR_materials_sheen",
                                "KHR_materials_ior"]}
    path = write_gltf(tmp_path / "w.gltf", [{"mesh": 0}], [SQUARE], MATTE, extra=extra)
    with pytest.warns(RenderWarning, match=r"w.gltf: extensions .*: KHR_materials_clearcoat, "
                                           r"KHR_materials_sheen$"):
        raytrace.Mesh(file=path, material="from_file")
    path = write_gltf(tmp_path / "r.gltf", [{"mesh": 0}], [SQUARE], MATTE, extra={
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"]})
    with pytest.raises(SceneError, match="r.gltf: extensionsRequired: .*draco"):
        raytrace.load_scene(path)


def test_bad_gltf_input_is_one_line_naming_file_and_field(tmp_path):
    path = write_gltf(tmp_path / "b.gltf", [{"mesh": 0}], [SQUARE], MATTE)
    doc = json.loads(path.read_text())
    doc["buffers"][0]["uri"] = "missing.bin"
    path.write_text(json.dumps(doc))
    r = subprocess.run([sys.executable, "-m", "raytrace", "render", str(path), "-o",
                        str(tmp_path / "o.exr")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "b.gltf: buffers[0].uri: buffer file not found" in r.stderr
    doc = json.loads(write_gltf(tmp_path / "c.gltf", [{"mesh": 0}], [SQUARE],
                                MATTE).read_text())
    doc["accessors"][1]["count"] = 99  # indices past their buffer view
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"b.gltf: accessors\[1\]: reaches past the end"):
        raytrace.load_scene(path)
    doc["accessors"][1]["count"] = 4
    doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = [2, 0, 0, 1]
    doc["materials"][0]["pbrMetallicRoughness"]["metallicFactor"] = 1.0
    doc["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = 0.0
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"b.gltf: materials\[0\]\.pbrMetallicRoughness\."
                                         r"baseColorFactor\[0\]: must be <= 1"):
        raytrace.load_scene(path)
    with pytest.raises(SceneError, match="nope.glb: model file not found"):
        raytrace.load_scene(tmp_path / "nope.glb")


def test_render_a_gltf_with_no_camera_or_light_reports_the_defaults(tmp_path):
    path = write_gltf(tmp_path / "a.gltf", [{"mesh": 0}], [SQUARE], MATTE)
    out = tmp_path / "a.exr"
    r = subprocess.run([sys.executable, "-m", "raytrace", "render", str(path), "-o", str(out),
                        "--width", "16", "--height", "12", "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "no camera in the file: camera at" in r.stderr
    assert "no lights in the file: a directional light" in r.stderr
    assert out.is_file()
    with pytest.warns(RenderWarning):
        scene = raytrace.load_scene(path)
    image = raytrace.render(scene, width=16, height=12)
    assert image.rgb[6, 8].min() > 0  # the square fills the middle of the frame


def test_import_raytrace_and_a_toml_render_do_not_import_the_asset_libraries(tmp_path):
    # The readers' modules stand at the head of scene.py (docs/architecture.md); the libraries
    # they read model files and images with load on the first file that needs them.
    code = ("import sys, raytrace\n"
            "s = raytrace.load_scene(sys.argv[1])\n"
            "raytrace.render(s, width=4, height=3)\n"
            "print(sorted(m for m in ('pygltflib', 'PIL', 'trimesh') if m in sys.modules))\n")
    (tmp_path / "s.toml").write_text('[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\n'
                                     'radius = 1\n[[lights]]\nposition = [0, 2, 0]\n')
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "s.toml")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_a_node_cycle_and_a_bad_index_are_one_line(tmp_path):
    # A node that is its own child looped for ever; an index past a list was a traceback.
    cyclic = write_gltf(tmp_path / "c.gltf", [{"mesh": 0, "children": [0]}], [SQUARE], MATTE)
    with pytest.raises(SceneError, match=r"c\.gltf: nodes\[0\]: is reached twice"):
        raytrace.load_scene(cyclic)
    bad = write_gltf(tmp_path / "i.gltf", [{"mesh": 5}], [SQUARE], MATTE)
    with pytest.raises(SceneError, match=r"i\.gltf: malformed glTF: IndexError"):
        raytrace.load_scene(bad)


def test_a_glb_of_garbage_is_one_line_with_pygltflibs_note_and_no_paragraphs(tmp_path, recwarn):
    """pygltflib warns in paragraphs (asking for issues on its tracker) before it fails on a
    file that only starts like a GLB: the failure is one line carrying its first note."""
    path = tmp_path / "m.glb"
    path.write_bytes(b"glTF" + bytes(range(256)) * 8)
    with pytest.raises(SceneError) as e:
        raytrace.Mesh(file=str(path), material="from_file")
    assert "\n" not in str(e.value) and str(e.value).startswith(f"{path}: cannot read glTF: ")
    assert "this file is version 50462976" in str(e.value)
    assert "issue" not in str(e.value)
    assert not recwarn.list


def _dome_square(tmp_path, name: str, normals: bool):
    """The square scaled ×2 along x by its node, with NORMALs tilted outwards at its corners
    (n_k ∝ (x_k/2, y_k/2, 1) in the file) or none."""
    corners = np.asarray(SQUARE["positions"], float)
    mesh = {**SQUARE, "normals": (corners / 2 + [0, 0, 1]) / np.linalg.norm(
        corners / 2 + [0, 0, 1], axis=1, keepdims=True) if normals else None}
    return write_gltf(tmp_path / f"{name}.gltf", [{"mesh": 0, "scale": [2, 1, 1]}], [mesh],
                      MATTE), corners


def test_a_node_scaled_to_zero_hides_its_part_and_the_rest_loads(tmp_path):
    """glTF allows a node's scale to be 0 (exporters hide parts so): its linear part has no
    inverse, so its normals have no inverse transpose; its faces have no area and are
    dropped. The model loads with the other node's two triangles and their file normals."""
    corners = np.asarray(SQUARE["positions"], float)
    mesh = {**SQUARE, "normals": [[0, 0, 1]] * 4}
    path = write_gltf(tmp_path / "hidden.gltf", [{"mesh": 0}, {"mesh": 0, "scale": [0, 0, 0]}],
                      [mesh], MATTE)
    loaded = raytrace.Mesh(file=path)
    assert len(loaded.faces) == 2 and loaded.degenerate == 2
    np.testing.assert_array_equal(loaded.normals, [[[0, 0, 1]] * 3] * 2)
    used = loaded.vertices[np.unique(loaded.faces)]
    assert sorted(map(tuple, used.tolist())) == sorted(map(tuple, corners.tolist()))


@pytest.mark.parametrize("normals", [True, False])
def test_gltf_normals_shade_by_the_spec(tmp_path, normals):
    """With NORMAL, the point of triangle (0, 1, 2) at barycentrics b = (0.2, 0.5, 0.3) shades
    with N = Σ b_k·n'_k / |…|, n'_k the file's normals through the inverse transpose of the
    node's matrix, diag(1/2, 1, 1) (∝ (x_k/4, y_k/2, 1)); without, with the flat +z (glTF 2.0
    §3.7.2.1: "client implementations MUST calculate flat normals"). kd 0.6 (ka = kd),
    Ia 0.1, one directional light of 1: pixel = 0.06 + 0.6·max(N·L, 0), worked here."""
    path, corners = _dome_square(tmp_path, "dome", normals)
    mesh = raytrace.Mesh(file=path, material=raytrace.Material(kd=0.6))
    assert mesh.shading == ("file" if normals else "flat")
    own = raytrace.Mesh(file=path, material="from_file")  # the same normals either way
    np.testing.assert_array_equal(own.normals, mesh.normals)
    b = np.array([0.2, 0.5, 0.3])
    world = corners[:3] * [2, 1, 1]
    p = b @ world
    n = corners[:3] / 2 + [0, 0, 1]
    n = n / np.linalg.norm(n, axis=1, keepdims=True) * [0.5, 1, 1]  # inverse transpose
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    normal = b @ n if normals else np.array([0, 0, 1.0])
    normal /= np.linalg.norm(normal)
    light = np.array([0.5, -0.3, -1.0]) / np.linalg.norm([0.5, -0.3, -1.0])
    want = 0.06 + 0.6 * max(-(normal @ light), 0.0)
    scene = make_scene([mesh], [raytrace.DirectionalLight(light, 1.0)], ambient=0.1,
                       camera=raytrace.Camera(p + [0.1, 0.2, 3.0], p, fov=10))
    assert pixel(scene)[0] == pytest.approx(want, rel=1e-5)
    if normals:  # and the tilt shows: the flat value differs
        assert abs(want - (0.06 + 0.6 * light[2] * -1)) > 1e-3


def _glb(path, gltf):
    """The .gltf file ``gltf`` (its buffer a data URI) as a GLB (glTF 2.0 §4.4): a 12-byte
    header (magic ``glTF``, version 2, total length), a JSON chunk padded with spaces and a BIN
    chunk padded with zeros to 4 bytes, each led by its length and type."""
    import base64
    import struct

    doc = json.loads(gltf.read_text())
    blob = base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1])
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    chunks = (struct.pack("<II", len(text), 0x4E4F534A) + text
              + struct.pack("<II", len(blob), 0x004E4942) + blob)
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    return path


def _edited(tmp_path, name, edit):
    """The square's .gltf file with ``edit`` applied to its JSON."""
    doc = json.loads(write_gltf(tmp_path / "base.gltf", [{"mesh": 0}], [SQUARE],
                                MATTE).read_text())
    edit(doc)
    (tmp_path / name).write_text(json.dumps(doc))
    return name


def _truncated_glb(tmp_path):
    whole = _glb(tmp_path / "whole.glb", write_gltf(tmp_path / "base.gltf", [{"mesh": 0}],
                                                      [SQUARE], MATTE)).read_bytes()
    (tmp_path / "t.glb").write_bytes(whole[:-40])  # the last 40 bytes of the BIN chunk lost
    return "t.glb"


#: Broken files → the problem their one error line states (after "FILE: key: ").
BROKEN = {
    # a GLB cut short: its buffer (byteLength 104: 4 positions × 12 bytes, 4 uv × 8, 6 uint32
    # indices × 4) holds 104 − 40 = 64 bytes
    "truncated glb": (_truncated_glb, r"buffers\[0\]: holds 64 bytes, its byteLength says 104: "
                                      r"the file is truncated"),
    "view past its buffer": (
        lambda t: _edited(t, "v.gltf", lambda d: d["bufferViews"][0].update(byteLength=999)),
        r"bufferViews\[0\]: bytes 0\.\.999 reach past the end of buffers\[0\] \(104 bytes\)"),
    "no such view": (
        lambda t: _edited(t, "n.gltf", lambda d: d["accessors"][0].update(bufferView=9)),
        r"accessors\[0\]\.bufferView: no such bufferView 9"),
    "count past its view": (  # 5 VEC3 floats = 60 bytes > the view's 48
        lambda t: _edited(t, "c.gltf", lambda d: d["accessors"][0].update(count=5)),
        r"accessors\[0\]: reaches past the end of bufferViews\[0\] \(48 bytes\): count 5"),
    "offset past its view": (
        lambda t: _edited(t, "o.gltf", lambda d: d["accessors"][0].update(byteOffset=40)),
        r"accessors\[0\]: reaches past the end of bufferViews\[0\] \(48 bytes\): count 4 "
        r"from byteOffset 40"),
    "node cycle": (
        lambda t: _edited(t, "y.gltf", lambda d: d["nodes"][0].update(children=[0])),
        r"nodes\[0\]: is reached twice: the node hierarchy is not a tree"),
    "draco": (lambda t: _edited(t, "d.gltf", lambda d: d.update(
        extensionsUsed=["KHR_draco_mesh_compression"],
        extensionsRequired=["KHR_draco_mesh_compression"])),
        r"extensionsRequired: KHR_draco_mesh_compression: its meshes are Draco-compressed"),
    "meshopt": (lambda t: _edited(t, "m.gltf", lambda d: d.update(
        extensionsUsed=["EXT_meshopt_compression"],
        extensionsRequired=["EXT_meshopt_compression"])),
        r"extensionsRequired: EXT_meshopt_compression: its meshes are meshopt-compressed"),
}


@pytest.mark.parametrize("case", BROKEN)
@pytest.mark.parametrize("how", ["alone", "in a scene", "from_file"])
def test_a_broken_gltf_is_one_line_naming_the_file_as_written_in_every_path(
        tmp_path, monkeypatch, case, how):
    """The same verdict for a broken glTF rendered alone, named by a TOML scene's mesh (it
    went to trimesh: 'FileNotFoundError: model.gltf', a node cycle accepted) or read with its
    materials: one line naming the file as the user wrote it (not resolved) and the problem."""
    make, problem = BROKEN[case]
    name = make(tmp_path)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError) as e:
        if how == "alone":
            raytrace.load_scene(name)
        else:
            raytrace.Mesh(file=name, material="from_file" if how == "from_file" else None)
    line = str(e.value)
    assert "\n" not in line and "model.gltf" not in line
    assert re.match(rf"{re.escape(name)}: {problem}", line), line


def test_a_broken_gltf_on_the_command_line_exits_2_with_one_line(tmp_path):
    name = _truncated_glb(tmp_path)
    r = subprocess.run([sys.executable, "-m", "raytrace", "render", name, "-o", "o.exr"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("raytrace: error: t.glb: buffers[0]: holds 64 bytes")
    assert not (tmp_path / "o.exr").exists()


# -- normalTexture and TANGENT ----------------------------------------------------------------
def _normal_mapped_square(tmp_path, name: str, normal_texture: dict) -> raytrace.Scene:
    """SQUARE (MATTE) with ``normalTexture`` the 2 × 2 PNG of codes (204, 128, 230), lit by
    a point light at the camera (0, 0, 3), looking at the centre."""
    write_png(tmp_path / "n.png", np.tile(np.array([204, 128, 230], np.uint8), (2, 2, 1)))
    material = [dict(MATTE[0], normalTexture=normal_texture)] if normal_texture else MATTE
    path = write_gltf(tmp_path / f"{name}.gltf", [{"mesh": 0}], [SQUARE], material, extra={
        "images": [{"uri": "n.png"}], "textures": [{"source": 0}]})
    return make_scene([raytrace.Mesh(file=path, material="from_file")],
                      [raytrace.PointLight(position=[0, 0, 3])],
                      camera=aimed_camera([0, 0, 3], [0, 0, 0]))


def test_a_normal_texture_tilts_the_normal_by_its_linear_texel_and_scale(tmp_path):
    """glTF 2.0 §3.9.3: n_t = (2·code/255 − 1)·(scale, scale, 1), the codes read as linear
    values (not sRGB), in the frame T = ∂P/∂s = +x, B = +y, N = +z of SQUARE. Codes (204,
    128, 230) at scale 0.5: n_t = (0.6·0.5, (1/255)·0.5, 205/255) = (0.3, 0.0019608,
    0.8039216), |n_t| = 0.8580756, and with the light at the eye (L = V = N) every term of the
    material (its Lambert kd and its blinn_cosine highlight, both ∝ N·L here) scales by
    N_s·L = 0.8039216/0.8580756 = 0.9368890 against the unmapped square. Decoded as sRGB the
    codes would give (0.6038, 0.2159, 0.7913) and a ratio 0.872."""
    flat = pixel(_normal_mapped_square(tmp_path, "flat", None))
    mapped = pixel(_normal_mapped_square(tmp_path, "mapped", {"index": 0, "scale": 0.5}))
    n_t = np.array([(2 * 204 / 255 - 1) * 0.5, (2 * 128 / 255 - 1) * 0.5, 2 * 230 / 255 - 1])
    np.testing.assert_allclose(mapped / flat, n_t[2] / np.linalg.norm(n_t), rtol=1e-6)
    assert abs(n_t[2] / np.linalg.norm(n_t) - 0.9368890) < 1e-7


def test_a_normal_mapped_model_renders_alike_with_and_without_tangent(tmp_path):
    """#27's requirement, on the gallery's model (scenes/models/make_normal_mapped.py): the
    sphere whose TANGENT is the analytic ∂P/∂s, and the same file without TANGENT, whose
    tangents are then MikkTSpace's (tests/test_tangents.py: within 1.3e-6° of ∂P/∂s away from
    the seam, which lies at the back). Tolerance 1e-5 per channel (measured: 6e-8, the float32
    TANGENT accessor's rounding); the map itself moves the picture by 0.015 on average and up
    to 0.32 (the same model drawn without its normalTexture), so the comparison can fail."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "make_normal_mapped", Path(__file__).resolve().parent.parent
        / "scenes/models/make_normal_mapped.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    writer = module._make_models()
    images = {}
    for tangents in (True, False):
        path = tmp_path / f"ball{int(tangents)}.glb"
        writer.write_glb(path, *module.normal_mapped(tangents))
        mesh = raytrace.Mesh(file=path, material="from_file")
        assert (mesh.tangents is not None) == tangents
        scene = make_scene([mesh], [raytrace.DirectionalLight([0.4, -0.4, -0.8])],
                           aimed_camera([0, 0, 4], [0, 0, 0]))
        images[tangents] = raytrace.render(scene, width=64, height=48).rgb
    plain = make_scene([raytrace.Mesh(file=tmp_path / "ball1.glb", material="from_file")],
                       [raytrace.DirectionalLight([0.4, -0.4, -0.8])],
                       aimed_camera([0, 0, 4], [0, 0, 0]))
    plain.objects[0].file_materials[0].normal_map = None
    unmapped = raytrace.render(plain, width=64, height=48).rgb
    assert np.abs(images[True] - images[False]).max() < 1e-5
    assert np.abs(images[True] - unmapped).max() > 0.1


def test_a_tangent_of_the_wrong_shape_is_one_line(tmp_path):
    doc = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}], [SQUARE], MATTE)
    gl = json.loads(doc.read_text())
    gl["meshes"][0]["primitives"][0]["attributes"]["TANGENT"] = 0  # POSITION's VEC3
    doc.write_text(json.dumps(gl))
    with pytest.raises(SceneError) as e:
        raytrace.Mesh(file=doc, material="from_file")
    assert str(e.value).startswith(f"{doc}: meshes[0].primitives[0].attributes.TANGENT: "
                                   "TANGENT has (4, 3), POSITION (4, 3)")


def test_an_output_never_overwrites_a_gltf_buffer_file(tmp_path, capsys):
    """A .gltf's buffers may live in files beside it (``"uri": "m.bin"``): they are inputs
    like the .gltf itself, so ``--stats m.bin`` is refused in one line and the buffer keeps
    its bytes (before, the stats JSON was written over it and the model was lost)."""
    from raytrace import cli

    tri = {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "indices": [[0, 1, 2]]}
    write_gltf(tmp_path / "m.gltf", [{"mesh": 0}], [tri], buffer_file="m.bin")
    before = (tmp_path / "m.bin").read_bytes()
    rc = cli.main(["render", str(tmp_path / "m.gltf"), "-o", str(tmp_path / "o.exr"),
                   "--width", "4", "--height", "3", "-q", "--stats", str(tmp_path / "m.bin")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and (tmp_path / "m.bin").read_bytes() == before
    assert "m.bin is a file read by the mesh of objects[0], which this command reads" in err[-1]
    assert not (tmp_path / "o.exr").exists()


# -- texture mapping: KHR_texture_transform, texCoord 1, occlusion, emission, COLOR_0 ----------
#: SQUARE's (s, t) at the world point (x, y, 0): s = (x + 1)/2, t = (1 − y)/2.
#: A 2 × 1 image, texel 0 black, texel 1 white (sRGB codes 0 and 255: exactly 0 and 1), read
#: with REPEAT: its texel centres s = 0.25 (black) and 0.75 (white) give them exactly.
BLACK_WHITE = np.array([[[0, 0, 0], [255, 255, 255]]], np.uint8)


def _unlit_square_pixel(tmp_path, at, tex_info: dict, uv1=None, name="t"):
    """The pixel seen at the point ``at`` (x, y) of SQUARE, unlit, its base colour the
    :data:`BLACK_WHITE` texture read through ``tex_info`` (a glTF textureInfo): the texel
    value there, with no light's share."""
    write_png(tmp_path / "bw.png", BLACK_WHITE)
    mat = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, **tex_info}},
            "extensions": {"KHR_materials_unlit": {}}}]
    path = write_gltf(tmp_path / f"{name}.gltf", [{"mesh": 0}], [{**SQUARE, "uv1": uv1}], mat,
                      extra={"images": [{"uri": "bw.png"}], "textures": [{"source": 0}],
                             "extensionsUsed": ["KHR_materials_unlit", "KHR_texture_transform"]})
    x, y = at
    scene = make_scene([raytrace.Mesh(file=path, material="from_file")], [],
                       camera=aimed_camera([x, y, 3.0], [x, y, 0.0]), max_depth=0)
    return pixel(scene)[0]


@pytest.mark.parametrize("transform,at,value", [
    # the identity: s = 0.25 black, s = 0.75 white
    ({}, (-0.5, 0.5), 0.0), ({}, (0.5, 0.5), 1.0),
    # offset (0.5, 0): s' = s + 0.5, the halves swap (1.25 wraps to 0.25)
    ({"offset": [0.5, 0.0]}, (-0.5, 0.5), 1.0), ({"offset": [0.5, 0.0]}, (0.5, 0.5), 0.0),
    # rotation 90°: s' = cos r·s + sin r·t = t, so the image runs down the square: at
    # y = 0.5, t = 0.25 (black), at y = −0.5, t = 0.75 (white), whatever x; the opposite
    # direction (s' = −t, 0.75 at y = 0.5 after the wrap) would read white and black
    ({"rotation": math.pi / 2}, (0.5, 0.5), 0.0), ({"rotation": math.pi / 2}, (-0.5, -0.5), 1.0),
    # scale 2: s' = 2s, two periods: s = 0.125, 0.375, 0.625, 0.875 (x = −0.75, −0.25, 0.25,
    # 0.75) read s' = 0.25, 0.75, 1.25, 1.75: black, white, black, white
    ({"scale": [2.0, 1.0]}, (-0.75, 0.5), 0.0), ({"scale": [2.0, 1.0]}, (-0.25, 0.5), 1.0),
    ({"scale": [2.0, 1.0]}, (0.25, 0.5), 0.0), ({"scale": [2.0, 1.0]}, (0.75, 0.5), 1.0),
])
def test_khr_texture_transform_moves_the_texture_by_the_spec(tmp_path, transform, at, value):
    """KHR_texture_transform's T·R·S of (s, t) (hand-worked values beside each case)."""
    info = {"extensions": {"KHR_texture_transform": transform}} if transform else {}
    assert _unlit_square_pixel(tmp_path, at, info) == pytest.approx(value, abs=1e-6)


def test_texcoord_1_reads_the_second_set(tmp_path):
    """texCoord 1 reads TEXCOORD_1, here the first set mirrored (s₁ = 1 − s): at x = −0.5,
    s = 0.25 (black) and s₁ = 0.75 (white); the KHR_texture_transform's texCoord overrides
    the textureInfo's (glTF KHR_texture_transform: "Overrides the textureInfo texCoord")."""
    uv1 = [[1 - s, t] for s, t in SQUARE["uv"]]
    at = (-0.5, 0.5)
    assert _unlit_square_pixel(tmp_path, at, {}, uv1, "a") == 0.0
    assert _unlit_square_pixel(tmp_path, at, {"texCoord": 1}, uv1, "b") == 1.0
    override = {"texCoord": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}
    assert _unlit_square_pixel(tmp_path, at, override, uv1, "c") == 1.0
    with pytest.raises(SceneError, match=r"meshes\[0\]\.primitives\[0\]\.attributes: material "
                                         r"'materials\[0\]' reads TEXCOORD_1"):
        _unlit_square_pixel(tmp_path, at, {"texCoord": 1}, None, "d")
    with pytest.raises(SceneError, match=r"baseColorTexture\.texCoord: only TEXCOORD_0 and "
                                         r"TEXCOORD_1 are supported, got 2"):
        _unlit_square_pixel(tmp_path, at, {"texCoord": 2}, uv1, "e")


def _matte_square(tmp_path, name, material: dict, mesh: dict | None = None, images=()):
    """SQUARE with the MATTE base colour (0.8, 0.4, 0.2) and ``material``'s other fields."""
    for i, codes in enumerate(images):
        write_png(tmp_path / f"{name}{i}.png", codes)
    extra = {"images": [{"uri": f"{name}{i}.png"} for i in range(len(images))],
             "textures": [{"source": i} for i in range(len(images))],
             "extensionsUsed": ["KHR_materials_emissive_strength"]} if images else {}
    path = write_gltf(tmp_path / f"{name}.gltf", [{"mesh": 0}], [{**SQUARE, **(mesh or {})}],
                      [{**MATTE[0], **material}], extra=extra)
    return raytrace.Mesh(file=path, material="from_file")


def test_occlusion_halves_the_ambient_term_only(tmp_path):
    """occlusionTexture with strength 1, read at 0.5: ambient × (1 + 1·(0.5 − 1)) = ½ (glTF
    2.0 §3.9.3). The image is 2 × 1, R codes 0 and 255 read as linear 0 and 1, sampled at
    s₁ = 0.5 (through TEXCOORD_1, s₁ = 1 − s, at x = 0), the midpoint of the texel centres:
    0.5 exactly. Ambient light (1, 1, 1) alone: ka = kd = (0.8, 0.4, 0.2) becomes (0.4, 0.2,
    0.1). A point light at the eye and no ambient: the same pixel with and without the map."""
    uv1 = {"uv1": [[1 - s, t] for s, t in SQUARE["uv"]]}
    occ = {"occlusionTexture": {"index": 0, "texCoord": 1, "strength": 1.0}}
    cam = aimed_camera([0.0, 0.5, 3.0], [0.0, 0.5, 0.0])
    light = [raytrace.PointLight(position=[0.0, 0.5, 3.0], color=[1, 1, 1])]
    with_map = _matte_square(tmp_path, "o", occ, uv1, [BLACK_WHITE])
    without = _matte_square(tmp_path, "n", {}, uv1)
    ambient = pixel(make_scene([with_map], [], cam, ambient=1.0, max_depth=0))
    np.testing.assert_allclose(ambient, [0.4, 0.2, 0.1], rtol=1e-6)
    lit = pixel(make_scene([with_map], light, cam, max_depth=0))
    assert lit.min() > 0
    np.testing.assert_array_equal(lit, pixel(make_scene([without], light, cam, max_depth=0)))


def test_emissive_texture_times_factor_times_strength(tmp_path):
    """emissiveTexture (sRGB code 128 everywhere: ((128/255 + 0.055)/1.055)^2.4 = 0.2158605)
    × emissiveFactor (1, 0.5, 0.25) × KHR_materials_emissive_strength 2 is the pixel with no
    light and no ambient (glTF 2.0 §3.9.4)."""
    mat = {"emissiveTexture": {"index": 0}, "emissiveFactor": [1.0, 0.5, 0.25],
           "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}}
    mesh = _matte_square(tmp_path, "e", mat, images=[np.full((2, 2, 3), 128, np.uint8)])
    got = pixel(make_scene([mesh], [], aimed_camera([0.3, 0.2, 3], [0.3, 0.2, 0]), max_depth=0))
    np.testing.assert_allclose(got, 0.2158605 * 2 * np.array([1, 0.5, 0.25]), rtol=1e-6)


@pytest.mark.parametrize("colors,at,want", [
    # float VEC3, red at every corner: kd × (1, 0, 0)
    (np.tile([1.0, 0.0, 0.0], (4, 1)), (0.3, -0.6), [0.8, 0.0, 0.0]),
    # normalised uint8 VEC4 (255 → 1): red, green, blue, white at corners 0…3; at (0.5, −0.5)
    # in triangle (0, 1, 2) the barycentrics are (¼, ½, ¼) (P = v₀ + ½(v₁ − v₀) + ¼(v₂ − v₀)),
    # so the colour is (¼, ½, ¼) and the pixel kd × it = (0.2, 0.2, 0.05)
    (np.array([[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255] * 4], np.uint8),
     (0.5, -0.5), [0.2, 0.2, 0.05]),
])
def test_color_0_multiplies_the_base_colour(tmp_path, colors, at, want):
    """COLOR_0 multiplies the base colour (glTF 2.0 §3.7.2.1), interpolated by barycentrics as
    texture coordinates are: ambient light (1, 1, 1) alone shows ka = kd × colour."""
    mesh = _matte_square(tmp_path, "c", {}, {"colors": colors})
    x, y = at
    got = pixel(make_scene([mesh], [], aimed_camera([x, y, 3], [x, y, 0]), ambient=1.0,
                           max_depth=0))
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-12)


def test_color_0_tints_a_metals_specular_colour(tmp_path):
    """For metallic 1 the specular colour F0 is the base colour, so COLOR_0 multiplies ks and
    kr too: a white metal with red corners, lit by a point light at the eye (ambient 0), is
    the plain metal's pixel times (1, 0, 0)."""
    metal = {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 1.0,
                                      "roughnessFactor": 1.0}}
    eye = [0.3, -0.6, 3.0]
    cam, light = aimed_camera(eye, [0.3, -0.6, 0]), [raytrace.PointLight(position=eye)]
    plain = pixel(make_scene([_matte_square(tmp_path, "p", metal)], light, cam, max_depth=0))
    red = _matte_square(tmp_path, "r", metal, {"colors": np.tile([1.0, 0.0, 0.0], (4, 1))})
    assert plain.min() > 0
    np.testing.assert_allclose(pixel(make_scene([red], light, cam, max_depth=0)),
                               plain * [1, 0, 0], rtol=1e-12)


@pytest.mark.parametrize("info,key,problem", [
    ({"extensions": {"KHR_texture_transform": {"offset": [1.0]}}},
     "baseColorTexture.extensions.KHR_texture_transform.offset", "must be a list of 2 numbers"),
    ({"extensions": {"KHR_texture_transform": {"rotation": "a"}}},
     "baseColorTexture.extensions.KHR_texture_transform.rotation", "must be a number"),
    ({"extensions": {"KHR_texture_transform": {"texCoord": 3}}},
     "baseColorTexture.extensions.KHR_texture_transform.texCoord", "only TEXCOORD_0 and"),
])
def test_a_bad_texture_transform_is_one_line_naming_its_field(tmp_path, info, key, problem):
    with pytest.raises(SceneError, match=re.escape(f"t.gltf: materials[0].pbrMetallicRoughness."
                                                   f"{key}: {problem}")):
        _unlit_square_pixel(tmp_path, (0, 0), info)


SCENES = Path(__file__).resolve().parent.parent / "scenes"
#: A glTF document with a value of every shape pygltflib's classes declare: lists of objects,
#: optional objects (camera projections, texture infos, sparse accessors), lists of numbers
#: and strings, extension and extras dicts, morph targets (lists of attribute dicts), custom
#: attributes, a key no class has, and fields left to their defaults.
RICH_GLTF = {
    "asset": {"version": "2.0", "generator": "hand", "extras": {"a": [1, 2]}},
    "extensionsUsed": ["KHR_texture_transform", "KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 2}]}},
    "scene": 0, "scenes": [{"nodes": [0, 1], "name": "s"}],
    "nodes": [{"mesh": 0, "translation": [1, 2, 3], "rotation": [0, 0, 0, 1],
               "children": [2], "weights": [0.5]},
              {"camera": 1, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
               "extensions": {"KHR_lights_punctual": {"light": 0}}},
              {"camera": 0, "scale": [2, 2, 2]}],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}},
                {"type": "orthographic",
                 "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 9}}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "_ID": 2},
                                "indices": 3, "material": 0, "mode": 4,
                                "targets": [{"POSITION": 4}]}], "weights": [0.5]}],
    "materials": [{"name": "m", "pbrMetallicRoughness": {
        "baseColorFactor": [1, 0.5, 0.25, 1], "metallicFactor": 0,
        "baseColorTexture": {"index": 0, "texCoord": 1, "extensions": {
            "KHR_texture_transform": {"offset": [0, 1], "rotation": 1.5}}}},
        "normalTexture": {"index": 0, "scale": 0.5},
        "occlusionTexture": {"index": 0, "strength": 0.25},
        "emissiveFactor": [0, 0, 1], "alphaMode": "MASK", "doubleSided": True}],
    "textures": [{"sampler": 0, "source": 0}],
    "samplers": [{"wrapS": 33071, "magFilter": 9729}],
    "images": [{"uri": "t.png", "mimeType": "image/png"}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0]},
                  {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC2",
                   "normalized": False},
                  {"componentType": 5125, "count": 3, "type": "SCALAR", "sparse": {
                      "count": 1, "indices": {"bufferView": 0, "componentType": 5125},
                      "values": {"bufferView": 0, "byteOffset": 4}}},
                  {"bufferView": 0, "componentType": 5125, "count": 3, "type": "SCALAR"},
                  {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
    "bufferViews": [{"buffer": 0, "byteLength": 36, "byteStride": 12, "target": 34962}],
    "buffers": [{"byteLength": 36, "uri": "b.bin"}],
    "animations": [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
                    "samplers": [{"input": 0, "output": 1, "interpolation": "STEP"}]}],
    "skins": [{"joints": [0], "inverseBindMatrices": 0}],
    "notAGltfKey": {"dropped": True},
}


def _fields(obj):
    """A pygltflib object tree as plain values, its classes' names kept (for ==)."""
    from dataclasses import fields, is_dataclass

    if is_dataclass(obj):
        return type(obj).__name__, {f.name: _fields(getattr(obj, f.name)) for f in fields(obj)}
    if type(obj).__name__ == "Attributes":
        return "Attributes", _fields(vars(obj))
    if isinstance(obj, list):
        return [_fields(x) for x in obj]
    if isinstance(obj, dict):
        return {k: _fields(v) for k, v in obj.items()}
    return obj


@pytest.mark.parametrize("doc", ["rich", "gltf_scene.glb", "glass_model.glb",
                                 "normal_mapped.glb"])
def test_the_reader_makes_the_objects_pygltflib_makes(doc):
    # the reader's own JSON decoding (gltf_objects) against pygltflib's (dataclasses-json):
    # the same classes, fields and values, defaults where the JSON is silent, on a document
    # with every shape of value and on the shipped models
    import pygltflib

    from raytrace.readers import gltf

    if doc == "rich":
        text = json.dumps(RICH_GLTF)
        theirs = pygltflib.GLTF2.from_json(text, infer_missing=True)
        ours = gltf._reader().from_json(text, infer_missing=True)
    else:
        theirs = pygltflib.GLTF2().load(str(SCENES / doc))
        ours = gltf._reader()().load(str(SCENES / doc))
    assert isinstance(ours, pygltflib.GLTF2)
    expected = _fields(theirs)
    assert _fields(ours)[1] == expected[1]
    if doc == "rich":  # the document's values did arrive (not two empty trees alike)
        assert ours.materials[0].normalTexture.scale == 0.5
        assert ours.meshes[0].primitives[0].attributes._ID == 2
        assert ours.cameras[1].orthographic.zfar == 9
        assert ours.samplers[0].wrapT == 10497  # pygltflib's default where the JSON is silent
        assert not hasattr(ours, "notAGltfKey")


# -- normalTexture through its texCoord and KHR_texture_transform ----------------------------
#: A directional light from 60° off SQUARE's normal, towards −y: L = (0, −sin 60°, cos 60°).
FROM_MINUS_Y = [0.0, math.sin(math.pi / 3), -math.cos(math.pi / 3)]


def _tilted_square_ratio(tmp_path, name: str, normal_texture: dict, towards: list,
                         mesh: dict | None = None) -> float:
    """SQUARE (MATTE: kd (0.8, 0.4, 0.2) and a roughness-1 highlight 0.04·N·L, every term
    ∝ N·L) with ``normalTexture`` the 2 × 2 PNG of codes (204, 128, 230), n_t = (0.6, 1/255,
    205/255), |n_t| = 1.0031477, lit by a directional light travelling ``towards``: its
    pixel over the same square's without the map, N_s·L / N·L."""
    write_png(tmp_path / "n.png", np.tile(np.array([204, 128, 230], np.uint8), (2, 2, 1)))
    values = []
    for texture in (normal_texture, None):
        material = [dict(MATTE[0], normalTexture=texture)] if texture else MATTE
        path = write_gltf(tmp_path / f"{name}{texture is None}.gltf", [{"mesh": 0}],
                          [{**SQUARE, **(mesh or {})}], material, extra={
                              "images": [{"uri": "n.png"}], "textures": [{"source": 0}],
                              "extensionsUsed": ["KHR_texture_transform"]})
        values.append(pixel(make_scene([raytrace.Mesh(file=path, material="from_file")],
                                       [raytrace.DirectionalLight(towards)],
                                       camera=aimed_camera([0, 0, 3], [0, 0, 0])))[0])
    return values[0] / values[1]


#: N_s·L / N·L where the map's +x runs along −y: (0.6·sin 60° + (205/255)·cos 60°)/|n_t|
#: over cos 60°, = (0.5196152 + 0.4019608)/1.0031477/0.5 = 1.8373686; read with T = +x
#: instead (the first set's unrotated frame), (0.0039216·sin 60° + 0.4019608)/1.0031477/0.5
#: = 0.8081701.
ALONG_MINUS_Y = 1.8373686


@pytest.mark.parametrize("tangent", [False, True])
def test_a_rotated_normal_texture_turns_the_frame_with_or_without_tangent(tmp_path, tangent):
    """KHR_texture_transform rotation π/2 on the normalTexture: (s', t') = (t, −s), so the
    map's +x (right on the image as read, glTF 2.0 §3.9.3) runs along ∂P/∂s' = ∂P/∂t = −y on
    SQUARE. Without TANGENT the MikkTSpace tangents of the mapped coordinates give it; with
    TANGENT (1, 0, 0, 1) (∂P/∂s of the file's set) the file's frame is turned by the same
    transform (tangents.mapped_tangents): the same :data:`ALONG_MINUS_Y` either way."""
    mesh = {"tangents": [[1, 0, 0, 1]] * 4} if tangent else None
    info = {"index": 0, "extensions": {"KHR_texture_transform": {"rotation": math.pi / 2}}}
    ratio = _tilted_square_ratio(tmp_path, "r", info, FROM_MINUS_Y, mesh)
    assert ratio == pytest.approx(ALONG_MINUS_Y, rel=1e-6)


def test_a_normal_texture_on_texcoord_1_takes_that_sets_tangents(tmp_path):
    """TEXCOORD_1 (s₁, t₁) = ((y + 1)/2, (x + 1)/2): s₁ runs along +y, t₁ along +x, so
    ∂P/∂s₁ = +y and ∂P/∂v₁ = −x (= N × T: w = +1). glTF 2.0 §3.7.2.1 computes the tangents
    from "the texture coordinates associated with the normal texture": the map's +x runs
    along +y. A light from +y at 60° then gives the ratio of :data:`ALONG_MINUS_Y` mirrored,
    the same number; read in the first set's frame (T = +x) it would be 0.8081701 again."""
    uv1 = [[(y + 1) / 2, (x + 1) / 2] for x, y, _ in SQUARE["positions"]]
    from_plus_y = [0.0, -math.sin(math.pi / 3), -math.cos(math.pi / 3)]
    ratio = _tilted_square_ratio(tmp_path, "c", {"index": 0, "texCoord": 1}, from_plus_y,
                                 {"uv1": uv1})
    assert ratio == pytest.approx(ALONG_MINUS_Y, rel=1e-6)


# -- what is not read, said once: metallicRoughnessTexture, orthographic cameras ---------------
def _warnings_of(load) -> list[str]:
    with pytest.warns(RenderWarning) as notes:
        load()
    return [str(n.message) for n in notes]


def test_a_metallic_roughness_texture_is_named_once_a_material_with_the_factors(tmp_path):
    """Two primitives of one material named "Metal" (metallic 1, roughness 0.5) with a
    metallicRoughnessTexture: one line, naming the material and the factors used."""
    write_png(tmp_path / "mr.png", np.full((2, 2, 3), 128, np.uint8))
    metal = [{"name": "Metal", "pbrMetallicRoughness": {
        "metallicFactor": 1.0, "roughnessFactor": 0.5, "metallicRoughnessTexture": {"index": 0}}}]
    path = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}, {"mesh": 1}], [SQUARE, SQUARE], metal,
                      extra={"images": [{"uri": "mr.png"}], "textures": [{"source": 0}]})
    assert _warnings_of(lambda: raytrace.Mesh(file=path, material="from_file")) == [
        f'{path}: materials[0] ("Metal"): metallicRoughnessTexture is not read: metallic 1, '
        "roughness 0.5 (the factors) are used over the whole surface"]


def test_an_orthographic_camera_before_a_perspective_one_names_the_one_used(tmp_path):
    """cameras[0] orthographic on the first node met, cameras[1] perspective on the next: the
    perspective one frames the render (the first perspective camera, as without the
    orthographic one), and the warning says so."""
    cameras = [{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1,
                                                         "zfar": 9}},
               {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}]
    path = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}, {"camera": 0},
                                            {"camera": 1, "translation": [0, 0, 4]}],
                      [SQUARE], MATTE, extra={"cameras": cameras})
    with pytest.warns(RenderWarning) as notes:
        scene = raytrace.load_scene(path)
    assert str(notes[0].message).startswith(
        f"{path}: cameras[0] is orthographic: not read; cameras[1], the first perspective "
        "camera, is used; no lights in the file")
    np.testing.assert_allclose(scene.camera.position, [0, 0, 4])
    assert scene.camera.fov == pytest.approx(math.degrees(0.5))
