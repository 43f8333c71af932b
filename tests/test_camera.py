"""Camera rays: pixel centres, orientation (pixel (0, 0) top-left), stratified samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

import raytrace
from raytrace import RenderSettings
from raytrace.camera import camera_rays, hash_uniform, sample_offsets
from raytrace.kernels.camera import tile_order


def _rays(camera, w, h, spp=1, seed=0):
    frame = RenderSettings(width=w, height=h, spp=spp, seed=seed)
    return camera_rays(camera, frame, 0, w * h * spp)


def test_one_pixel_ray_is_the_forward_direction():
    cam = raytrace.Camera(position=[1, 2, 3], look_at=[4, -2, 3], fov=55)
    r = _rays(cam, 1, 1)
    np.testing.assert_allclose(r.direction[0], [0.6, -0.8, 0.0], atol=1e-15)
    assert np.all(r.origin == 0)          # camera-relative


def test_pixel_centres_through_the_image_plane():
    # Default camera: at the origin looking down −z, up +y. For a W×H image and vertical
    # fov φ, pixel (row, col)'s centre is at x = (2(col + ½)/W − 1)·tan(φ/2)·W/H,
    # y = (1 − 2(row + ½)/H)·tan(φ/2) on the plane z = −1.
    w, h, fov = 8, 6, 60.0
    r = _rays(raytrace.Camera(fov=fov), w, h)
    d = r.direction.reshape(h, w, 3)
    t = math.tan(math.radians(fov) / 2)
    for row, col in [(0, 0), (0, 7), (5, 0), (3, 4), (5, 7)]:
        x = (2 * (col + 0.5) / w - 1) * t * w / h
        y = (1 - 2 * (row + 0.5) / h) * t
        expected = np.array([x, y, -1.0]) / math.sqrt(x * x + y * y + 1)
        np.testing.assert_allclose(d[row, col], expected, atol=1e-15)
    # pixel (0, 0) is top-left: up and to the left
    assert d[0, 0, 0] < 0 and d[0, 0, 1] > 0
    np.testing.assert_allclose(np.linalg.norm(r.direction, axis=1), 1.0, rtol=1e-15)


def test_vertical_fov_spans_the_image_height():
    # With H rows the top and bottom edges are at ±tan(φ/2): a ray through the very top edge
    # would be at φ/2 above the axis; the top pixel centre is at atan((1 − 1/H)·tan(φ/2)).
    h, fov = 4, 90.0
    r = _rays(raytrace.Camera(fov=fov), 1, h)
    top = math.degrees(math.atan2(r.direction[0, 1], -r.direction[0, 2]))
    assert top == pytest.approx(math.degrees(math.atan((1 - 1 / h) * 1.0)))


def test_stratified_samples_fill_the_pixel_grid():
    # spp = k²: sample j lies in cell (j % k, j // k) of a k×k grid inside the pixel.
    spp, k = 16, 4
    idx = np.arange(10 * spp)
    sx, sy = sample_offsets(spp, 7, idx)
    cell = idx % spp
    assert np.all(np.floor(sx * k) == cell % k) and np.all(np.floor(sy * k) == cell // k)
    assert np.all((sx >= 0) & (sx < 1) & (sy >= 0) & (sy < 1))
    # Deterministic for a seed, different for another.
    np.testing.assert_array_equal(sx, sample_offsets(spp, 7, idx)[0])
    assert not np.array_equal(sx, sample_offsets(spp, 8, idx)[0])


def test_hash_uniform_is_uniform_enough():
    u = hash_uniform(0, np.arange(100_000), 0)
    assert u.min() >= 0 and u.max() < 1
    hist = np.bincount((u * 10).astype(int), minlength=10)
    assert np.all(np.abs(hist - 10_000) < 500)


def test_rays_do_not_depend_on_how_the_samples_are_split():
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=5, height=3, spp=4, seed=11)
    whole = camera_rays(cam, frame, 0, 60)
    part = camera_rays(cam, frame, 24, 40)
    np.testing.assert_array_equal(whole.direction[24:40], part.direction)
    np.testing.assert_array_equal(part.sample, np.arange(16))


@pytest.mark.parametrize("spp,lanes,start,stop", [(1, 8, 0, 60), (1, 8, 7, 53), (4, 16, 24, 160),
                                                  (2, 8, 6, 90), (4, 8, 24, 160)])
def test_packet_order_is_the_same_rays_in_blocks(spp, lanes, start, stop):
    """With ``lanes`` the camera rays of a pass come block by block: the same rays (each
    ray's direction is its sample's), every sample once; where a packet holds fewer than 4 pixels
    (4 samples a pixel, 8 lanes: two) they stay in sample order."""
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=10, height=8, spp=spp, seed=3)
    plain = camera_rays(cam, frame, start, stop)
    blocks = camera_rays(cam, frame, start, stop, lanes=lanes)
    np.testing.assert_array_equal(np.sort(blocks.sample), np.arange(stop - start))
    np.testing.assert_array_equal(blocks.direction, plain.direction[blocks.sample])
    assert np.array_equal(blocks.sample, plain.sample) == (lanes // spp < 4)


def test_part_of_a_pixel_stays_in_sample_order():
    """A range that is not whole pixels (``raytrace explain`` traces one sample) is not cut
    into blocks: every ray keeps its own sample."""
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=10, height=8, spp=2, seed=3)
    for start, stop in ((5, 6), (4, 13), (3, 11)):
        plain = camera_rays(cam, frame, start, stop)
        blocks = camera_rays(cam, frame, start, stop, lanes=8)
        np.testing.assert_array_equal(blocks.sample, np.arange(stop - start))
        np.testing.assert_array_equal(blocks.direction, plain.direction)


@pytest.mark.parametrize("lanes,spp,block", [(8, 1, (2, 4)), (16, 1, (4, 4)), (8, 2, (2, 2)),
                                             (16, 4, (2, 2))])
def test_a_packet_of_rays_covers_a_block_of_pixels(lanes, spp, block):
    """Each packet of ``lanes`` consecutive camera rays looks through one block of h × w
    pixels (rows × columns, h = ⌊√p⌋ for p = lanes/spp pixels a packet), on a frame whose
    size is a multiple of the block."""
    h, w = block
    cols, rows = 4 * w, 3 * h
    order = np.empty(cols * rows * spp, np.int64)
    tile_order(0, cols * rows, cols, spp, lanes, order)
    pixel = order // spp
    for packet in np.split(pixel, len(order) // lanes):
        r, c = np.divmod(packet, cols)
        assert set(zip(r.tolist(), c.tolist(), strict=True)) == {
            (r.min() + i, c.min() + j) for i in range(h) for j in range(w)}
        assert r.min() % h == 0 and c.min() % w == 0


@pytest.mark.parametrize("kw,key", [
    (dict(look_at=[0, 0, 0], position=[0, 0, 0]), "camera.look_at"),
    (dict(look_at=[0, -1, 0]), "camera.up"),
    (dict(fov=0), "camera.fov"),
    (dict(fov=180), "camera.fov"),
    (dict(up=[0, 0, 0]), "camera.up"),
])
def test_bad_cameras_name_the_key(kw, key):
    with pytest.raises(raytrace.SceneError) as e:
        raytrace.Camera(**kw)
    assert e.value.key == key
