"""Trilinear texture lookups (``texture_filter = "trilinear"``): the box-filtered pyramid
(raytrace/mipmap.py), the ray-cone level of detail (raytrace/kernels/mip.py, Akenine-Möller et
al., Ray Tracing Gems ch. 20, 2019, eq. 34) and what a render shows, each against hand work."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import make_scene
from PIL import Image as PILImage

import raytrace
from raytrace import mipmap
from raytrace.errors import SceneError
from raytrace.kernels.mip import lod_rows
from raytrace.rendering import render_options
from raytrace.tables import scene_arrays


# -- the pyramid ---------------------------------------------------------------------------------
def test_the_pyramid_of_a_4x4_texture_is_its_hand_box_averages():
    """Red of texel (row j, column i) = 4j + i, green = 1, blue = 2·(4j + i):
    level 1 is 2 × 2, each the mean of a 2 × 2 block: (0 + 1 + 4 + 5)/4 = 2.5, (2 + 3 + 6 + 7)/4
    = 4.5, (8 + 9 + 12 + 13)/4 = 10.5, (10 + 11 + 14 + 15)/4 = 12.5; level 2 is 1 × 1, the mean
    of 0 … 15 = 7.5; green stays 1, blue doubles red."""
    v = np.arange(16, dtype=np.float32).reshape(4, 4)
    texels = np.stack([v, np.ones_like(v), 2 * v, np.ones_like(v)], axis=2)
    one, two = mipmap.pyramid(texels, (0, 0))
    np.testing.assert_array_equal(one[..., 0], [[2.5, 4.5], [10.5, 12.5]])
    np.testing.assert_array_equal(one[..., 1], np.ones((2, 2)))
    np.testing.assert_array_equal(one[..., 2], [[5.0, 9.0], [21.0, 25.0]])
    np.testing.assert_array_equal(two[..., :3], [[[7.5, 1.0, 15.0]]])


@pytest.mark.parametrize("wrap, last", [(0, (5 + 1) / 2), (1, 5.0), (2, 5.0)])
def test_an_odd_side_halves_to_its_ceiling_with_the_missing_texel_by_the_wrap_mode(wrap, last):
    """A row of three texels 1, 3, 5 (one row: its texel counts twice, so the mean of a 2 × 2 is
    the mean of the pair): level 1 has ⌈3/2⌉ = 2 texels, (1 + 3)/2 = 2 and (5 + texel 3)/2,
    texel 3 being texel 0 (repeat: 3), texel 2 (clamp: 5) or texel 2 (mirror: 5)."""
    texels = np.zeros((1, 3, 4), np.float32)
    texels[0, :, 0] = (1.0, 3.0, 5.0)
    levels = mipmap.pyramid(texels, (wrap, wrap))
    assert [lv.shape[:2] for lv in levels] == [(1, 2), (1, 1)]
    np.testing.assert_array_equal(levels[0][0, :, 0], [2.0, last])


# -- the level of detail -------------------------------------------------------------------------
def _textured_quad(folder, size, side, depth, shift=0.0, period=2):
    """A ``side`` × ``side`` square facing the camera (at the origin, looking down −z) at
    z = −``depth``, its (s, t) 0 … 1 (plus ``shift`` texels) over a ``size``² checker of
    ``period``-texel period (codes 0 and 255: linear 0 and 1), lit head on by a directional
    light of 1 (no ambient): a pixel is the texture there. OBJ + MTL + PNG in ``folder``."""
    i = np.arange(size) // (period // 2)
    codes = np.where((i[:, None] + i[None, :]) % 2 == 1, 255, 0).astype(np.uint8)
    PILImage.fromarray(codes, "L").convert("RGB").save(folder / "checker.png")
    (folder / "quad.mtl").write_text("newmtl q\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nillum 1\n"
                                     "map_Kd checker.png\n")
    h, d, o = side / 2, -depth, shift / size
    (folder / "quad.obj").write_text(
        f"mtllib quad.mtl\nusemtl q\nv {-h} {-h} {d}\nv {h} {-h} {d}\nv {h} {h} {d}\n"
        f"v {-h} {h} {d}\nvt {o} {o}\nvt {1 + o} {o}\nvt {1 + o} {1 + o}\nvt {o} {1 + o}\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    return raytrace.Mesh(file=str(folder / "quad.obj"), material="from_file")


def _scene(mesh, fov, pixels, **render):
    camera = raytrace.Camera(position=(0, 0, 0), look_at=(0, 0, -1), up=(0, 1, 0), fov=fov)
    light = raytrace.DirectionalLight(direction=(0, 0, -1), color=1.0)
    return make_scene([mesh], [light], camera, width=pixels, height=pixels, max_depth=0,
                      **render)


def test_lambda_is_2_where_one_pixel_covers_4x4_texels(tmp_path):
    """A 2 × 2 quad with a 256² texture (texel 2/256 = 1/128 wide) facing a camera of fov 40°
    and H = 64 pixels, at the distance D where a pixel at the centre covers 4 texels across:
    2·D·tan(20°)/64 = 4/128, D = 1/tan(20°) ≈ 2.747. By hand (eq. 34, W = γ·D, n̂·d̂ = 1 at the
    centre): Δ = ½·log₂(t_a/p_a) = ½·log₂(1/2²) = −1 (UV area ½ over world area 2 a triangle),
    ½·log₂(256·256) = 8, W = γ·D with γ = arctan(2·tan(20°)/64), so λ = −1 + 8 + log₂(γ·D)
    = 7 + log₂(4/128 · arctan(x)/x), x = 2·tan(20°)/64 = 0.011374: arctan(x)/x = 1 − x²/3 +
    … = 0.9999569, λ = 7 − 5 + log₂(0.9999569) = 2 − 6.2e-5 (the cone's γ is the arc, the
    pixel its tangent). 1 spp, so γ is not divided."""
    depth = 1.0 / math.tan(math.radians(20.0))
    scene = _scene(_textured_quad(tmp_path, 256, 2.0, depth), 40.0, 64)
    options = render_options(scene, texture_filter="trilinear")
    arrays = scene_arrays(scene)
    record = mipmap.with_mips(arrays.record, arrays.table, scene.camera, options)
    np.testing.assert_allclose(record.mips.delta, [-1.0, -1.0], rtol=1e-12)
    out = np.empty(1)
    lod_rows(record.mips, 0, np.array([0]), np.array([[0.0, 0.0, -depth]]), out)
    assert out[0] == pytest.approx(2.0 - 6.2e-5, abs=1e-6)
    assert out[0] == pytest.approx(2.0, abs=1e-4)


def _checker_view(tmp_path, texels_per_pixel, filter):
    """The checker of period 2 texels on a quad that exactly fills a 64 × 64 view of fov 2°
    (side 2·tan(1°) at depth 1), ``texels_per_pixel`` (n) texels a pixel across, so that every
    pixel centre falls on a texel centre: pixel c's centre is at s = (c + ½)/64, x = s·64n − ½
    = n·c + (n − 1)/2, a whole number for n = 1, and for n = 8 after a shift of half a texel
    (+ ½); 1 spp."""
    size = 64 * texels_per_pixel
    mesh = _textured_quad(tmp_path, size, 2.0 * math.tan(math.radians(1.0)), 1.0,
                          shift=0.0 if texels_per_pixel == 1 else 0.5)
    return raytrace.render(_scene(mesh, 2.0, 64), spp=1, threads=1,
                           texture_filter=filter).rgb[..., 0].astype(np.float64)


def test_one_texel_a_pixel_shows_level_0(tmp_path):
    """One texel a pixel: each pixel centre is a texel centre, so level 0 alone is the checker
    itself, 0 and 1 alternating. λ = log₂(γ·|P|²/|n̂·P| · 64/L) is at most
    log₂(1 + 2·tan²(1°)) = 8.8e-4 at a corner (and below 0 at the centre: γ < 2·tan(1°)/64),
    so at most 8.8e-4 of level 1 (0.5 everywhere) is mixed in: within 4.4e-4 of the checker,
    where a blurred lookup (level 1) would give 0.5."""
    tri = _checker_view(tmp_path, 1, "trilinear")
    parity = (np.add.outer(np.arange(64), np.arange(64)) + (tri[0, 0] > 0.5)) % 2
    np.testing.assert_allclose(tri, parity, atol=4.4e-4)
    # bilinear: the texel itself, up to the rounding of s·W − ½ (a few 1e-15 off a centre)
    np.testing.assert_allclose(_checker_view(tmp_path, 1, "bilinear"), parity, atol=1e-12)


def test_eight_texels_a_pixel_converge_to_the_average_grey(tmp_path):
    """Eight texels a pixel (a 512² checker): λ = 3 (to 1e-3), between levels 2 and 3, whose
    texels are all exactly 0.5 (level 1 already averages each 2 × 2 block of the checker:
    (0 + 1 + 1 + 0)/4), so every pixel is 0.5 within 1e-6 at 1 spp. Bilinear reads the one
    texel under each pixel centre, all of one parity: 0 or 1 everywhere (to rounding), 0.5
    off."""
    np.testing.assert_allclose(_checker_view(tmp_path, 8, "trilinear"), 0.5, atol=1e-6)
    assert np.all(np.abs(_checker_view(tmp_path, 8, "bilinear") - 0.5) > 0.5 - 1e-12)


def test_a_noise_driven_render_reads_textures_bilinearly_and_says_so(tmp_path):
    """Eight texels a pixel, by target error: trilinear's pyramid would make every sample
    0.5, a blur no sample count removes and the streams' difference cannot see; the render
    reads level 0 instead (the bilinear image, bit for bit, and its error estimate not 0),
    and warns that the setting is not used."""
    mesh = _textured_quad(tmp_path, 512, 2.0 * math.tan(math.radians(1.0)), 1.0, shift=0.5)
    scene = _scene(mesh, 2.0, 64)
    common = dict(target_error=0.05, threads=1, max_spp=16)
    with pytest.warns(raytrace.RenderWarning, match="trilinear.*not used by noise-driven"):
        tri = raytrace.render(scene, texture_filter="trilinear", **common)
    bi = raytrace.render(scene, texture_filter="bilinear", **common)
    np.testing.assert_array_equal(tri.rgb, bi.rgb)
    assert tri.stats["aa"]["estimated_relative_rmse"] > 0.0


# -- the setting ---------------------------------------------------------------------------------
def test_a_scene_without_textures_is_the_same_record_and_image_under_trilinear():
    scene = make_scene([raytrace.Sphere(center=(0, 0, -3), radius=1.0)],
                       [raytrace.PointLight(position=(0, 2, 0), color=1.0)], width=16,
                       height=12)
    arrays = scene_arrays(scene)
    options = render_options(scene, texture_filter="trilinear")
    assert mipmap.with_mips(arrays.record, arrays.table, scene.camera, options) is arrays.record
    np.testing.assert_array_equal(raytrace.render(scene, texture_filter="trilinear").rgb,
                                  raytrace.render(scene).rgb)


def test_an_unknown_texture_filter_is_one_line_naming_the_key():
    with pytest.raises(SceneError, match=r"render\.texture_filter.*'bilinear', 'trilinear'"):
        raytrace.RenderSettings(texture_filter="anisotropic")


def test_the_spread_is_the_papers_over_the_root_of_the_stratified_samples():
    """γ = arctan(2·tan(ψ/2)/H) (eq. 30): ψ = 90°, H = 2 gives arctan(1) = π/4; 16 stratified
    samples a pixel: a stratum a quarter of the pixel, π/16; adaptive and noise keep γ."""
    assert mipmap.spread_angle(90.0, 2, 1, "uniform") == pytest.approx(math.pi / 4, rel=1e-15)
    assert mipmap.spread_angle(90.0, 2, 16, "uniform") == pytest.approx(math.pi / 16, rel=1e-15)
    assert mipmap.spread_angle(90.0, 2, 16, "noise") == pytest.approx(math.pi / 4, rel=1e-15)


def test_only_a_scene_with_a_box_filtered_checker_has_a_spread():
    # spread None: the kernels compile none of the filter's code (kernels.material).
    def floor(kind):
        mat = raytrace.Material(kd={"pattern": "checker", "colors": [0.2, 0.8],
                                    "filter": kind})
        return make_scene([raytrace.Plane([0, -1, 0], [0, 1, 0], material=mat)],
                          camera=raytrace.Camera(fov=90.0), width=16, height=2, spp=16)
    for kind, want in (("none", None), ("box", math.pi / 16)):
        scene = floor(kind)
        arrays = scene_arrays(scene)
        record = mipmap.with_spread(arrays.record, arrays.table, scene.camera,
                                    render_options(scene))
        if want is None:
            assert record is arrays.record and record.spread is None
        else:
            assert record.spread == pytest.approx(want, rel=1e-15)
        # a noise-driven render point-samples (with_spread): no footprint shrinks with its
        # samples, so a filtered checker's blur would stay however long it ran
        noisy = mipmap.with_spread(arrays.record, arrays.table, scene.camera,
                                   render_options(scene, aa="noise"))
        assert noisy is arrays.record and noisy.spread is None


def test_a_noise_driven_render_converges_to_the_unfiltered_checker():
    """A render by target error of a box-filtered checkered floor is the same image, bit for
    bit, as of the plain checker: its samples are point samples of the pixel, so the image
    converges to the pixel's true mean (the 1024-sample reference), not to the pixel-wide
    blur a full-pixel footprint would add to every sample (with it, the blurred floor's
    streams agree and the render stopped at 6 samples a pixel where the plain floor takes
    57, its image 0.16 off)."""
    def floor(kind):
        mat = raytrace.Material(kd={"pattern": "checker", "colors": [0.2, 0.8], "scale": 0.5,
                                    "filter": kind})
        return make_scene([raytrace.Plane([0, -1, 0], [0, 1, 0], material=mat)],
                          [raytrace.DirectionalLight([0, -1, -0.2])],
                          camera=raytrace.Camera(position=[0, 0.5, 0], look_at=[0, -0.2, -4]),
                          width=24, height=16)
    plain, boxed = (raytrace.render(floor(kind), target_error=0.05, threads=1)
                    for kind in ("none", "box"))
    assert plain.stats["aa"]["samples"] == boxed.stats["aa"]["samples"]
    np.testing.assert_array_equal(plain.rgb, boxed.rgb)
