"""AOVs: depth, normal, albedo and id of the camera rays' first hits, against hand-worked values.

The camera looks down −z from (0, 1, 0) (right +x, up +y), so pixel (col, row)'s centre ray is
d = (x, y, −1)/√(x² + y² + 1) with x = (2(col + ½)/W − 1)·tan(fov/2)·W/H and
y = (1 − 2(row + ½)/H)·tan(fov/2) (SCENE_FORMAT.md). The floor y = 0 is hit at
t = 1/(−d_y); a sphere (c, r) at t = b − √(b² − |c − o|² + r²), b = d·(c − o). The depth AOV
is that t, the normal the unit normal turned towards the camera.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace.camera import sample_offsets

W, H, FOV = 40, 30, 50.0
EYE = np.array([0.0, 1.0, 0.0])
SPHERE_C, SPHERE_R = np.array([0.3, 1.1, -4.0]), 1.0
RED, GREY = np.array([0.8, 0.1, 0.05]), np.array([0.3, 0.3, 0.3])


def centre_ray(col: float, row: float) -> np.ndarray:
    """The unit direction through (col + sx, row + sy) given as col, row (centre: +0.5)."""
    t = math.tan(math.radians(FOV) / 2)
    x = (2 * col / W - 1) * t * W / H
    y = (1 - 2 * row / H) * t
    return np.array([x, y, -1.0]) / math.sqrt(x * x + y * y + 1)


def sphere_t(d: np.ndarray, c=SPHERE_C, r=SPHERE_R) -> float:
    oc = c - EYE
    b = float(d @ oc)
    disc = b * b - float(oc @ oc) + r * r
    return b - math.sqrt(disc) if disc >= 0 else math.inf


def scene(**render) -> raytrace.Scene:
    floor = raytrace.Material(kd=raytrace.Checker((RED, GREY), 1.0))
    return raytrace.Scene(
        camera=raytrace.Camera(position=EYE, look_at=EYE + [0, 0, -1], fov=FOV),
        objects=[raytrace.Plane([0, 0, 0], [0, 1, 0], material=floor),
                 raytrace.Sphere(SPHERE_C, SPHERE_R, material="brass")],
        lights=[raytrace.PointLight([3, 5, 2])], ambient=0.1,
        render=raytrace.RenderSettings(width=W, height=H, **render))


@pytest.fixture(scope="module")
def image() -> raytrace.Image:
    return raytrace.render(scene(), aovs=["depth", "normal", "albedo", "id"], threads=2)


def test_a_floor_pixel(image):
    col, row = 3, 27                                   # bottom left: the floor
    d = centre_ray(col + 0.5, row + 0.5)
    t = 1.0 / -d[1]                                    # from y = 1 down to y = 0
    assert image.aov("depth")[row, col] == pytest.approx(t, rel=1e-6)
    np.testing.assert_array_equal(image.aov("normal")[row, col], [0, 1, 0])
    assert image.aov("id")[row, col] == 0
    p = EYE + t * d                                    # the checker cell of the hit
    odd = (math.floor(p[0] + 1e-4) + math.floor(p[1] + 1e-4) + math.floor(p[2] + 1e-4)) % 2
    np.testing.assert_allclose(image.aov("albedo")[row, col], GREY if odd else RED, rtol=1e-6)


def test_the_other_checker_colour_one_cell_over(image):
    # Along the bottom row the hit point's x crosses whole cells: both colours appear, each
    # where the hand-worked parity says.
    row = H - 1
    seen = set()
    for col in range(W):
        d = centre_ray(col + 0.5, row + 0.5)
        p = EYE + d / -d[1]
        odd = (math.floor(p[0] + 1e-4) + math.floor(1e-4) + math.floor(p[2] + 1e-4)) % 2
        np.testing.assert_allclose(image.aov("albedo")[row, col], GREY if odd else RED,
                                   rtol=1e-6)
        seen.add(odd)
    assert seen == {0, 1}


def test_a_sphere_pixel(image):
    col, row = 22, 13                                  # the sphere, just right of centre
    d = centre_ray(col + 0.5, row + 0.5)
    t = sphere_t(d)
    assert math.isfinite(t)
    n = (EYE + t * d - SPHERE_C) / SPHERE_R            # outward: it faces the camera
    assert n @ d < 0
    assert image.aov("depth")[row, col] == pytest.approx(t, rel=1e-6)
    np.testing.assert_allclose(image.aov("normal")[row, col], n, atol=1e-6)
    assert image.aov("id")[row, col] == 1
    np.testing.assert_allclose(image.aov("albedo")[row, col],
                               raytrace.materials["brass"].kd, rtol=1e-6)


def test_a_miss(image):
    col, row = 0, 0                                    # top left: sky
    assert np.isinf(image.aov("depth")[row, col]) and image.aov("depth")[row, col] > 0
    np.testing.assert_array_equal(image.aov("normal")[row, col], [0, 0, 0])
    np.testing.assert_array_equal(image.aov("albedo")[row, col], [0, 0, 0])
    assert image.aov("id")[row, col] == -1


def test_the_normal_faces_the_camera_from_below():
    # Under the floor, looking up: the plane's normal is +y, the AOV turns it to −y.
    s = scene()
    s.camera = raytrace.Camera(position=[0, -1, 0], look_at=[0, 0, -1], fov=FOV)
    img = raytrace.render(s, width=4, height=4, aovs="normal")
    np.testing.assert_array_equal(img.aov("normal")[0, 0], [0, -1, 0])


def test_aov_shapes_and_types(image):
    assert image.aov("depth").shape == image.aov("id").shape == (H, W)
    assert image.aov("normal").shape == image.aov("albedo").shape == (H, W, 3)
    assert image.aov("depth").dtype == np.float32 and image.aov("id").dtype == np.int32


def test_the_id_of_each_object_is_its_index_in_the_scene():
    # Types interleaved, so the index is the scene's order, not spheres-then-planes-then-meshes.
    box = trimesh.creation.box(extents=[0.6, 0.6, 0.6])
    objects = [
        raytrace.Sphere([-2.0, 0.5, 0.0], 0.5),                         # 0
        raytrace.Mesh(mesh=box, translate=[-1.0, 0.5, 0.0]),             # 1
        raytrace.Plane([0, -1, 0], [0, 1, 0]),                           # 2
        raytrace.Sphere([0.0, 0.5, 0.0], 0.5),                           # 3
        raytrace.Mesh(mesh=box, translate=[1.0, 0.5, 0.0]),              # 4
        raytrace.Mesh(mesh=box, translate=[2.0, 0.5, 0.0]),              # 5
    ]
    targets = {0: [-2.0, 0.5, 0.0], 1: [-1.0, 0.5, 0.0], 2: [0.0, -1.0, 3.0],
               3: [0.0, 0.5, 0.0], 4: [1.0, 0.5, 0.0], 5: [2.0, 0.5, 0.0]}
    for index, target in targets.items():
        s = raytrace.Scene(camera=raytrace.Camera(position=[0, 0.5, 6], look_at=target),
                           objects=objects)
        img = raytrace.render(s, width=1, height=1, aovs=["id"])
        assert img.aov("id")[0, 0] == index, index


def test_samples_combine_nearest_depth_and_id_mean_normal():
    # A pixel on the sphere's silhouette, 16 jittered samples: some on the sphere (id 1),
    # some on the floor behind it (id 0). Depth and id: the nearest sample's; normal and
    # albedo: the mean over the samples (misses none here).
    spp, row, c, r = 16, 23, np.array([-0.35, 0.35, -2.5]), 0.5
    s = scene(spp=spp)
    s.objects[1] = raytrace.Sphere(c, r, material="brass")
    s.resolve_materials()
    img = raytrace.render(s, aovs="depth,normal,albedo,id")
    # The first pixel of the row whose left edge misses the sphere and right edge hits it.
    col = next(x for x in range(W) if not math.isfinite(sphere_t(centre_ray(x, row + 0.5), c, r))
               and math.isfinite(sphere_t(centre_ray(x + 1, row + 0.5), c, r)))
    first = (row * W + col) * spp
    sx, sy = sample_offsets(spp, 0, np.arange(first, first + spp))
    ts, ids, normals, albedos = [], [], [], []
    for u, v in zip(sx, sy, strict=True):
        d = centre_ray(col + u, row + v)
        t = sphere_t(d, c, r)
        if math.isfinite(t):
            ts.append(t)
            ids.append(1)
            normals.append((EYE + t * d - c) / r)
            albedos.append(raytrace.materials["brass"].kd)
        else:
            t = 1.0 / -d[1]
            p = EYE + t * d
            odd = (math.floor(p[0] + 1e-4) + math.floor(1e-4) + math.floor(p[2] + 1e-4)) % 2
            ts.append(t)
            ids.append(0)
            normals.append(np.array([0.0, 1.0, 0.0]))
            albedos.append(GREY if odd else RED)
    assert set(ids) == {0, 1}, "the pixel must straddle the silhouette"
    nearest = int(np.argmin(ts))
    assert ids[0] != ids[nearest], "sample 0 must not be the nearest (tells 'first' apart)"
    assert img.aov("depth")[row, col] == pytest.approx(ts[nearest], rel=1e-6)
    assert img.aov("id")[row, col] == ids[nearest]
    np.testing.assert_allclose(img.aov("normal")[row, col], np.mean(normals, axis=0),
                               atol=1e-6)
    np.testing.assert_allclose(img.aov("albedo")[row, col], np.mean(albedos, axis=0),
                               rtol=1e-6)


def test_aovs_are_extra_channels_of_the_same_exr(image, tmp_path):
    import OpenEXR

    path = tmp_path / "aov.exr"
    image.save(path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {k: v.pixels.copy() for k, v in f.channels().items()}
    assert sorted(ch) == sorted(["R", "G", "B", "Z", "N.X", "N.Y", "N.Z", "albedo.R",
                                 "albedo.G", "albedo.B", "id"])
    np.testing.assert_array_equal(ch["Z"], image.aov("depth"))
    np.testing.assert_array_equal(ch["N.Y"], image.aov("normal")[..., 1])
    np.testing.assert_array_equal(ch["albedo.R"], image.aov("albedo")[..., 0])
    np.testing.assert_array_equal(ch["id"], image.aov("id").astype(np.float32))
    # read_exr still reads the colour; Image.from_exr reads the AOVs back too.
    rgb, _ = raytrace.read_exr(path)
    np.testing.assert_array_equal(rgb, image.rgb)
    back = raytrace.Image.from_exr(path)
    for name in ("depth", "normal", "albedo", "id"):
        np.testing.assert_array_equal(back.aov(name), image.aov(name))
        assert back.aov(name).dtype == image.aov(name).dtype


def test_aovs_do_not_change_the_colour(image):
    plain = raytrace.render(scene(), threads=1)
    np.testing.assert_array_equal(plain.rgb, image.rgb)
    assert plain.aovs == {} and plain.channels() == {}


def test_only_what_is_asked_for_is_computed(monkeypatch):
    from raytrace import integrator

    def forbidden(*args):
        raise AssertionError("AOV kernel called without AOVs")

    with monkeypatch.context() as m:
        m.setattr(integrator, "aov_hits", forbidden)
        m.setattr(integrator, "aov_pixels", forbidden)
        raytrace.render(scene(), width=8, height=6)          # no AOVs: never called
    opts = integrator.RenderOptions(width=8, height=6, max_depth=2, aovs=("normal",))
    integ = integrator.WhittedIntegrator(scene(), opts)
    tables = []  # each pass's per-sample AOV table (made on its pass thread)
    aov_pixels = integrator.aov_pixels
    monkeypatch.setattr(integrator, "aov_pixels", lambda *args: tables.append(args[2].shape)
                        or aov_pixels(*args))
    img = integ.render()
    assert tables == [(48, 1 + 3)]  # one pass: the distance, then N.X N.Y N.Z
    assert list(img.aovs) == ["normal"]


def test_unknown_aov_names_are_one_clear_error():
    with pytest.raises(raytrace.SceneError, match=r"aovs: unknown AOV 'deph' \(choose from "
                                                  r"depth, normal, albedo, id, uv, position, "
                                                  r"samples\)"):
        raytrace.render(scene(), width=4, height=3, aovs=["deph"])
    img = raytrace.render(scene(), width=4, height=3, aovs=["id"])
    with pytest.raises(KeyError, match="rendered: id"):
        img.aov("depth")


# -- position and uv ------------------------------------------------------------------------
def test_position_is_the_world_point_of_the_nearest_hit(image):
    img = raytrace.render(scene(), aovs="position,depth", threads=2)
    for col, row in ((3, 27), (22, 13)):                   # the floor, the sphere
        d = centre_ray(col + 0.5, row + 0.5)
        t = 1.0 / -d[1] if row == 27 else sphere_t(d)
        np.testing.assert_allclose(img.aov("position")[row, col], EYE + t * d, atol=2e-6)
    # every pixel: the point is the camera plus the depth along the pixel's ray
    rows, cols = np.mgrid[0:H, 0:W]
    t = math.tan(math.radians(FOV) / 2)
    d = np.stack([(2 * (cols + 0.5) / W - 1) * t * W / H, (1 - 2 * (rows + 0.5) / H) * t,
                  -np.ones((H, W))], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    hit = np.isfinite(img.aov("depth"))
    np.testing.assert_allclose(img.aov("position")[hit],
                               EYE + img.aov("depth")[hit][:, None] * d[hit], atol=1e-5)
    np.testing.assert_array_equal(img.aov("position")[~hit], 0.0)
    assert img.aov("position").shape == (H, W, 3) and img.aov("position").dtype == np.float32


def test_uv_is_the_file_s_texture_coordinates_at_the_hit(tmp_path):
    # A unit quad facing the camera with vt at its corners (OBJ: v up), seen head-on: the
    # pixel at (x, y) of the quad reads (s, t) = (x, 1 − y), t running down the image as
    # textures read it. A sphere has no texture coordinates: (0, 0).
    (tmp_path / "quad.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
                                       "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                       "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    s = raytrace.Scene(camera=raytrace.Camera(position=[0, 0, 4], look_at=[0, 0, 0], fov=40),
                       objects=[raytrace.Mesh(file=tmp_path / "quad.obj"),
                                raytrace.Sphere([2.2, 0, 0], 0.5)],
                       lights=[raytrace.PointLight([0, 0, 5])])
    w = h = 41
    img = raytrace.render(s, width=w, height=h, aovs="uv,position,id")
    uv, p, ident = img.aov("uv"), img.aov("position"), img.aov("id")
    quad = ident == 0
    assert quad.sum() > 200
    np.testing.assert_allclose(uv[quad, 0], (p[quad, 0] + 1) / 2, atol=1e-5)
    np.testing.assert_allclose(uv[quad, 1], 1 - (p[quad, 1] + 1) / 2, atol=1e-5)
    np.testing.assert_allclose(uv[h // 2, w // 2], [0.5, 0.5], atol=1e-6)
    np.testing.assert_array_equal(uv[ident == 1], 0.0)
    assert uv.shape == (h, w, 2) and uv.dtype == np.float32
    # read back from the EXR under the channel names compositors know
    img.save(tmp_path / "uv.exr")
    back = raytrace.Image.from_exr(tmp_path / "uv.exr")
    np.testing.assert_array_equal(back.aov("uv"), uv)
    np.testing.assert_array_equal(back.aov("position"), p)
