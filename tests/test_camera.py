"""Camera rays: pixel centres, orientation (pixel (0, 0) top-left), stratified samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

import raytrace
from raytrace import RenderSettings
from raytrace.camera import camera_rays, hash_uniform, sample_offsets
from raytrace.kernels.camera import pixel_packets


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


@pytest.mark.parametrize("spp,lanes,start,stop,window", [
    (1, 8, 0, 60, None), (1, 8, 7, 53, None), (4, 16, 24, 160, None), (2, 8, 6, 90, None),
    (4, 8, 24, 160, None), (2, 8, 5, 6, None), (2, 8, 3, 11, None), (16, 8, 9, 40, None),
    (1, 8, 3, 30, (1, 1, 8, 7)), (3, 16, 2, 50, (3, 2, 9, 8))])
def test_packets_hold_the_pass_s_own_rays(spp, lanes, start, stop, window):
    """With ``lanes`` the camera rays of a pass come packet by packet: the same rays, each
    ray's direction bit for bit its sample's, every sample once, for whole pixels, parts of
    a pixel (``raytrace explain`` traces one sample) and crops."""
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=10, height=8, spp=spp, seed=3)
    plain = camera_rays(cam, frame, start, stop, window=window)
    packed = camera_rays(cam, frame, start, stop, window=window, lanes=lanes)
    np.testing.assert_array_equal(np.sort(packed.sample), np.arange(stop - start))
    np.testing.assert_array_equal(packed.direction, plain.direction[packed.sample])
    own = packed.packets.sample >= 0
    np.testing.assert_array_equal(packed.packets.sample[own], packed.sample)
    np.testing.assert_array_equal(packed.packets.direction[own], packed.direction)


def test_a_pass_of_whole_blocks_traces_its_packets_as_they_are():
    """Where every slot of a pass's packets is its own (a pass of whole bands of blocks, as
    the integrator cuts them), the batch is the packets' rays themselves, not a copy; a pass
    that cuts a block holds other passes' samples in its packets and keeps its own apart."""
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=10, height=8, spp=1, seed=3)
    whole = camera_rays(cam, frame, 0, 60, lanes=8)  # rows 0–5: three bands of 2×4 blocks
    assert len(whole.packets.sample) == 60
    assert np.shares_memory(whole.direction, whole.packets.direction)
    assert np.shares_memory(whole.sample, whole.packets.sample)
    cut = camera_rays(cam, frame, 7, 53, lanes=8)
    assert len(cut.packets.sample) > 46 and not np.shares_memory(cut.direction,
                                                                 cut.packets.direction)


def _packets(p):
    """Each packet of ``p`` (a CameraPackets) as the bytes of its directions."""
    return [p.direction[a:b].tobytes() for a, b in zip(p.bounds[:-1], p.bounds[1:], strict=True)]


@pytest.mark.parametrize("spp,lanes", [(1, 8), (2, 8), (1, 16), (3, 16), (16, 8)])
def test_a_range_s_packets_are_the_full_frame_s(spp, lanes):
    """A COHERENT answer may depend on a packet's other rays, so a pass, a crop or a single
    sample traces each of its rays in the very packet the full frame traces it in: every
    packet of a range is one of the full frame's, bit for bit, and holds one of the range's
    samples at least."""
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=11, height=7, spp=spp, seed=3)
    full = set(_packets(camera_rays(cam, frame, 0, 77 * spp, lanes=lanes).packets))
    for window in (None, (1, 1, 8, 7), (3, 2, 10, 5), (0, 3, 11, 4)):
        x0, y0, x1, y1 = window or (0, 0, 11, 7)
        n = (x1 - x0) * (y1 - y0) * spp
        for start, stop in ((0, n), (1, n - 2), (n // 3, n // 2), (n - 1, n)):
            p = camera_rays(cam, frame, start, stop, window=window, lanes=lanes).packets
            assert set(_packets(p)) <= full
            for a, b in zip(p.bounds[:-1], p.bounds[1:], strict=True):
                assert 0 < b - a <= lanes and (p.sample[a:b] >= 0).any()


@pytest.mark.parametrize("lanes,spp,block", [(8, 1, (2, 4)), (16, 1, (4, 4)), (8, 2, (2, 2)),
                                             (16, 4, (2, 2)), (8, 3, (1, 2))])
def test_a_packet_of_rays_covers_a_block_of_pixels(lanes, spp, block):
    """Each packet looks through one block of h × w pixels (rows × columns, h = ⌊√p⌋ for
    p = lanes/spp pixels a packet), aligned to the frame's top-left corner, every sample of
    each of them, on a frame whose size is a multiple of the block."""
    h, w = block
    cols, rows = 4 * w, 3 * h
    cam = raytrace.Camera(position=[0, 1, 5], look_at=[0, 0, 0])
    frame = RenderSettings(width=cols, height=rows, spp=spp, seed=3)
    p = camera_rays(cam, frame, 0, cols * rows * spp, lanes=lanes).packets
    assert len(p.bounds) - 1 == cols * rows // (h * w)
    for a, b in zip(p.bounds[:-1], p.bounds[1:], strict=True):
        r, c = np.divmod(p.sample[a:b] // spp, cols)
        assert b - a == h * w * spp
        assert set(zip(r.tolist(), c.tolist(), strict=True)) == {
            (r.min() + i, c.min() + j) for i in range(h) for j in range(w)}
        assert r.min() % h == 0 and c.min() % w == 0


@pytest.mark.parametrize("lanes", [4, 8, 16])
def test_a_pixel_s_points_fill_packets_of_their_own(lanes):
    """A noise-driven round's points come pixel by pixel, a pixel's count any number (none
    included): its packets hold one pixel's points each, ⌈count/lanes⌉ of them, in order,
    covering every point once, so a packet does not depend on which pass holds its pixel."""
    counts = np.random.default_rng(lanes).choice([0, 1, 3, 4, 8, 15, 16, 17, 40], 200)
    pixels = np.concatenate([[0], np.cumsum(counts)])
    out = np.empty(len(pixels) + pixels[-1] // lanes + 1, np.int64)
    k = pixel_packets(pixels, lanes, out)
    assert k == sum(-(-c // lanes) for c in counts)
    starts = out[:k + 1]
    assert starts[0] == 0 and starts[-1] == pixels[-1] and (np.diff(starts) > 0).all()
    assert (np.diff(starts) <= lanes).all()
    owner = np.searchsorted(pixels, np.arange(pixels[-1]), "right") - 1  # each point's pixel
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        assert owner[a] == owner[b - 1]  # one pixel's
        assert a == pixels[owner[a]] or (a - pixels[owner[a]]) % lanes == 0


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
