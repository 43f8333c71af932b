"""Image textures (raytrace/texture.py, core.texture1): texel centres and bilinear midpoints
exact, wrap modes, sRGB decoding, textures on kd from TOML, MTL map_Kd and glTF."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import make_scene, pixel, write_gltf, write_png
from PIL import Image

import raytrace
from raytrace import shading
from raytrace.errors import SceneError
from raytrace.readers import texture
from raytrace.readers.texture import Texture
from raytrace.tables import MaterialTable, texel_array

#: 4 × 2 texels, RGBA, values exact in binary so every bilinear blend below is exact
TEXELS = np.array([[[0.0, 0.25, 0.5, 1], [0.5, 0.5, 0.5, 1], [1.0, 0.0, 0.25, 1],
                    [0.25, 1.0, 0.75, 1]],
                   [[0.75, 0.5, 0.0, 1], [0.125, 0.375, 1.0, 1], [0.5, 0.75, 0.25, 1],
                    [0.0, 0.0, 0.0, 1]]], np.float32)


@pytest.mark.parametrize("wrap", ["repeat", "clamp", "mirror"])
def test_texel_centres_are_exact(wrap):
    tex = Texture(TEXELS, (wrap, wrap))
    i, j = np.meshgrid(np.arange(4), np.arange(2))
    st = np.column_stack([(i.ravel() + 0.5) / 4, (j.ravel() + 0.5) / 2])
    np.testing.assert_array_equal(shading.texture(tex, st), TEXELS[j.ravel(), i.ravel(), :3])


def test_bilinear_midpoints_are_exact_means():
    tex = Texture(TEXELS)
    # between texels (0, 0) and (1, 0): s = 1/4, t = 1/4
    np.testing.assert_array_equal(shading.texture(tex, [[0.25, 0.25]]),
                                  [(TEXELS[0, 0, :3] + TEXELS[0, 1, :3]) / 2])
    # the centre of four texels (1, 0), (2, 0), (1, 1), (2, 1): s = 1/2, t = 1/2
    four = (TEXELS[0, 1, :3] + TEXELS[0, 2, :3] + TEXELS[1, 1, :3] + TEXELS[1, 2, :3]) / 4
    np.testing.assert_array_equal(shading.texture(tex, [[0.5, 0.5]]), [four])


def test_wrap_modes_at_the_edges():
    """s = 0 lies half a texel left of texel 0's centre: repeat blends texel 3 and texel 0,
    clamp gives texel 0, mirror (texel −1 is texel 0) gives texel 0; s = 1 + 1/8 is texel 0
    under repeat."""
    row = np.float64(TEXELS[0, :, :3])
    t = 0.25
    assert np.array_equal(shading.texture(Texture(TEXELS, ("repeat",) * 2), [[0.0, t]])[0],
                          (row[3] + row[0]) / 2)
    assert np.array_equal(shading.texture(Texture(TEXELS, ("clamp",) * 2), [[0.0, t]])[0], row[0])
    assert np.array_equal(shading.texture(Texture(TEXELS, ("mirror",) * 2), [[0.0, t]])[0], row[0])
    assert np.array_equal(shading.texture(Texture(TEXELS), [[1.125, t]])[0], row[0])
    # mirror: texel 4 is texel 3, texel 5 texel 2: s = 1.25 (x = 4.5) blends texels 3 and 2
    assert np.array_equal(shading.texture(Texture(TEXELS, ("mirror",) * 2), [[1.25, t]])[0],
                          (row[3] + row[2]) / 2)


def test_an_srgb_png_is_decoded_to_linear(tmp_path):
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(tmp_path / "g.png")
    tex = Texture.from_file(tmp_path / "g.png", "kd")
    c = 128 / 255
    by_hand = ((c + 0.055) / 1.055) ** 2.4  # IEC 61966-2-1
    np.testing.assert_allclose(tex.texels[..., :3], by_hand, rtol=1e-6)
    linear = Texture.from_file(tmp_path / "g.png", "kd", srgb=False)
    np.testing.assert_allclose(linear.texels[..., :3], c, rtol=1e-6)


#: 16-bit codes one apart, which 8 bits cannot tell apart (4660 / 257 = 18.13…, 4661 / 257 =
#: 18.14…: both 8-bit code 18), in two rows of two texels, four channels.
CODES16 = np.array([[[4660, 4661, 4662, 65535], [4663, 30000, 30001, 1]],
                    [[0, 1, 65534, 32768], [65535, 12345, 12346, 12347]]], np.uint16)


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_a_16_bit_png_is_read_at_16_bits(tmp_path, channels):
    """Grey, grey + alpha, RGB and RGBA 16-bit PNGs (written by hand, helpers.write_png) read
    back as code / 65535 to float32's precision (≪ 1/65535): grey in R, G and B; alpha 1 where
    the file has none, else its own, unassociated."""
    codes = CODES16[..., :channels]
    tex = Texture.from_file(write_png(tmp_path / "t.png", codes), "kd", srgb=False)
    want = codes / 65535.0
    rgb = want[..., :1].repeat(3, axis=2) if channels <= 2 else want[..., :3]
    alpha = want[..., -1] if channels in (2, 4) else np.ones(codes.shape[:2])
    np.testing.assert_allclose(tex.texels[..., :3], rgb, rtol=0, atol=1e-7)
    np.testing.assert_allclose(tex.texels[..., 3], alpha, rtol=0, atol=1e-7)
    assert tex.texels[0, 0, 0] < tex.texels[0, 1, 0]  # 4660 < 4663: one code at 8 bits


def test_a_16_bit_png_in_a_gltf_buffer_is_decoded_from_srgb_at_16_bits(tmp_path):
    """The bytes of a 16-bit RGBA PNG (a glTF image in a buffer or a data URI), sRGB: each
    colour code c decodes to ((c/65535 + 0.055)/1.055)^2.4 (IEC 61966-2-1; all codes here
    are above the linear segment's 0.04045·65535 = 2651), alpha stays c/65535."""
    data = write_png(tmp_path / "t.png", CODES16).read_bytes()
    tex = Texture.from_file(tmp_path / "model.glb#images[0]", "kd", data=data)
    c = CODES16[..., :3] / 65535.0
    by_hand = np.where(c > 0.04045, ((c + 0.055) / 1.055) ** 2.4, c / 12.92)
    np.testing.assert_allclose(tex.texels[..., :3], by_hand, rtol=2e-6, atol=1e-9)
    np.testing.assert_allclose(tex.texels[..., 3], CODES16[..., 3] / 65535.0, atol=1e-7)
    assert tex.texels[0, 0, 0] != tex.texels[0, 0, 1]  # 4660 and 4661: apart at 16 bits


def _square_obj(tmp_path, extra_mtl=""):
    """A square z = 0, |x|, |y| ≤ 1, uv (0, 0) at the bottom left (OBJ's t runs up)."""
    (tmp_path / "sq.obj").write_text(
        "mtllib sq.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
        "vt 0 1\nusemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (tmp_path / "sq.mtl").write_text(f"newmtl m\nKa 0\nillum 1\n{extra_mtl}")
    return tmp_path / "sq.obj"


def _png(path, rgb):
    Image.fromarray(np.asarray(rgb, np.uint8)).save(path)


def _at(x, y):
    """A one-pixel camera head-on at (x, y) on the square, a unit light at the eye."""
    cam = raytrace.Camera(position=(x, y, 2), look_at=(x, y, 0))
    return cam, [raytrace.PointLight(position=(x, y, 2))]


def test_map_kd_textures_the_obj_at_its_uvs(tmp_path):
    """A 2 × 2 texture: the image's top-left texel (red) is at uv (0.25, 0.75), the top of the
    square's left half. Texel centres are exact: the pixel is the decoded texel."""
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    mesh = raytrace.Mesh(file=_square_obj(tmp_path, "map_Kd -clamp on t.png\n"),
                         material="from_file")
    for (x, y), want in [((-0.5, 0.5), [1, 0, 0]), ((0.5, 0.5), [0, 1, 0]),
                         ((-0.5, -0.5), [0, 0, 1]), ((0.5, -0.5), [1, 1, 1])]:
        cam, lights = _at(x, y)
        np.testing.assert_allclose(pixel(make_scene([mesh], lights, cam)), want, atol=1e-6)
    assert tmp_path / "t.png" in [p for p, _ in make_scene([mesh]).input_files()]


def test_a_toml_kd_texture_beside_the_checker(tmp_path):
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    (tmp_path / "sq.obj").write_text(_square_obj(tmp_path).read_text())
    (tmp_path / "s.toml").write_text(
        '[camera]\nposition = [0.5, -0.5, 2]\nlook_at = [0.5, -0.5, 0]\n[[lights]]\n'
        'position = [0.5, -0.5, 2]\n[[objects]]\ntype = "mesh"\nfile = "sq.obj"\n'
        'material = { kd = { texture = "t.png", wrap = "clamp", scale = 0.5 }, ka = 0 }\n')
    np.testing.assert_allclose(pixel(raytrace.load_scene(tmp_path / "s.toml")), 0.5, atol=1e-6)


def test_a_gltf_base_color_texture_times_its_factor(tmp_path):
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
              "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
              "material": 0}
    mat = [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1, 1, 1], "metallicFactor": 0,
                                     "roughnessFactor": 1, "baseColorTexture": {"index": 0}}}]
    path = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}], [square], mat, extra={
        "textures": [{"source": 0, "sampler": 0}], "images": [{"uri": "t.png"}],
        "samplers": [{"wrapS": 33071, "wrapT": 33071}]})
    mesh = raytrace.Mesh(file=path, material="from_file")
    cam, lights = _at(-0.5, 0.5)  # the top-left texel: red, times 0.5 in red; + ks = 0.04
    np.testing.assert_allclose(pixel(make_scene([mesh], lights, cam)), [0.54, 0.04, 0.04],
                               atol=1e-6)


def test_texture_errors_are_one_line(tmp_path):
    with pytest.raises(SceneError, match=r"sq.mtl: material 'm': map_Kd: texture file not "
                                         r"found: .*nope.png"):
        raytrace.Mesh(file=_square_obj(tmp_path, "map_Kd nope.png\n"), material="from_file")
    (tmp_path / "bad.png").write_text("not a png")
    with pytest.raises(SceneError, match="kd.texture: cannot read texture"):
        raytrace.Material(kd={"texture": str(tmp_path / "bad.png")})
    with pytest.raises(SceneError, match="kd.wrap: must be one of"):
        raytrace.Material(kd={"texture": str(tmp_path / "bad.png"), "wrap": "tile"})


def test_scenes_without_textures_carry_no_texture_arrays():
    from raytrace.integrator import WhittedIntegrator
    from raytrace.rendering import render_options

    scene = raytrace.load_scene("scenes/mesh_model.toml")
    integ = WhittedIntegrator(scene, render_options(scene, width=8, height=6))
    assert integ.tables.materials.texels.size == 0
    assert integ.tables.triangles.texcoords.size == 0


@pytest.mark.parametrize("mode, cutoff", [("BLEND", None), ("MASK", 0.6)])
def test_gltf_texture_alpha_is_opacity_in_blend_and_mask_modes(tmp_path, mode, cutoff):
    """A 2 × 1 RGBA texture, white, alpha 128/255 on the left and 1 on the right; baseColor
    0.5, metallic 0, roughness 1: the surface alone is 0.5 + ks 0.04 under a unit light at the
    eye. BLEND: t·0.54 + (1 − t)·0.2 over a 0.2 background; MASK at 0.6: clear, opaque."""
    Image.fromarray(np.array([[[255, 255, 255, 128], [255, 255, 255, 255]]], np.uint8),
                    "RGBA").save(tmp_path / "a.png")
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
              "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
              "material": 0}
    mat = {"alphaMode": mode, "pbrMetallicRoughness": {
        "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0, "roughnessFactor": 1,
        "baseColorTexture": {"index": 0}}}
    if cutoff is not None:
        mat["alphaCutoff"] = cutoff
    path = write_gltf(tmp_path / "a.gltf", [{"mesh": 0}], [square], [mat], extra={
        "textures": [{"source": 0, "sampler": 0}], "images": [{"uri": "a.png"}],
        "samplers": [{"wrapS": 33071, "wrapT": 33071}]})
    mesh = raytrace.Mesh(file=path, material="from_file")
    t = 128 / 255
    want = {"BLEND": (t * 0.54 + (1 - t) * 0.2, 0.54), "MASK": (0.2, 0.54)}[mode]
    for x, value in zip((-0.5, 0.5), want, strict=True):
        cam, lights = _at(x, 0.0)
        got = pixel(make_scene([mesh], lights, cam, background=0.2))
        np.testing.assert_allclose(got, value, rtol=1e-6)


def test_the_stored_8_bit_srgb_table_is_colour_sciences_decoding():
    """The 256 values 8-bit images are decoded through (stored so that a load need not import
    colour-science) are colour-science's cctf_decoding of c/255, bit for bit; spot values by
    IEC 61966-2-1: code 10 is on the linear segment, 10/255/12.92; code 128 is
    ((128/255 + 0.055)/1.055)^2.4 = 0.21586."""
    stored = np.loadtxt(texture.SRGB8_FILE)
    np.testing.assert_array_equal(stored, texture.srgb_decoding(8))
    assert stored[10] == pytest.approx(10 / 255 / 12.92, rel=1e-15)
    assert stored[128] == pytest.approx(((128 / 255 + 0.055) / 1.055) ** 2.4, rel=1e-12)
    assert stored[0] == 0 and stored[255] == 1


def test_a_texture_times_one_is_itself_and_its_max_is_found_once():
    tex = Texture(TEXELS)
    assert tex.scaled([1, 1, 1]) is tex
    np.testing.assert_array_equal(tex.scaled(0.5).texels[..., :3], TEXELS[..., :3] * 0.5)
    np.testing.assert_array_equal(tex.max, [1.0, 1.0, 1.0])  # by eye from TEXELS
    assert tex.max is tex.max


def test_a_gltf_image_is_decoded_once_for_the_materials_that_share_it(tmp_path):
    """Two MASK materials on one image, factor 1: one Texture serves both as kd and as
    alpha, so the material table holds its texels once (it held three copies)."""
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    quads = [dict(positions=[[x, 0, 0], [x + 1, 0, 0], [x + 1, 1, 0], [x, 1, 0]],
                  indices=[[0, 1, 2], [0, 2, 3]], uv=[[0, 1], [1, 1], [1, 0], [0, 0]],
                  material=i) for i, x in enumerate((0, 2))]
    mat = {"alphaMode": "MASK", "pbrMetallicRoughness": {
        "metallicFactor": 0, "baseColorTexture": {"index": 0}}}
    path = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}, {"mesh": 1}], quads, [mat, mat],
                      extra={"textures": [{"source": 0}], "images": [{"uri": "t.png"}]})
    mesh = raytrace.Mesh(file=path, material="from_file")
    a, b = mesh.file_materials
    assert a.kd is b.kd is a.alpha is b.alpha
    table = MaterialTable([a, b])
    assert len(table.tex_info) == 1 and table.texels.size == 2 * 2 * 4


def test_a_metallic_gltf_material_has_no_diffuse_texture(tmp_path):
    """kd = baseColor·(1 − metallic): metallic 1 makes it 0, a constant, not a texture of
    zeros the size of the image; the highlight colour F0 = baseColor factor (1) stays."""
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    mat = [{"pbrMetallicRoughness": {"metallicFactor": 1, "baseColorTexture": {"index": 0}}}]
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
              "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
              "material": 0}
    path = write_gltf(tmp_path / "m.gltf", [{"mesh": 0}], [square], mat, extra={
        "textures": [{"source": 0}], "images": [{"uri": "t.png"}]})
    (m,) = raytrace.Mesh(file=path, material="from_file").file_materials
    assert not isinstance(m.kd, Texture) and not np.any(m.kd)


@pytest.mark.parametrize("mapping,at,value", [
    ("", (-0.5, 0.5), 0.0),
    ("uv_offset = [0.5, 0]", (-0.5, 0.5), 1.0),  # s' = s + 0.5 = 0.75: white
    # s' = t (KHR_texture_transform's rotation): t = (1 − y)/2, 0.25 at y = 0.5 (black),
    # 0.75 at y = −0.5 (white)
    ("uv_rotation = 90", (0.5, 0.5), 0.0), ("uv_rotation = 90", (0.5, -0.5), 1.0),
    ("uv_scale = [2, 1]", (-0.25, 0.5), 1.0),  # s = 0.375, s' = 0.75: white
])
def test_a_toml_texture_takes_an_offset_rotation_and_scale(tmp_path, mapping, at, value):
    """A TOML texture's ``uv_offset``, ``uv_rotation`` (degrees) and ``uv_scale``, the mapping
    of glTF KHR_texture_transform (texture.uv_transform), on the square's ka with ambient 1
    alone: the pixel is the 2 × 1 black/white image's texel at (s', t') (s = (x + 1)/2)."""
    _png(tmp_path / "bw.png", [[[0, 0, 0], [255, 255, 255]]])
    (tmp_path / "sq.obj").write_text(_square_obj(tmp_path).read_text())
    x, y = at
    (tmp_path / "s.toml").write_text(
        f'[ambient]\ncolor = 1\n[camera]\nposition = [{x}, {y}, 2]\nlook_at = [{x}, {y}, 0]\n'
        '[[objects]]\ntype = "mesh"\nfile = "sq.obj"\n'
        'material = { kd = 0, ka = { texture = "bw.png"'
        + (f", {mapping}" if mapping else "") + " } }\n")
    np.testing.assert_allclose(pixel(raytrace.load_scene(tmp_path / "s.toml")), value,
                               atol=1e-6)


def test_one_image_with_two_mappings_is_stored_once():
    """Two uses of one image (its texels shared, :meth:`Texture.mapped`) are two rows of the
    texture tables over the same texels; an identity mapping is no mapping (MAP_AFFINE 0)."""
    from raytrace.kernels.records import MAP_AFFINE, MAP_SET, TEX_OFFSET

    tex = Texture(TEXELS)
    assert tex.mapped(0, texture.IDENTITY) is tex
    shifted = tex.mapped(1, texture.uv_transform((0.5, 0.0), 0.0, (1.0, 1.0)))
    table = MaterialTable([raytrace.Material(kd=tex, ke=shifted)])
    assert table.texels.size == TEXELS.size
    np.testing.assert_array_equal(table.tex_info[:, TEX_OFFSET], [0, 0])
    np.testing.assert_array_equal(table.tex_map[:, MAP_SET], [0, 1])
    np.testing.assert_array_equal(table.tex_map[:, MAP_AFFINE], [0, 1])


@pytest.mark.parametrize("key,value,problem", [
    ("uv_set", 2, "must be <= 1"), ("uv_offset", [1], "must be a list of 2 numbers"),
    ("uv_rotation", "a", "must be a number"), ("uv_scale", 2, "must be a list of 2 numbers"),
])
def test_a_bad_mapping_key_is_one_line_naming_it(tmp_path, key, value, problem):
    _png(tmp_path / "t.png", [[[0, 0, 0]]])
    with pytest.raises(SceneError, match=rf"kd\.{key}: {problem}"):
        raytrace.Material(kd={"texture": str(tmp_path / "t.png"), key: value})


def test_a_texture_on_a_scene_without_texture_coordinates_reads_its_origin(tmp_path):
    """A textured material on a mesh without texture coordinates, in a scene where no mesh has
    any: every hit reads the texture at (s, t) = (0, 0) (the stated rule), never past the end
    of the scene's empty coordinate table. At (0, 0) with repeat, bilinear weighs the four
    corner texels of this 2 × 2 image equally: sRGB codes 255, 0, 0, 255 in red → linear
    (1 + 0 + 0 + 1)/4 = 0.5; green (0, 255, 0, 255) → 0.5; blue (0, 0, 255, 255) → 0.5. Seen
    by ambient 1 alone (ka the texture, kd 0): 0.5 in every channel."""
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    mesh = raytrace.Mesh(vertices=[[-1, -1, 0], [1, -1, 0], [0, 1, 0]], faces=[[0, 1, 2]],
                         material={"ka": {"texture": str(tmp_path / "t.png")}, "kd": 0.0,
                                   "ks": 0.0})
    scene = make_scene([mesh], camera=raytrace.Camera(position=(0, 0, 3), look_at=(0, 0, 0)),
                       ambient=1.0)
    np.testing.assert_allclose(pixel(scene), 0.5, atol=1e-6)


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("srgb", [True, False])
def test_codes_decode_in_the_material_table_as_numpy_decodes_them(bits, srgb):
    # an image kept as its codes is decoded by the material table's kernel (texel_array)
    # into the values numpy's lookup gives (Texels.floats), bit for bit, beside a float
    # image copied as it is; its maximum is found from the codes without decoding them
    rng = np.random.default_rng(bits + srgb)
    codes = rng.integers(0, 2**bits, (5, 7, 4)).astype(np.uint8 if bits == 8 else np.uint16)
    coded = texture.Texels(codes=codes, colour=texture.decoding_table(bits, srgb),
                           alpha=texture.decoding_table(bits, False))
    floats = texture.Texels(rng.random((3, 2, 4)).astype(np.float32))
    max_from_codes = coded.max
    assert not coded.decoded
    flat = texel_array([floats, coded])
    assert not coded.decoded  # the table decoded into its own array
    np.testing.assert_array_equal(flat[:24], floats.floats.reshape(-1))
    by_hand = coded.colour[codes]
    by_hand[..., 3] = coded.alpha[codes[..., 3]]
    np.testing.assert_array_equal(flat[24:], by_hand.reshape(-1))
    np.testing.assert_array_equal(coded.floats, by_hand)
    np.testing.assert_array_equal(max_from_codes, by_hand[..., :3].max(axis=(0, 1)))


def test_loading_a_textured_model_keeps_its_images_as_codes(tmp_path):
    # a model's load does not decode the images a render decodes (docs/performance.md,
    # "Model files"): the base colour texture of a glTF stays 8-bit codes until a build
    # decodes it into the material table, and the render reads the decoded values
    _png(tmp_path / "t.png", [[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]])
    square = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
              "indices": [[0, 1, 2], [0, 2, 3]], "uv": [[0, 1], [1, 1], [1, 0], [0, 0]],
              "material": 0}
    mat = [{"pbrMetallicRoughness": {"metallicFactor": 0, "baseColorTexture": {"index": 0}}}]
    path = write_gltf(tmp_path / "t.gltf", [{"mesh": 0}], [square], mat, extra={
        "textures": [{"source": 0}], "images": [{"uri": "t.png"}]})
    mesh = raytrace.Mesh(file=path, material="from_file")
    image = mesh.file_materials[0].kd.image
    assert image.codes is not None and image.codes.dtype == np.uint8 and not image.decoded
    table = MaterialTable(mesh.file_materials)
    assert not image.decoded
    np.testing.assert_array_equal(table.texels.reshape(2, 2, 4)[0, 0], [1, 0, 0, 1])
