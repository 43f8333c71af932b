"""``threads=N`` changes speed, never pixels: renders are bit-identical for any thread count.

The threads render passes of whole pixels side by side, each with its own scratch arrays and
counters, and every sample's contributions are summed in a fixed order; so the image cannot
depend on which thread took which pass. The pass size is shrunk here so that a small image is
split into many passes that really do run concurrently.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace import integrator
from raytrace.integrator import RenderOptions, WhittedIntegrator, frame_passes
from raytrace.rays import CAMERA, NO_SHAPE

W, H = 48, 36
#: 1728 pixels → 18 passes.
SMALL_PASS = 97


def scene() -> raytrace.Scene:
    """Meshes (a smooth glass icosphere, a flat box), a mirror sphere, a reflective checker
    floor, a point, a spot and a jittered area light: every kind of ray, transparent shadows,
    lifted shadow-ray origins on the smooth mesh, per-hit light samples."""
    glass = raytrace.Material(kd=0.0, ks=0.5, shininess=200, highlight="blinn", kr=0.1, kt=0.9,
                              ior=1.5)
    floor = raytrace.Material(
        kd=raytrace.Checker((np.array([0.9, 0.9, 0.9]), np.array([0.2, 0.3, 0.6])), 0.5),
        ks=0.2, kr=0.2)
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0.0, 1.5, 5.0], look_at=[0.0, 0.8, 0.0], fov=45.0),
        objects=[
            raytrace.Mesh(mesh=trimesh.creation.icosphere(subdivisions=2), shading="smooth",
                          translate=[0.6, 0.8, 0.5], scale=0.8, material=glass),
            raytrace.Mesh(mesh=trimesh.creation.box(extents=[0.8, 0.8, 0.8]),
                          translate=[-1.2, 0.4, 0.8], rotate=[0.0, 30.0, 0.0],
                          material="red_plastic"),
            raytrace.Sphere([-0.5, 1.0, -1.2], 1.0, material="mirror"),
            raytrace.Plane([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], material=floor),
        ],
        lights=[raytrace.PointLight([4.0, 6.0, 4.0]),
                raytrace.SpotLight([0.0, 4.0, 2.0], [0.0, -1.0, -0.3], cutoff=40.0,
                                   exponent=4.0, color=0.5),
                # jittered: a point per hit, drawn from the global sample index and depth
                raytrace.AreaLight([-2.0, 4.0, 3.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0],
                                   samples=4, jitter=True, color=0.4)],
        ambient=0.1, render=raytrace.RenderSettings(background=[0.2, 0.3, 0.5]))


@pytest.fixture(scope="module")
def renders() -> dict:
    s = scene()
    out = {t: raytrace.render(s, width=W, height=H, threads=t, pass_samples=SMALL_PASS)
           for t in (1, 2, 3)}
    out["one pass"] = raytrace.render(s, width=W, height=H, threads=1)
    return out


def test_the_scene_exercises_every_kind_of_ray(renders):
    stats = renders[1].stats
    assert stats["rays"]["reflection"] > 0
    assert stats["rays"]["refraction"] > 0
    assert stats["rays"]["shadow"] > 0
    rgb = renders[1].rgb
    assert np.isfinite(rgb).all() and rgb.std() > 0.01


@pytest.mark.parametrize("threads", [2, 3])
def test_bit_identical_for_any_thread_count(renders, threads):
    a, b = renders[1], renders[threads]
    assert np.array_equal(a.rgb.view(np.uint32), b.rgb.view(np.uint32))
    assert a.stats["rays"] == b.stats["rays"]
    assert a.stats["pruned"] == b.stats["pruned"]


def test_bit_identical_when_rendered_in_passes(renders):
    # 97 samples per pass: the 1728-pixel image in 18 passes, split mid-row, against one pass.
    one = renders["one pass"]
    assert np.array_equal(renders[1].rgb.view(np.uint32), one.rgb.view(np.uint32))
    assert renders[1].stats["rays"] == one.stats["rays"]


def test_counters_are_summed_over_threads(renders):
    # Every thread counts its own rays; the totals must not lose a thread's share.
    for t in (2, 3):
        assert renders[t].stats["rays"] == renders[1].stats["rays"]
        assert (renders[t].stats["total_internal_reflections"]
                == renders[1].stats["total_internal_reflections"])


def test_phase_seconds_fit_in_the_total(renders):
    # trace and shade are wall seconds (the passes' wall time shared out), not thread-seconds
    # summed over threads, so with any thread count they fit in the render's total.
    for t in (1, 2, 3):
        sec = renders[t].stats["seconds"]
        assert 0 < sec["trace"] and 0 < sec["shade"]
        assert sec["build"] + sec["trace"] + sec["shade"] <= sec["total"]


def test_an_error_in_a_pass_stops_the_render_and_is_raised(monkeypatch):
    # A failure in any thread's pass reaches the caller (not swallowed by the pool), and the
    # other threads take no further passes.
    calls = []
    real = integrator.WhittedIntegrator.trace_samples

    def failing(self, start, stop, samples):
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("boom")
        return real(self, start, stop, samples)

    monkeypatch.setattr(integrator.WhittedIntegrator, "trace_samples", failing)
    with pytest.raises(RuntimeError, match="boom"):
        raytrace.render(scene(), width=W, height=H, threads=2, pass_samples=SMALL_PASS)
    # 18 passes; after the third fails, the other thread finishes the pass it is on at most.
    assert len(calls) <= 4


#: Image, spp, threads, and the pass size: plain, then in whole bands of camera-ray blocks of
#: 4 or 8 lanes (h = 2 rows at 1 spp, 1 at 3 and 5) and of 16 lanes (h = 4, 2 and 1). From 8
#: threads a frame goes in 16 passes or more; on fewer, in 2 a thread or more, a multiple of
#: the threads, cut evenly; each share rounded up to whole pixels or bands, down where up
#: would pass the most a pass holds (65 536).
PASS_SIZES = [
    (2000, 2000, 1, 16, 65536, 64000, 64000),  # large: the full pass (PASS_SAMPLES), or down
    (2000, 2000, 1, 2, 64517, 64000, 64000),   # 62 passes: 4 000 000 / 62, rounded up
    (1000, 1000, 1, 16, 62500, 64000, 64000),  # 16 passes of 62 500, just under PASS_SAMPLES
    (1000, 1000, 1, 1, 62500, 64000, 64000),   # 16 of at most 65 536 on 1, 2 or 4 threads…
    (1000, 1000, 1, 7, 47620, 48000, 48000),   # …but 21 on 7 threads, 3 each: 10⁶ / 21
    (250, 250, 1, 16, 16384, 16500, 17000),    # 62 500 / 16 = 3907 → MIN_PASS_SAMPLES: 4 passes
    (250, 250, 1, 2, 16384, 16500, 17000),     # 62 500 / 4 = 15 625 → MIN_PASS_SAMPLES
    (250, 250, 1, 1, 31250, 31500, 32000),     # 2 passes on one thread
    (1024, 512, 1, 16, 32768, 32768, 32768),   # 524 288 / 16 = 32 768: exactly 16 passes
    (1024, 512, 1, 2, 65536, 65536, 65536),    # 8 passes on 2 threads, the most a pass
    (500, 500, 3, 16, 46875, 48000, 48000),    # 750 000 / 16 = 46 875 = 15 625 pixels of 3
    (500, 500, 3, 2, 62502, 63000, 63000),     # 12 passes: 62 500 up to whole pixels of 3
    (10, 10, 5, 16, 16385, 16400, 16400),      # MIN_PASS_SAMPLES up to whole pixels of 5
    (10, 10, 5, 2, 16385, 16400, 16400),
]


@pytest.mark.parametrize(("width", "height", "spp", "threads", "expected", "bands8", "bands16"),
                         PASS_SIZES)
@pytest.mark.parametrize("packets", [False, True], ids=["plain", "packets"])
def test_pass_size_cuts_the_image_for_its_threads(monkeypatch, width, height, spp, threads,
                                                  expected, bands8, bands16, packets):
    """A pass is at most ``pass_samples``, an even cut of a small image into 16 passes, or 2
    a thread where that is fewer, whole pixels; with camera rays in packets of pixel blocks
    (a scene with meshes), whole bands of blocks, so that no pass cuts one
    (``WhittedIntegrator.pass_size``, ``integrator.frame_passes``), rounded up so that the
    cut leaves no pass over where that stays within ``pass_samples``."""
    monkeypatch.setattr(WhittedIntegrator, "coherent_camera", packets)
    made = WhittedIntegrator(scene(), RenderOptions(width=width, height=height, spp=spp,
                                                    max_depth=2, threads=threads))
    want = expected if not packets else bands16 if made.lanes == 16 else bands8
    assert made.pass_size == want
    assert want % spp == 0


@pytest.mark.parametrize(("samples", "threads", "passes"), [
    (307200, 16, 16), (307200, 8, 16),  # 160×120 at 16 spp: 16 passes from 8 threads up…
    (307200, 4, 8), (307200, 2, 6),     # …2 a thread, or the fewest of at most 65 536 (5),
    (307200, 3, 6), (307200, 1, 5),     # rounded up to a multiple of the threads
    (76800, 2, 4), (76800, 1, 2),       # 160×120 at 4: 2 a thread
])
def test_frame_passes_are_two_a_thread_up_to_sixteen(samples, threads, passes):
    assert frame_passes(samples, threads, 65536) == passes


def test_threads_default_to_every_core_and_an_explicit_count_is_kept():
    import os

    small = raytrace.Scene(camera=raytrace.Camera(), objects=[], lights=[])
    with pytest.warns(raytrace.errors.RenderWarning, match="no objects"):
        assert raytrace.render(small, width=4, height=3).stats["threads"] == (
            os.cpu_count() or 1)
    with pytest.warns(raytrace.errors.RenderWarning, match="no objects"):
        assert raytrace.render(small, width=4, height=3, threads=3).stats["threads"] == 3
    with pytest.raises(raytrace.SceneError, match="threads"):
        raytrace.render(small, width=4, height=3, threads=0)


@pytest.mark.parametrize("threads", [1, 2])
def test_progress_reports_every_pass_once_in_increasing_order(threads):
    # 48×36 = 1728 samples in passes of 97 (the last one 79), or of 96 where camera rays go
    # in blocks of 2 rows: the callback sees the running total after each pass, one call at
    # a time, ending exactly at the total.
    size = WhittedIntegrator(scene(), RenderOptions(width=W, height=H, threads=threads,
                                                    pass_samples=SMALL_PASS)).pass_size
    assert size in (SMALL_PASS, 2 * W)  # 97, or whole bands of 2-row camera-ray blocks
    calls = []
    raytrace.render(scene(), width=W, height=H, threads=threads, pass_samples=SMALL_PASS,
                    progress=lambda done, total: calls.append((done, total)))
    assert len(calls) == -(-W * H // size)
    assert all(total == W * H for _, total in calls)
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == W * H
    steps = np.diff([0, *done])
    assert set(steps.tolist()) <= {size, W * H % size} - {0}


def test_kept_camera_columns_are_never_written_to(monkeypatch):
    # Each thread keeps the constant columns of its camera batches (origin 0, sample index
    # within the pass, weight 1, no start shape, kind CAMERA) for all its passes and writes
    # only the directions anew: right only while no step of the render writes into a batch it
    # was handed. After renders with every kind of ray (and a background for the misses) the
    # kept columns must still hold their constants, and a second render must give the same
    # image. (The passes run on worker threads, so the columns are caught as they are made.)
    made = []

    def kept(n: int):
        made.append(integrator_columns(n))
        return made[-1]

    integrator_columns = integrator.camera_columns
    monkeypatch.setattr(integrator, "camera_columns", kept)
    integ = WhittedIntegrator(scene(), RenderOptions(width=W, height=H, spp=2, max_depth=5,
                                                     background=0.2, threads=1,
                                                     pass_samples=SMALL_PASS))
    first_image = integ.render()
    first = first_image.rgb
    (cols,) = made  # one thread: one set of columns for all its passes
    n = len(cols.origin)
    assert n == integ.pass_size == 96  # 97 rounded down to whole pixels of 2 samples
    np.testing.assert_array_equal(cols.origin, np.zeros((n, 3)))
    np.testing.assert_array_equal(cols.weight, np.ones((n, 3)))
    np.testing.assert_array_equal(cols.sample, np.arange(n))
    assert np.all(cols.origin_shape == NO_SHAPE) and np.all(cols.kind == CAMERA)
    again = integ.render()
    np.testing.assert_array_equal(again.rgb, first)
    # ...and counts its rays from zero: W·H·2 camera rays, as many of each kind as the first.
    assert first_image.stats["rays"]["camera"] == W * H * 2
    assert again.stats["rays"] == first_image.stats["rays"]
    assert again.stats["pruned"] == first_image.stats["pruned"]


@pytest.mark.parametrize("threads", [1, 2])
def test_a_second_render_of_one_integrator_counts_from_zero(threads):
    # The counters live per thread; the calling thread's outlive a render. Each render must
    # still report its own rays only: W·H camera rays, not the sum over renders.
    integ = WhittedIntegrator(scene(), RenderOptions(width=W, height=H, max_depth=3,
                                                     threads=threads))
    first, second = integ.render().stats, integ.render().stats
    assert first["rays"]["camera"] == second["rays"]["camera"] == W * H
    assert first["rays"] == second["rays"]
    assert first["total_internal_reflections"] == second["total_internal_reflections"]
