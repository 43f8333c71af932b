"""OBJ + MTL materials (raytrace/mtl.py, raytrace/assets.py): each illum model on a flat quad
against a hand-worked pixel, and the one-line errors of bad MTL input."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from helpers import make_scene, pixel, write_png

import raytrace
from raytrace import cli
from raytrace.errors import RenderWarning, SceneError

B = np.array([0.3, 0.5, 0.7])  # the background every secondary ray ends in

QUAD = """mtllib quad.mtl
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl m
f 1/1 2/2 3/3
f 1/1 3/3 4/4
"""


def quad(tmp_path, mtl: str, obj: str = QUAD) -> raytrace.Mesh:
    """The quad z = 0, |x|, |y| ≤ 1 (normal +z) with material ``m`` of ``mtl``."""
    (tmp_path / "quad.obj").write_text(obj)
    (tmp_path / "quad.mtl").write_text(mtl)
    return raytrace.Mesh(file=tmp_path / "quad.obj", material="from_file")


def camera_at(angle: float) -> raytrace.Camera:
    """A one-pixel camera looking at the quad's centre at ``angle`` degrees from its normal."""
    a = math.radians(angle)
    return raytrace.Camera(position=(2 * math.sin(a), 0.0, 2 * math.cos(a)),
                           look_at=(0.0, 0.0, 0.0))


#: a directional light arriving at 60° from the normal: N·L = 1/2, N·H = cos 30° seen from +z
LIGHT = raytrace.DirectionalLight(direction=(-math.sin(math.pi / 3), 0.0,
                                             -math.cos(math.pi / 3)))
LIT = "Ka 0.1\nKd 0.5\nKs 0.25\nNs 10\n"


def lit_value(ks_term: bool = True) -> float:
    """Ka·Ia + Kd·(N·L) + Ks·(N·H)^Ns with Ia = 0.2 (Blinn: the MTL spec's H)."""
    return 0.1 * 0.2 + 0.5 * 0.5 + (0.25 * math.cos(math.radians(30)) ** 10 if ks_term else 0)


def render_quad(tmp_path, mtl, angle=0.0, lights=(LIGHT,), ambient=0.2):
    scene = make_scene([quad(tmp_path, "newmtl m\n" + mtl)], lights, camera_at(angle),
                       ambient=ambient, background=B)
    return pixel(scene)


def test_illum_0_is_the_constant_colour_kd(tmp_path):
    got = render_quad(tmp_path, "Kd 0.2 0.4 0.6\nKs 1\nillum 0\n")
    np.testing.assert_allclose(got, [0.2, 0.4, 0.6], rtol=1e-6)


def test_illum_1_is_ambient_and_lambert_only(tmp_path):
    got = render_quad(tmp_path, LIT + "illum 1\n")
    np.testing.assert_allclose(got, lit_value(ks_term=False), rtol=1e-6)


@pytest.mark.parametrize("illum", [2, 8, 10])
def test_illum_2_adds_the_blinn_highlight(tmp_path, illum):
    got = render_quad(tmp_path, LIT + f"illum {illum}\n")
    np.testing.assert_allclose(got, lit_value(), rtol=1e-6)


def test_illum_3_adds_ray_traced_reflection_weighted_by_ks(tmp_path):
    got = render_quad(tmp_path, LIT + "illum 3\n")
    np.testing.assert_allclose(got, lit_value() + 0.25 * B, rtol=1e-6)


def test_illum_4_dissolves_with_d(tmp_path):
    got = render_quad(tmp_path, LIT + "d 0.6\nillum 4\n")
    np.testing.assert_allclose(got, 0.6 * (lit_value() + 0.25 * B) + 0.4 * B, rtol=1e-6)


def test_illum_9_dissolves_without_reflection_and_tr_is_one_minus_d(tmp_path):
    got = render_quad(tmp_path, LIT + "Tr 0.4\nillum 9\n")
    np.testing.assert_allclose(got, 0.6 * lit_value() + 0.4 * B, rtol=1e-6)


def test_tr_1_warns_naming_the_material_the_file_and_the_fix(tmp_path, recwarn):
    """Meshlab writes ``Tr 1`` meaning opaque; by the spec (Tr = 1 − d) it is fully
    transparent: read by the spec, with a warning that says which material and how to fix it.
    A partial Tr, or a d beside it (d wins), says nothing."""
    with pytest.warns(RenderWarning) as caught:
        mesh = quad(tmp_path, "newmtl m\nKd 0.5\nTr 1\n")
    (note,) = [str(w.message) for w in caught]
    assert note == (f"{tmp_path / 'quad.mtl'}: material 'm' (line 1): Tr 1 makes it fully "
                    "transparent (Tr = 1 − d by the MTL spec), so it is not drawn; Meshlab "
                    "writes Tr 1 meaning opaque: write d 1 or Tr 0 there to see it")
    assert mesh.material.opacity == 0.0
    recwarn.clear()
    for mtl in ("newmtl m\nKd 0.5\nTr 0.4\n", "newmtl m\nKd 0.5\nd 1\nTr 1\n"):
        (tmp_path / "quad.mtl").write_text(mtl)
        raytrace.Mesh(file=tmp_path / "quad.obj", material="from_file")
    assert not [w for w in recwarn.list if issubclass(w.category, RenderWarning)]


def test_a_model_made_invisible_by_tr_is_two_warning_lines_at_the_cli(tmp_path, capsys):
    """``raytrace render quad.obj`` of the Tr 1 quad: the MTL line and the render's line that
    the model is invisible, each one line (with the default-camera line of a bare OBJ)."""
    quad(tmp_path, "newmtl m\nKd 0.5\nd 1\n")  # writes quad.obj
    (tmp_path / "quad.mtl").write_text("newmtl m\nKd 0.5\nTr 1\n")
    rc = cli.main(["render", str(tmp_path / "quad.obj"), "-o", str(tmp_path / "q.exr"), "-q",
                   "--width", "8", "--height", "6"])
    assert rc == 0
    lines = capsys.readouterr().err.splitlines()
    assert [x for x in lines if "Tr 1 makes it fully transparent" in x] == [
        f"raytrace: warning: {tmp_path / 'quad.mtl'}: material 'm' (line 1): Tr 1 makes it "
        "fully transparent (Tr = 1 − d by the MTL spec), so it is not drawn; Meshlab writes Tr "
        "1 meaning opaque: write d 1 or Tr 0 there to see it"]
    assert [x for x in lines if "opacity 0" in x] == [
        f"raytrace: warning: {tmp_path / 'quad.obj'}: objects[0]: every surface has opacity 0 "
        "(MTL d 0 or Tr 1, glTF alpha 0), so nothing of it is drawn"]


def test_illum_5_fresnel_reflection_rises_from_ks_towards_grazing(tmp_path):
    """At 60°: kr = Ks + (1 − Ks)(1 − cos 60°)⁵ = 0.25 + 0.75/32 (Schlick, F0 = Ks)."""
    got = render_quad(tmp_path, "Kd 0\nKs 0.25\nillum 5\n", angle=60.0, lights=(), ambient=0)
    np.testing.assert_allclose(got, (0.25 + 0.75 / 32) * B, rtol=1e-6)
    head_on = render_quad(tmp_path, "Kd 0\nKs 0.25\nillum 5\n", lights=(), ambient=0)
    np.testing.assert_allclose(head_on, 0.25 * B, rtol=1e-6)


def test_illum_6_refracts_with_one_minus_ks_times_tf(tmp_path):
    got = render_quad(tmp_path, "Kd 0\nKs 0.25\nTf 0.8 0.6 0.4\nNi 1.5\nillum 6\n",
                      lights=(), ambient=0)
    np.testing.assert_allclose(got, 0.25 * B + 0.75 * np.array([0.8, 0.6, 0.4]) * B,
                               rtol=1e-6)


def fresnel_by_hand(theta_deg: float, n: float) -> float:
    """Unpolarised Fresnel reflectance from air into index n, by Snell's law's angles."""
    ti = math.radians(theta_deg)
    tt = math.asin(math.sin(ti) / n)
    rs = math.sin(ti - tt) ** 2 / math.sin(ti + tt) ** 2 if ti else ((1 - n) / (1 + n)) ** 2
    rp = math.tan(ti - tt) ** 2 / math.tan(ti + tt) ** 2 if ti else rs
    return (rs + rp) / 2


@pytest.mark.parametrize("angle", [0.0, 60.0])
def test_illum_7_splits_reflection_and_refraction_by_the_fresnel_reflectance(tmp_path, angle):
    """Glass (Ni 1.5): F = 0.04 head on; at 60° F from the Fresnel equations by hand."""
    f = fresnel_by_hand(angle, 1.5)
    if angle == 0.0:
        assert f == pytest.approx(0.04)
    got = render_quad(tmp_path, "Kd 0\nKs 0.25\nTf 0.9\nNi 1.5\nillum 7\n", angle=angle,
                      lights=(), ambient=0)
    np.testing.assert_allclose(got, f * B + (1 - f) * 0.9 * B, rtol=1e-6)


def test_fresnel_is_one_beyond_the_critical_angle():
    from raytrace.kernels.core import fresnel1

    assert fresnel1(math.cos(math.radians(45)), 1.5) == 1.0  # leaving glass past 41.8°
    assert fresnel1(1.0, 1 / 1.5) == pytest.approx(0.04, abs=1e-15)


def test_ke_adds_a_constant_term(tmp_path):
    got = render_quad(tmp_path, LIT + "Ke 0.1 0.2 0.3\nillum 2\n")
    np.testing.assert_allclose(got, lit_value() + np.array([0.1, 0.2, 0.3]), rtol=1e-6)


def test_faces_take_their_own_materials_and_scene_materials_override_by_name(tmp_path):
    obj = QUAD.replace("usemtl m\nf 1/1 2/2 3/3\n", "usemtl red\nf 1/1 2/2 3/3\nusemtl m\n")
    mesh = quad(tmp_path, "newmtl red\nKd 1 0 0\nillum 1\nnewmtl m\nKd 0 0 1\nillum 1\n", obj)
    light = raytrace.PointLight(position=(0, 0, 2))
    lower_right = raytrace.Camera(position=(0.5, -0.5, 2), look_at=(0.5, -0.5, 0))
    upper_left = raytrace.Camera(position=(-0.5, 0.5, 2), look_at=(-0.5, 0.5, 0))
    red = pixel(make_scene([mesh], [light], lower_right))
    blue = pixel(make_scene([mesh], [light], upper_left))
    assert red[0] > 0 and red[1] == red[2] == 0
    assert blue[2] > 0 and blue[0] == blue[1] == 0
    mesh = quad(tmp_path, "newmtl red\nKd 1 0 0\nillum 1\nnewmtl m\nKd 0 0 1\nillum 1\n", obj)
    green = raytrace.Material(kd=[0, 1, 0], name="red")
    got = pixel(make_scene([mesh], [light], lower_right, materials={"red": green}))
    assert got[1] > 0 and got[0] == got[2] == 0


def test_a_toml_scene_takes_from_file(tmp_path):
    quad(tmp_path, "newmtl m\nKd 0.25\nillum 1\n")
    (tmp_path / "s.toml").write_text(
        '[camera]\nposition = [0, 0, 2]\nlook_at = [0, 0, 0]\n[[lights]]\ntype = "point"\n'
        'position = [0, 0, 2]\n[[objects]]\ntype = "mesh"\nfile = "quad.obj"\n'
        'material = "from_file"\n')
    scene = raytrace.load_scene(tmp_path / "s.toml")
    np.testing.assert_allclose(pixel(scene), 0.25, rtol=1e-6)
    assert tmp_path / "quad.mtl" in [p for p, _ in scene.input_files()]


@pytest.mark.parametrize("mtl, words", [
    ("newmtl m\nNi -1\n", ["quad.mtl: line 2", "Ni", ">= 0"]),
    ("newmtl m\nd 1.5\n", ["quad.mtl: line 2", "d", "[0, 1]"]),
    ("newmtl m\nillum 12\n", ["quad.mtl: line 2", "illum", "0..10"]),
    ("newmtl m\nKd 0.1 0.2\n", ["quad.mtl: line 2", "Kd", "1 or 3 numbers"]),
    ("newmtl m\nKs x\n", ["quad.mtl: line 2", "Ks", "number"]),
    ("Kd 1\n", ["quad.mtl: line 1", "Kd", "before any newmtl"]),
    ("newmtl other\n", ["quad.obj", "usemtl 'm'", "no such material"]),
])
def test_bad_mtl_values_give_one_line(tmp_path, mtl, words):
    with pytest.raises(SceneError) as e:
        quad(tmp_path, mtl)
    line = str(e.value)
    assert "\n" not in line
    for w in words:
        assert w in line


def test_a_missing_mtl_file_is_one_line_through_the_cli(tmp_path):
    (tmp_path / "quad.obj").write_text(QUAD)
    (tmp_path / "s.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "quad.obj"\n'
                                     'material = "from_file"\n')
    r = subprocess.run([sys.executable, "-m", "raytrace", "render", str(tmp_path / "s.toml"),
                        "-o", str(tmp_path / "out.exr")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1
    assert "quad.mtl" in r.stderr and "MTL file not found" in r.stderr
    assert not (tmp_path / "out.exr").exists()


def test_unmodelled_statements_are_listed_on_one_warning(tmp_path):
    with pytest.warns(RenderWarning, match=r"not modelled.*disp, map_Ks, refl"):
        quad(tmp_path, "newmtl m\nmap_Ks a.png\ndisp b.png\nrefl -type sphere c.png\n")


def test_from_file_needs_a_file_and_a_format_with_materials(tmp_path):
    with pytest.raises(SceneError, match="needs a mesh file"):
        raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                      material="from_file")
    (tmp_path / "t.stl").write_text("solid t\nendsolid t\n")
    with pytest.raises(SceneError, match="OBJ .* or a glTF/GLB"):
        raytrace.Mesh(file=tmp_path / "t.stl", material="from_file")


@pytest.mark.parametrize(("statement", "problem"), [
    ("Kd nan 1 1", "Kd: must be finite, got nan"),
    ("Ns -3", "Ns: must be >= 0, got -3.0"),
    ("d 1.5", "d: must be <= 1 (the range is [0, 1]), got 1.5"),
    ("Ni x", "Ni: must be a number, got 'x'"),
])
def test_an_mtl_value_out_of_range_reads_as_a_scene_value_does(tmp_path, statement, problem):
    with pytest.raises(SceneError) as e:
        quad(tmp_path, f"newmtl m\n{statement}\n")
    assert str(e.value) == f"{tmp_path / 'quad.mtl'}: line 2: {problem}"


def test_an_mtl_error_names_the_mtl_file_not_the_scene_object(tmp_path, monkeypatch, capsys):
    from raytrace import cli

    (tmp_path / "quad.obj").write_text(QUAD)
    (tmp_path / "quad.mtl").write_text("newmtl m\nKd nan 1 1\n")
    (tmp_path / "s.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "quad.obj"\n'
                                     'material = "from_file"\n')
    monkeypatch.chdir(tmp_path)
    assert cli.main(["render", "s.toml"]) == 2
    assert capsys.readouterr().err == ("raytrace: error: quad.mtl: line 2: Kd: must be finite, "
                                       "got nan\n")


def test_an_mtl_of_binary_bytes_is_named_not_text_without_echoing_them(tmp_path):
    (tmp_path / "quad.obj").write_text(QUAD)
    (tmp_path / "quad.mtl").write_bytes(b"V\xc3\x1e\x00\xff garbage\n")
    with pytest.raises(SceneError) as e:
        raytrace.Mesh(file=tmp_path / "quad.obj", material="from_file")
    assert str(e.value) == (f"{tmp_path / 'quad.mtl'}: mtllib: byte 0x1e on line 1 is not "
                            "text: an MTL file must be text")


def test_obj_normals_come_with_the_materials(tmp_path):
    # The quad as one polygon fanned into (1 2 3), (1 3 4), its corners naming vn by
    # v/vt/vn; a third triangle with no vn. Each corner keeps the vn it names (rows of
    # Mesh.normals); the triangle without any is flat (glTF's rule): N·L = 1/2 there, so the
    # lit value above, while the vn tilt the quad's pixel away from it.
    obj = QUAD.replace("f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
                       "vn 0 0 1\nvn 0.6 0 0.8\nf 1/1/1 2/2/2 3/3/2 4/4/1\nv 5 5 0\n"
                       "f 2 5 3\n")
    mesh = quad(tmp_path, "newmtl m\n" + LIT, obj)
    n, t = [0, 0, 1], [0.6, 0, 0.8]
    np.testing.assert_array_equal(mesh.normals, [[n, t, t], [n, t, n], [[0, 0, 0]] * 3])
    assert mesh.shading == "file"
    far = raytrace.Camera(position=(3.0, 2.5, 2), look_at=(3.0, 2.5, 0))  # inside (2 5 3)
    assert pixel(make_scene([mesh], [LIGHT], far, ambient=0.2))[0] == pytest.approx(
        lit_value(), rel=1e-5)
    tilted = raytrace.Camera(position=(0.5, -0.5, 2), look_at=(0.5, -0.5, 0))
    assert abs(pixel(make_scene([mesh], [LIGHT], tilted, ambient=0.2))[0] - lit_value()) > 0.01


# -- norm, bump, map_Bump -------------------------------------------------------------------
def _at_eye(tmp_path, mtl: str) -> np.ndarray:
    """The quad's centre pixel, lit by a point light of 1 at the camera (0, 0, 2), no
    ambient: Kd·N·L with L = V = +z."""
    scene = make_scene([quad(tmp_path, "newmtl m\nKa 0\nKd 0.5\nKs 0\n" + mtl)],
                       [raytrace.PointLight(position=[0, 0, 2])], camera_at(0.0), ambient=0.0)
    return pixel(scene)


def test_norm_is_a_tangent_space_normal_map_of_linear_codes(tmp_path):
    """``norm`` as glTF's normalTexture: codes (204, 128, 230) read linear (not sRGB),
    n_t = 2·c/255 − 1 = (0.6, 0.0039216, 0.8039216), OBJ's vt with t flipped gives T = +x,
    B = +y on the quad: N_s·L = 0.8039216/1.0031477 = 0.8013990; Kd 0.5: 0.4006995. Without
    the map 0.5."""
    write_png(tmp_path / "n.png", np.tile(np.array([204, 128, 230], np.uint8), (2, 2, 1)))
    n_t = np.array([2 * 204 / 255 - 1, 2 * 128 / 255 - 1, 2 * 230 / 255 - 1])
    assert abs(n_t[2] / np.linalg.norm(n_t) - 0.8013990) < 1e-7
    np.testing.assert_allclose(_at_eye(tmp_path, "norm n.png\n"),
                               0.5 * n_t[2] / np.linalg.norm(n_t), rtol=1e-6)


@pytest.mark.parametrize("stmt", ["bump", "map_Bump"])
def test_a_bump_map_of_a_linear_height_ramp_tilts_the_normal_by_its_slope(tmp_path, stmt):
    """Blinn 1978: a height map ``-bm 0.5`` whose 256 columns hold the codes 0 … 255 (grey,
    linear): texel i (centre s = (i + ½)/256) is i/255, so between texel centres the bilinear
    height is H(s) = (256·s − ½)/255 and ∂H/∂s = 256/255; h = 0.5·H rises along s at
    h_s = 0.5·256/255 = 0.5019608 per unit s. The quad spans s over 2 units of x: P_s =
    (2, 0, 0), P_t = (0, −2, 0) (t down the image), N = +z, σ = sign((P_s × P_t)·N) = −1,
    |P_s × P_t| = 4: N′ = N + σ·h_s·(N × P_t)/4 = (−h_s/2, 0, 1) (tilted away from the
    rise). With the light at the eye, Kd·N′·L/|N′| = 0.5/√(1 + 0.2509804²) = 0.4849592."""
    write_png(tmp_path / "ramp.png", np.tile(np.arange(256, dtype=np.uint8), (4, 1))[..., None])
    want = 0.5 / math.sqrt(1 + (0.5 * 256 / 255 / 2) ** 2)
    assert abs(want - 0.4849592) < 1e-7
    np.testing.assert_allclose(_at_eye(tmp_path, f"{stmt} -bm 0.5 ramp.png\n"), want,
                               rtol=1e-6)
    # the tilt's side: a directional light from −x at 45° sees the slope facing it
    light = raytrace.DirectionalLight(direction=[1.0, 0.0, -1.0])
    scene = make_scene([quad(tmp_path, f"newmtl m\nKa 0\nKd 0.5\nKs 0\n{stmt} -bm 0.5 "
                             "ramp.png\n")], [light], camera_at(0.0), ambient=0.0)
    a = 0.5 * 256 / 255 / 2
    np.testing.assert_allclose(pixel(scene), 0.5 * (a + 1) / math.sqrt(2) / math.sqrt(1 + a * a),
                               rtol=1e-6)


def test_norm_with_a_mirroring_s_turns_its_frame(tmp_path):
    """``norm -s -1 1 1``: s' = −s, so the map's +x runs along ∂P/∂s' = −x and the frame's
    handedness flips (w' = −1: B' = w'·(N × T') = +y, up the image still). Codes (204, 128,
    230): n_t = (0.6, 0.0039216, 0.8039216), |n_t| = 1.0031477, so N_s = (−0.6, 0.0039216,
    0.8039216)/|n_t|. Kd 0.5, a directional light from −x at 60°, L = (−sin 60°, 0, cos 60°):
    0.5·(0.5196152 + 0.4019608)/1.0031477 = 0.4593422; read with the unmirrored frame
    (T = +x) N_s·L < 0: black."""
    write_png(tmp_path / "n.png", np.tile(np.array([204, 128, 230], np.uint8), (2, 2, 1)))
    light = raytrace.DirectionalLight(direction=[math.sin(math.pi / 3), 0.0,
                                                 -math.cos(math.pi / 3)])
    scene = make_scene([quad(tmp_path, "newmtl m\nKa 0\nKd 0.5\nKs 0\nnorm -s -1 1 1 n.png\n")],
                       [light], camera_at(0.0), ambient=0.0)
    np.testing.assert_allclose(pixel(scene), 0.4593422, rtol=1e-6)


def test_a_bump_map_stretched_by_s_has_half_the_slope(tmp_path):
    """The ramp of the test above read through ``-s 0.5 1 1`` (s' = s/2: the map stretched to
    twice its width): at the centre s' = 0.25, inside the ramp, h_s' = 0.5·256/255 per unit
    s', and P_s' = ∂P/∂s' = (4, 0, 0), P_t = (0, −2, 0), |P_s' × P_t| = 8, σ = −1:
    N′ = (−h_s'·2/8, 0, 1) = (−0.1254902, 0, 1), half the tilt; at the eye
    0.5/√(1 + 0.1254902²) = 0.4961089 (unscaled: 0.4849592)."""
    write_png(tmp_path / "ramp.png", np.tile(np.arange(256, dtype=np.uint8), (4, 1))[..., None])
    want = 0.5 / math.sqrt(1 + (0.5 * 256 / 255 / 4) ** 2)
    assert abs(want - 0.4961089) < 1e-7
    np.testing.assert_allclose(_at_eye(tmp_path, "bump -bm 0.5 -s 0.5 1 1 ramp.png\n"), want,
                               rtol=1e-6)


def test_a_bad_bm_is_one_line_naming_the_statement(tmp_path):
    with pytest.raises(SceneError) as e:
        quad(tmp_path, "newmtl m\nbump -bm x ramp.png\n")
    assert "line 2: bump -bm: must be a number, got 'x'" in str(e.value)


# -- maps: map_d, map_Ke, -o and -s ------------------------------------------------------------
#: QUAD's (s, t) at the world point (x, y, 0): s = (x + 1)/2 (OBJ's u). A 2 × 1 image, texel 0
#: black, texel 1 white, read at its texel centres s = 0.25 and 0.75: exactly 0 and 1.
BLACK_WHITE = np.array([[[0, 0, 0], [255, 255, 255]]], np.uint8)


def map_pixel(tmp_path, mtl: str, x: float, ambient: float = 1.0) -> np.ndarray:
    """The pixel at (x, 0.5) of QUAD with material ``mtl`` (bw.png beside it), no light:
    ambient × ka + ke where seen, else the background B."""
    write_png(tmp_path / "bw.png", BLACK_WHITE)
    cam = raytrace.Camera(position=(x, 0.5, 2.0), look_at=(x, 0.5, 0.0))
    return pixel(make_scene([quad(tmp_path, "newmtl m\n" + mtl)], [], cam, ambient=ambient,
                            background=B))


def test_map_d_cuts_out_where_the_map_is_black(tmp_path):
    """map_d as an alpha texture (a scalar map: its luminance where the image has no alpha,
    the MTL spec's default ``-imfchan l``): at s = 0.25 the map is 0, the quad unseen, the
    background B; at s = 0.75 it is 1, the quad opaque: ka·Ia = Kd·1 = 0.6."""
    mtl = "Kd 0.6 0.6 0.6\nillum 1\nmap_d bw.png\n"
    np.testing.assert_allclose(map_pixel(tmp_path, mtl, -0.5), B, rtol=1e-6)
    np.testing.assert_allclose(map_pixel(tmp_path, mtl, 0.5), [0.6] * 3, rtol=1e-6)


@pytest.mark.parametrize("options,x,value", [
    ("", -0.5, 0.0), ("", 0.5, 1.0),
    # -o 0.5: u' = u + 0.5, the halves swap
    ("-o 0.5 0 0 ", -0.5, 1.0), ("-o 0.5 ", 0.5, 0.0),
    # -s 2: u' = 2u, two periods: u = 0.125, 0.375 (x = −0.75, −0.25) read 0.25, 0.75
    ("-s 2 1 1 ", -0.75, 0.0), ("-s 2 1 ", -0.25, 1.0),
])
def test_map_options_o_and_s_offset_and_scale_the_map(tmp_path, options, x, value):
    """``map_Kd -o u v w`` shifts the map's origin, ``-s u v w`` scales it (Wavefront MTL,
    "Options for texture map statements"): (u', v') = (sᵤ·u + oᵤ, sᵥ·v + oᵥ). Kd is the map,
    Ka follows it, ambient 1 alone: the pixel is the texel (hand values beside each case)."""
    got = map_pixel(tmp_path, f"illum 1\nmap_Kd {options}bw.png\n", x)
    np.testing.assert_allclose(got, [value] * 3, atol=1e-6)


def test_map_ke_times_ke_is_the_emission(tmp_path):
    """map_Ke times Ke (as the spec multiplies every map by its colour): at s = 0.75 the map
    is 1, the pixel Ke = (1, 0.5, 0.25) with no light and no ambient; at s = 0.25 it is 0."""
    mtl = "Kd 0\nKe 1 0.5 0.25\nillum 1\nmap_Ke bw.png\n"
    np.testing.assert_allclose(map_pixel(tmp_path, mtl, 0.5, 0.0), [1, 0.5, 0.25], rtol=1e-6)
    np.testing.assert_allclose(map_pixel(tmp_path, mtl, -0.5, 0.0), [0, 0, 0], atol=1e-9)
