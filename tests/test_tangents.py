"""raytrace.readers.tangents (MikkTSpace's per-vertex rule, a file's tangents through a
transform) and the normal maps they serve (``kernels.material.relief1``, through a render):
tangents against the analytic ∂P/∂s of a plane and a UV sphere; one pixel of a normal-mapped
quad against the hand-worked Lambert value of the map's tilted normal; the below-the-surface
rule; and a scene without a map keeps no relief tables at all."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import aimed_camera, make_scene, pixel, unit
from PIL import Image

import raytrace
from raytrace.material import Relief, parse_relief
from raytrace.readers.tangents import given_tangents, mapped_tangents, mikktspace
from raytrace.readers.texture import Texture, uv_transform
from raytrace.tables import scene_arrays


def uv_sphere(rings: int = 32, segments: int = 64):
    """The unit UV sphere, +y up: P(θ, φ) = (sin θ sin φ, cos θ, sin θ cos φ), s = φ/2π,
    t = θ/π (t = 0 at the north pole, the image's top), the seam's vertices doubled; faces
    counter-clockwise from outside, none at a pole with zero area. Returns positions (V, 3),
    faces (F, 3), texture coordinates (V, 2) and the analytic tangents (V, 4):
    ``∂P/∂s ∝ ∂P/∂φ = sin θ·(cos φ, 0, −sin φ)``, unit, with w = +1 (B = N × T = ∂P/∂v
    with v = −t, up the sphere)."""
    theta = np.linspace(0.0, math.pi, rings + 1)
    phi = np.linspace(0.0, 2 * math.pi, segments + 1)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1)
    uv = np.stack([ph / (2 * math.pi), th / math.pi], -1)
    tangents = np.stack([np.cos(ph), np.zeros_like(ph), -np.sin(ph), np.ones_like(ph)], -1)
    index = np.arange(th.size).reshape(th.shape)
    faces = []
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = index[i, j], index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]
            if i < rings - 1:
                faces.append([a, b, c])
            if i > 0:
                faces.append([a, c, d])
    return (pos.reshape(-1, 3), np.array(faces), uv.reshape(-1, 2), tangents.reshape(-1, 4))


@pytest.mark.parametrize("mirror", [1.0, -1.0])
def test_a_plane_with_an_affine_mapping_has_the_analytic_tangent(mirror):
    """On a plane (orthonormal u₁, u₂, tilted) with (s, t) = A·(x, y), ∂P/∂s = column 0 of
    A⁻¹ in (u₁, u₂) and ∂P/∂v = −∂P/∂t = −column 1: every corner's tangent is ∂P/∂s
    normalised (it lies in the plane, so Gram–Schmidt leaves it), and w = sign((N × T)·∂P/∂v);
    mirroring s (``mirror`` −1) flips w. To rounding, on an irregular triangulation."""
    rng = np.random.default_rng(7)
    u1, u2 = unit([1.0, 0.2, -0.3]), None
    u2 = unit(np.cross([0.1, 0.3, 1.0], u1))
    n = np.cross(u1, u2)
    xy = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), -1).reshape(-1, 2)
    xy += rng.uniform(-0.3, 0.3, xy.shape)
    faces = np.array([[i * 5 + j, i * 5 + j + 1, i * 5 + j + 6] for i in range(4)
                      for j in range(4)] + [[i * 5 + j, i * 5 + j + 6, i * 5 + j + 5]
                                            for i in range(4) for j in range(4)])
    a = np.array([[0.7 * mirror, 0.2], [0.1, -0.9]])
    st = xy @ a.T
    p = xy[:, :1] * u1 + xy[:, 1:] * u2
    inv = np.linalg.inv(a)
    dp_ds = unit(inv[0, 0] * u1 + inv[1, 0] * u2)
    dp_dv = -(inv[0, 1] * u1 + inv[1, 1] * u2)
    w = np.sign(np.cross(n, dp_ds) @ dp_dv)
    # the corners wound counter-clockwise about n
    faces = np.where((np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
                      @ n > 0)[:, None], faces, faces[:, ::-1])
    out = mikktspace(p[faces], np.broadcast_to(n, (len(faces), 3, 3)), st[faces])
    np.testing.assert_allclose(out[..., :3], np.broadcast_to(dp_ds, out[..., :3].shape),
                               atol=1e-12)
    assert (out[..., 3] == w).all() and w == mirror


def test_a_uv_sphere_has_the_analytic_tangents_away_from_its_seam_and_poles():
    """UV sphere, 32 rings × 64 segments (Δφ = 5.625°), smooth normals N = P: each corner's
    MikkTSpace tangent against the analytic ∂P/∂s (:func:`uv_sphere`).
    * Inside (neither on the seam nor at a pole), each vertex has faces on both sides, whose
      chord gradients lean ±Δφ/2 from ∂P/∂s; the angle weights are mirror-symmetric about
      the meridian, so the sum is ∂P/∂s: measured within 1.3e-6°, asserted 1e-5°.
    * On the seam, a UV discontinuity, the two copies of a vertex (s = 0 and s = 1) are two
      vertices (their UVs differ), each with its faces on one side only: the chord of one
      segment, at most Δφ/2 = 2.8125° off, and not more.
    * w = +1 everywhere (the mapping does not mirror)."""
    pos, faces, uv, tangents = uv_sphere()
    out = mikktspace(pos[faces], pos[faces], uv[faces])
    cos = np.einsum("fkj,fkj->fk", out[..., :3], tangents[faces][..., :3])
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    ring, s = uv[faces][..., 1] * 32, uv[faces][..., 0]
    pole = (ring < 0.5) | (ring > 31.5)
    seam = np.isclose(s, 0.0) | np.isclose(s, 1.0)
    assert angle[~pole & ~seam].max() < 1e-5
    assert angle[seam].max() <= 5.625 / 2 + 1e-9
    assert (out[..., 3] == 1.0).all()


def test_a_file_tangent_goes_through_the_transform_and_a_mirror_flips_w():
    """A tangent is a direction along the surface: M·t normalised (not the inverse transpose
    normals take), w times sign det M; a corner without one stays zero."""
    t = np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]])
    shear = np.array([[2.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(given_tangents(t, shear), [[1, 0, 0, 1], [0, 0, 0, 0]])
    mirror = np.diag([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(given_tangents(t, mirror), [[-1, 0, 0, -1], [0, 0, 0, 0]])
    rotate = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(given_tangents(t, rotate)[0], [0, 1, 0, 1], atol=1e-15)


# -- normal maps in a render ----------------------------------------------------------------
QUAD_OBJ = ("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")


def flat_map(rgb) -> Texture:
    """A 2 × 2 texture of one linear texel value."""
    texels = np.ones((2, 2, 4), np.float32)
    texels[..., :3] = rgb
    return Texture(texels)


def quad_scene(tmp_path, material, light, camera=None) -> raytrace.Scene:
    """The quad |x|, |y| ≤ 1 in z = 0 (normal +z, s along +x, t down the image = −y, so
    T = +x, B = N × T = +y) with ``material``, lit by ``light``, seen from (0, 0, 3)."""
    path = tmp_path / "quad.obj"
    path.write_text(QUAD_OBJ)
    return make_scene([raytrace.Mesh(file=path, material=material)], [light],
                      camera=camera or aimed_camera([0.0, 0.0, 3.0], [0.0, 0.0, 0.0]))


@pytest.mark.parametrize("scale", [1.0, 0.5])
def test_a_constant_normal_map_tilts_the_normal_by_its_texel(tmp_path, scale):
    """The texel (0.8, 0.5, 0.9) (linear) encodes n_t = 2·rgb − 1 = (0.6, 0, 0.8), times
    (scale, scale, 1): N_s = normalize(0.6·scale·T + 0.8·N) with T = +x, N = +z.
    * A point light of 1 at the camera, the centre pixel (V = L = +z, distance 3, no
      attenuation), kd 0.5, no ambient: 0.5·N_s·L = 0.5·0.8/√(0.36·scale² + 0.64):
      0.5·0.8 = 0.4 at scale 1; 0.5·0.8/√0.73 = 0.468165 at scale 0.5. Without the map: 0.5.
    * A directional light from +x at 60° from the normal, L = (sin 60°, 0, cos 60°): N_s·L =
      (0.6·scale·0.8660254 + 0.8·0.5)/√(0.36·scale² + 0.64); at scale 1, 0.9196152 (a map
      read the wrong way round, −x, gives 0.1196152)."""
    m = raytrace.Material(kd=0.5, ka=0.0, normal_map=Relief(flat_map([0.8, 0.5, 0.9]), scale))
    length = math.sqrt(0.36 * scale**2 + 0.64)
    at_eye = pixel(quad_scene(tmp_path, m, raytrace.PointLight(position=[0, 0, 3])))
    np.testing.assert_allclose(at_eye, 0.5 * 0.8 / length, rtol=1e-6)
    side = raytrace.DirectionalLight(direction=[-math.sin(math.pi / 3), 0.0,
                                                -math.cos(math.pi / 3)])
    np.testing.assert_allclose(pixel(quad_scene(tmp_path, m, side)),
                               0.5 * (0.6 * scale * math.sin(math.pi / 3) + 0.4) / length,
                               rtol=1e-6)


def test_the_green_channel_tilts_the_normal_up_the_image(tmp_path):
    """+Y of a normal map is up the image (glTF §3.9.3: "+Y is up"), B = N × T = +y on the
    quad: the texel (0.5, 0.8, 0.9) is n_t = (0, 0.6, 0.8); a light from +y at 60° gives
    0.5·(0.6·sin 60° + 0.8·cos 60°) = 0.4598076; from −y, N·L = 0.4 − 0.5196 < 0: black
    (with green read downwards the two would swap)."""
    m = raytrace.Material(kd=0.5, ka=0.0, normal_map=Relief(flat_map([0.5, 0.8, 0.9])))
    for sign, want in ((1.0, 0.4598076), (-1.0, 0.0)):
        light = raytrace.DirectionalLight(direction=[0.0, -sign * math.sin(math.pi / 3),
                                                     -math.cos(math.pi / 3)])
        np.testing.assert_allclose(pixel(quad_scene(tmp_path, m, light)), want, rtol=1e-6)


def test_a_mapped_normal_below_the_surface_is_turned_over(tmp_path):
    """The stiff case of file normals (docs/shading.md, "Shading normals below the surface"),
    made by a normal map: the texel (0.525, 0.5, 0) is n_t = (0.05, 0, −1), below the face
    (N_g = +z); turned over, N = (−0.05, 0, 1)/|…|. Seen at grazing incidence (V·N_g ≈ 0.03),
    kd = ka = 0.6, Ia = 0.1, one directional light of 1, no highlight: a light in front
    (towards it (0.3, −0.2, 1)/|…|) gives 0.06 + 0.6·N·L; a light behind (0.3, −0.2, −1)/|…|
    gives 0.06 (taken as given, the map would light the open quad from behind); every pixel
    of a small grazing render is finite."""
    m = raytrace.Material(kd=0.6, normal_map=Relief(flat_map([0.525, 0.5, 0.0])))
    camera = aimed_camera([0.0, -10.0, 0.3], [0.0, 0.0, 0.0])
    turned = unit([-0.05, 0.0, 1.0])
    for towards, want in (([0.3, -0.2, 1.0], 0.06 + 0.6 * (turned @ unit([0.3, -0.2, 1.0]))),
                          ([0.3, -0.2, -1.0], 0.06)):
        scene = quad_scene(tmp_path, m, raytrace.DirectionalLight(-unit(towards), 1.0), camera)
        scene.ambient = np.full(3, 0.1)
        np.testing.assert_allclose(pixel(scene), want, rtol=2e-6)
        assert np.isfinite(raytrace.render(scene, width=16, height=12).rgb).all()


def test_a_scene_without_a_normal_map_has_no_relief_tables(tmp_path):
    """The kernels' relief code is compiled only for a scene that has a map
    (``Scene.reliefs`` None otherwise, so every other image stays bit for bit)."""
    plain = quad_scene(tmp_path, raytrace.Material(kd=0.5), raytrace.PointLight([0, 0, 3]))
    assert scene_arrays(plain).record.reliefs is None
    mapped = quad_scene(tmp_path, raytrace.Material(normal_map=Relief(flat_map(0.5))),
                        raytrace.PointLight([0, 0, 3]))
    reliefs = scene_arrays(mapped).record.reliefs
    assert reliefs is not None and reliefs.tangents.shape == (2, 3, 4)
    np.testing.assert_allclose(reliefs.tangents[..., :3], [[[1, 0, 0]] * 3] * 2, atol=1e-15)


# -- a normal map read through its mapping (uv set, transform) ----------------------------
def rotated(texture: Texture, degrees: float) -> Texture:
    """``texture`` read through KHR_texture_transform's rotation (TOML ``uv_rotation``)."""
    return texture.mapped(0, uv_transform((0.0, 0.0), math.radians(degrees), (1.0, 1.0)))


def test_a_rotated_normal_map_turns_its_tangent_frame(tmp_path):
    """uv_rotation 90° on the quad (s = (x + 1)/2, t = (1 − y)/2): the map reads
    (s', t') = (t, −s) (uv_transform's R), so its +x (right on the image as read) runs along
    ∂P/∂s' = ∂P/∂t = −y, and its +y (up) along ∂P/∂v' = ∂P/∂s = +x (glTF 2.0 §3.9.3: "+X is
    right and +Y is up"; the tangent is ∂P/∂s of the coordinates the map reads, §3.7.2.1).
    The constant texel (0.8, 0.5, 0.9) is n_t = (0.6, 0, 0.8): N_s = 0.6·(−y) + 0.8·z.
    kd 0.5, one directional light of 1, from 60° off the normal:
    * from −y, L = (0, −sin 60°, cos 60°): 0.5·(0.6·0.8660254 + 0.8·0.5) = 0.4598076;
    * from +x, L = (sin 60°, 0, cos 60°): 0.5·0.8·0.5 = 0.2.
    Read with the unrotated frame (T = +x), the two swap."""
    m = raytrace.Material(kd=0.5, ka=0.0,
                          normal_map=Relief(rotated(flat_map([0.8, 0.5, 0.9]), 90.0)))
    s60, c60 = math.sin(math.pi / 3), math.cos(math.pi / 3)
    for towards, want in (([0.0, -s60, c60], 0.4598076), ([s60, 0.0, c60], 0.2)):
        light = raytrace.DirectionalLight(direction=-np.array(towards))
        np.testing.assert_allclose(pixel(quad_scene(tmp_path, m, light)), want, rtol=1e-6)
    reliefs = scene_arrays(quad_scene(tmp_path, m, raytrace.PointLight([0, 0, 3]))).record.reliefs
    np.testing.assert_allclose(reliefs.tangents, [[[0, -1, 0, 1]] * 3] * 2, atol=1e-12)


def test_a_normal_map_is_read_at_its_mapped_coordinates(tmp_path):
    """A 2 × 1 map, clamped: texel 0 (0.8, 0.5, 0.9) is n_t = (0.6, 0, 0.8), texel 1 (0.5, 0.5,
    1) the flat normal. The centre pixel (s = 0.5) reads, with ``uv_offset = [-0.25, 0]``,
    s' = 0.25, texel 0's centre: with a point light of 1 at the camera, 0.5·0.8 = 0.4. Read at
    s = 0.5 unmapped it would be the mean (0.65, 0.5, 0.95), n_t = (0.3, 0, 0.9):
    0.5·0.9/√0.9 = 0.4743416."""
    texels = np.ones((1, 2, 4), np.float32)
    texels[0, 0, :3], texels[0, 1, :3] = [0.8, 0.5, 0.9], [0.5, 0.5, 1.0]
    shifted = Texture(texels, ("clamp", "clamp")).mapped(
        0, uv_transform((-0.25, 0.0), 0.0, (1.0, 1.0)))
    m = raytrace.Material(kd=0.5, ka=0.0, normal_map=Relief(shifted))
    np.testing.assert_allclose(pixel(quad_scene(tmp_path, m, raytrace.PointLight([0, 0, 3]))),
                               0.4, rtol=1e-6)


def test_a_scene_file_normal_map_takes_the_texture_mapping_keys(tmp_path):
    """``normal_map = { texture, uv_rotation = 90 }`` reads as a colour texture's mapping
    does (:func:`raytrace.readers.texture.parse_mapping`)."""
    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(tmp_path / "n.png")
    relief = parse_relief({"texture": str(tmp_path / "n.png"), "uv_rotation": 90.0,
                           "uv_set": 1}, "normal_map")
    assert relief.texture.uv_set == 1
    np.testing.assert_allclose(relief.texture.transform, [[0, 1, 0], [-1, 0, 0]], atol=1e-15)


def test_a_file_tangent_turns_with_the_map_as_mikktspace_of_the_mapped_set_does():
    """mapped_tangents of the quad's file frame (T = +x, w = 1) under a rotation by 90° and
    scales (2, 1) and a mirror (scale (−1, 1)) equal MikkTSpace's tangents computed from the
    mapped coordinates themselves (the quad's mapping is conformal, so the two agree exactly):
    rotation: −y, w 1; scale (2, 1): +x, w 1; mirror s' = −s: −x, w −1."""
    corners = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]]], float)
    st = np.array([[[0, 1], [1, 1], [1, 0]]], float)
    normals = np.tile([0.0, 0.0, 1.0], (1, 3, 1))
    frame = np.tile([1.0, 0.0, 0.0, 1.0], (1, 3, 1))
    for linear, want in (([[0, 1], [-1, 0]], [0, -1, 0, 1]), ([[2, 0], [0, 1]], [1, 0, 0, 1]),
                         ([[-1, 0], [0, 1]], [-1, 0, 0, -1])):
        linear = np.array([linear], float)
        turned = mapped_tangents(frame, normals, linear)
        np.testing.assert_allclose(turned, [[want] * 3], atol=1e-12)
        mapped_st = np.einsum("fij,fkj->fki", linear, st)
        np.testing.assert_allclose(mikktspace(corners, normals, mapped_st), turned, atol=1e-12)
