"""Embree called directly (raytrace/embree.py, raytrace/kernels/embree.py): the same hits as
embreex's own ``run`` on the same scene and rays, arrays owned by the scene, and every check
that keeps a wrong library from crashing a user's process ends in one line."""

from __future__ import annotations

import gc
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raytrace
from raytrace import accel, cli, embree
from raytrace.errors import EngineError
from raytrace.integrator import RenderOptions, WhittedIntegrator
from raytrace.kernels import embree as ek
from raytrace.kernels.records import EmbreeHits, EmbreeRays
from raytrace.tables import scene_arrays

ROOT = Path(__file__).resolve().parents[1]


def mesh_arrays(seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two meshes: a sphere of 1280 triangles and a bumpy plane, float64 vertices."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    rng = np.random.default_rng(seed)
    xs = np.linspace(-3, 3, 9)
    grid = np.array([[x, -1.2 + 0.1 * rng.standard_normal(), z] for z in xs for x in xs])
    faces = [[i * 9 + j, i * 9 + j + 1, (i + 1) * 9 + j] for i in range(8) for j in range(8)]
    faces += [[i * 9 + j + 1, (i + 1) * 9 + j + 1, (i + 1) * 9 + j]
              for i in range(8) for j in range(8)]
    return [(np.asarray(sphere.vertices, np.float64), np.asarray(sphere.faces, np.int64)),
            (grid, np.asarray(faces, np.int64))]


def random_rays(n: int, seed: int = 1) -> EmbreeRays:
    rng = np.random.default_rng(seed)
    origin = rng.uniform(-4, 4, (n, 3)).astype(np.float32)
    target = rng.uniform(-1.5, 1.5, (n, 3))
    d = target - origin
    direction = (d / np.linalg.norm(d, axis=1)[:, None]).astype(np.float32)
    far = np.where(rng.random(n) < 0.2, rng.uniform(0.5, 5, n),
                   np.finfo(np.float32).max).astype(np.float32)
    return EmbreeRays(origin, direction, far)


def embreex_answers(meshes, rays: EmbreeRays):
    """embreex's own closest hits and occlusion flags of the same rays."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene(robust=True)
    for v, f in meshes:
        TriangleMesh(scene, v, f)
    closest = scene.run(rays.origin, rays.direction, dists=rays.far.copy(), output=1)
    blocked = scene.run(rays.origin, rays.direction, dists=rays.far.copy(), query="OCCLUDED")
    return closest, blocked


@pytest.mark.parametrize("coherent", [False, True])
def test_hits_are_embreexs(coherent):
    """Closest hits (geomID, primID, u, v) and occlusion of 4000 random rays, some bounded,
    match embreex's single rays; ties on shared edges aside, the packet form may only differ
    where two triangles are hit at the same distance."""
    meshes = mesh_arrays()
    rays = random_rays(4000)
    scene = embree.Meshes(meshes, threads=2)
    n = len(rays.far)
    hits = EmbreeHits(np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.float32),
                      np.empty(n, np.float32))
    packets = np.append(np.arange(0, n, scene.record.width), n) if coherent else ek.PLAIN
    ek.closest_hits(scene.record, rays, packets, hits)
    blocked = np.empty(n, np.int32)
    ek.any_hits(scene.record, rays, coherent, blocked)
    closest, occluded = embreex_answers(meshes, rays)
    assert 1000 < (closest["geomID"] >= 0).sum() < n - 100  # both hits and misses
    assert np.array_equal(hits.geom_id, closest["geomID"])
    hit = closest["geomID"] >= 0  # primID, u and v are only an answer where a ray hits
    assert np.array_equal(hits.prim_id[hit], closest["primID"][hit])
    assert np.array_equal(hits.u[hit], closest["u"][hit])
    assert np.array_equal(hits.v[hit], closest["v"][hit])
    assert np.array_equal(blocked == ek.BLOCKED, occluded == 0)


def test_scene_owns_its_arrays():
    """Embree reads the vertex and index arrays in place: the scene keeps its own copies, so
    the caller's arrays may go (and be overwritten) without changing a hit."""
    meshes = mesh_arrays()
    rays = random_rays(500)
    scene = embree.Meshes([(v.copy(), f.copy()) for v, f in meshes])
    gc.collect()
    junk = [np.full((len(v), 3), np.nan) for v, _ in meshes]  # reuse the freed memory
    n = len(rays.far)
    hits = EmbreeHits(np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.float32),
                      np.empty(n, np.float32))
    ek.closest_hits(scene.record, rays, ek.PLAIN, hits)
    closest, _ = embreex_answers(meshes, rays)
    assert np.array_equal(hits.geom_id, closest["geomID"]) and len(junk) == 2
    hit = closest["geomID"] >= 0
    assert np.array_equal(hits.prim_id[hit], closest["primID"][hit])


@pytest.fixture
def fresh_library(monkeypatch):
    """The library is loaded and checked again by the test (and again after it)."""
    monkeypatch.setattr(embree, "_library", None)
    yield
    embree._library = None


def mesh_scene() -> raytrace.Scene:
    v, f = mesh_arrays()[0]
    return raytrace.Scene(objects=[raytrace.Mesh(vertices=v, faces=f)],
                          camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]))


def test_unchecked_version_is_one_line(fresh_library, monkeypatch):
    """An Embree whose layouts were not checked is refused before any traversal, naming the
    embreex release that works."""
    monkeypatch.setattr(embree, "CHECKED_VERSIONS", range(40500, 40600))
    with pytest.raises(EngineError) as e:
        raytrace.render(mesh_scene(), width=8, height=6, threads=1)
    message = str(e.value)
    assert "ships Embree 4.4.0" in message and "checked against that only" in message
    assert "install embreex 4.4.0.post1 (pip install 'embreex>=4.4,<4.5')" in message
    assert "\n" not in message


def test_cli_says_it_in_one_line(fresh_library, monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(embree, "CHECKED_VERSIONS", range(30000, 30100))
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\n'
                     '[[objects]]\ntype = "mesh"\nfile = "m.obj"\n')
    trimesh.creation.box().export(tmp_path / "m.obj")
    status = cli.main(["render", str(scene), "-o", str(tmp_path / "out.exr"),
                       "--width", "8", "--height", "6", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == cli.EXIT_ENGINE == 3
    assert len(err) == 1 and err[0].startswith("raytrace: error: embreex ")
    assert "install embreex 4.4.0.post1" in err[0]
    assert not (tmp_path / "out.exr").exists()


def test_layout_probe_catches_another_layout(fresh_library, monkeypatch):
    """A known ray whose answer is not read back as expected (here: every comparison fails,
    as where Embree writes elsewhere) is refused in one line. The kernels' layout constants
    are not patched: numba would compile them into its cache."""
    monkeypatch.setattr(embree, "near", lambda value, expected: False)
    with pytest.raises(EngineError, match="did not answer a known ray as raytrace reads"):
        embree.library()


def test_out_of_memory_is_one_line(monkeypatch):
    """Embree's memory monitor refuses a build beyond the memory available; the build ends
    with one line, and a build within it reports its bytes."""
    monkeypatch.setattr(embree, "available_bytes", lambda: 1000)
    with pytest.raises(EngineError, match=r"failed building the BVH: out of memory"):
        embree.Meshes(mesh_arrays())
    monkeypatch.undo()
    scene = embree.Meshes(mesh_arrays())
    assert scene.bytes > 1000


def test_device_per_thread_count():
    """Each --threads gets its own device (Embree builds on that many threads)."""
    lib = embree.library()
    assert embree.Meshes(mesh_arrays(), threads=1).device.threads == 1
    assert embree.Meshes(mesh_arrays(), threads=3).device is lib.device(3)
    assert lib.device(3) is not lib.device(1)


def test_a_library_that_does_not_load_is_one_line(fresh_library, monkeypatch, tmp_path):
    """A file that is no loadable library (a broken or foreign wheel) is an EngineError
    naming the embreex that works, not an OSError (the command line's exit 2)."""
    fake = tmp_path / "libembree4.so.4"
    fake.write_text("not a library")
    monkeypatch.setattr(embree, "library_path", lambda: fake)
    with pytest.raises(EngineError, match=r"cannot be used .*install embreex 4\.4\.0\.post1"):
        embree.library()


def test_the_memory_limit_is_each_build_s_own(monkeypatch):
    """A build is measured against the memory available by what it allocates itself, not by
    what the device's earlier scenes hold (those are already out of the available memory)."""
    first = embree.Meshes(mesh_arrays(), threads=2)
    assert first.device.bytes >= first.bytes > 0
    monkeypatch.setattr(embree, "available_bytes", lambda: first.bytes * 2)
    second = embree.Meshes(mesh_arrays(), threads=2)  # the device holds first's bytes too
    assert second.bytes > 0 and second.device.bytes >= first.bytes + second.bytes


def test_coherent_packets_answer_ties_as_single_rays(monkeypatch):
    """Camera rays go in COHERENT packets, whose traversal order picks among triangles hit at
    the same distance. The Cornell box's camera rays at 64×48 include rays through the exact
    corners where two walls' triangles meet: the packet's order gives 8 of them another wall
    (0.53 in a channel), so the hits near an edge are traced again without the flag, and
    every answer is the plain packet's, which is the single ray's."""
    batches = []
    monkeypatch.setattr(accel.Accelerator, "recorder",
                        staticmethod(lambda *batch: batches.append(batch)))
    monkeypatch.setattr(WhittedIntegrator, "compiled", False)  # the recorder's loop
    scene = raytrace.load_scene(ROOT / "scenes" / "cornell_box.toml")
    raytrace.render(scene, width=64, height=48, threads=1)
    query, origin, direction, far = batches[0]  # the one pass's camera rays, block by block
    assert query == "INTERSECT" and len(far) == 64 * 48
    meshes = embree.Meshes(scene_arrays(scene).meshes)
    answers = []
    n = len(far)
    for packets in (ek.PLAIN, np.arange(0, n + 1, meshes.record.width)):
        hits = EmbreeHits(np.empty(n, np.int32), np.empty(n, np.int32),
                          np.empty(n, np.float32), np.empty(n, np.float32))
        ek.closest_hits(meshes.record, EmbreeRays(origin, direction, far.copy()), packets,
                        hits)
        answers.append(hits)
    plain, coherent = answers
    hit = plain.geom_id >= 0
    assert hit.sum() > n // 2
    assert np.array_equal(coherent.geom_id, plain.geom_id)
    assert np.array_equal(coherent.prim_id[hit], plain.prim_id[hit])


@pytest.mark.parametrize("compiled", [False, True], ids=["python-loop", "compiled-loop"])
def test_coherent_camera_rays_render_the_same_image(monkeypatch, compiled):
    """Camera rays in COHERENT packets of pixel blocks, ties near an edge traced again,
    render the Cornell box, whose corner rays tie, bit for bit as plain packets
    (``RAYTRACE_COHERENT_CAMERA=0``) do, in both loops."""
    monkeypatch.setattr(WhittedIntegrator, "compiled", compiled)
    scene = raytrace.load_scene(ROOT / "scenes" / "cornell_box.toml")
    coherent = raytrace.render(scene, width=64, height=48, threads=2).rgb
    monkeypatch.setattr(WhittedIntegrator, "coherent_camera", False)
    plain = raytrace.render(scene, width=64, height=48, threads=2).rgb
    assert np.array_equal(coherent, plain)


def overlapping_grids() -> raytrace.Scene:
    """Two grids of 8 × 8 quads in the plane y = 0, one shifted by (0.11, 0, 0.07) over the
    other, of two materials: every ray that meets them meets both at the same distance, and
    which one a pixel shows is the traversal's choice (z-fighting)."""
    xs = np.linspace(-1, 1, 9)
    vertices = np.array([[x, 0.0, z] for z in xs for x in xs])
    faces = []
    for i in range(8):
        for j in range(8):
            a, b, c, d = i * 9 + j, i * 9 + j + 1, (i + 1) * 9 + j, (i + 1) * 9 + j + 1
            faces += [[a, c, b], [b, c, d]]
    grids = [raytrace.Mesh(vertices=vertices + shift, faces=faces,
                           material=raytrace.Material(kd=kd, ka=0.3))
             for shift, kd in (((0, 0, 0), 0.3), ((0.11, 0, 0.07), 0.7))]
    return raytrace.Scene(camera=raytrace.Camera([0.3, 2.2, 1.0], [0, 0, 0], fov=50),
                          objects=grids, lights=[raytrace.PointLight([0.5, 4.0, 0.3], 2.0)],
                          ambient=0.1, render=raytrace.RenderSettings(background=0.0))


@pytest.mark.parametrize("compiled", [False, True], ids=["python-loop", "compiled-loop"])
def test_coherent_camera_rays_keep_crops_and_passes_bit_identical(monkeypatch, compiled):
    """Where triangles overlap in one plane, a COHERENT packet's answer depends on its other
    rays, and no guard sees it: the packets are blocks of the frame
    (:func:`raytrace.kernels.camera.frame_packets`), traced whole, so a crop, a pass size
    or a thread count gives the full frame's pixels bit for bit. The packets' choice is
    not plain packets' (which answer as single rays): 586 of the 1728 pixels pick the other
    grid there, by up to 0.8 in a channel."""
    monkeypatch.setattr(WhittedIntegrator, "compiled", compiled)
    scene = overlapping_grids()
    full = raytrace.render(scene, width=48, height=36, threads=1).rgb
    with monkeypatch.context() as plain_packets:
        plain_packets.setattr(WhittedIntegrator, "coherent_camera", False)
        plain = raytrace.render(scene, width=48, height=36, threads=1).rgb
    assert (np.abs(plain - full).max(-1) > 0.1).sum() > 100  # the packets decide ties
    for crop in ((1, 1, 47, 35), (3, 2, 20, 17), (10, 5, 31, 25), (2, 0, 48, 36)):
        x0, y0, x1, y1 = crop
        part = raytrace.render(scene, width=48, height=36, threads=1, crop=crop).rgb
        assert np.array_equal(part, full[y0:y1, x0:x1]), crop
    for pass_samples, threads in ((64, 1), (100, 2), (333, 2)):
        other = raytrace.render(scene, width=48, height=36, threads=threads,
                                pass_samples=pass_samples).rgb
        assert np.array_equal(other, full), pass_samples


@pytest.mark.parametrize("compiled", [False, True], ids=["python-loop", "compiled-loop"])
def test_noise_driven_rounds_keep_passes_and_crops_bit_identical(monkeypatch, compiled):
    """A noise-driven round's camera rays go in COHERENT packets of one pixel's samples each
    (:func:`raytrace.kernels.camera.pixel_packets`), and a round's passes are cut at pixel
    bounds, so where triangles overlap in one plane a pass size, a thread count or a crop
    still gives the full render's pixels bit for bit, though the packets' choice is not
    plain packets'."""
    monkeypatch.setattr(WhittedIntegrator, "compiled", compiled)
    scene = overlapping_grids()
    common = dict(width=48, height=36, aa="noise", min_spp=8, max_spp=32, noise_threshold=0.05)
    full = raytrace.render(scene, threads=1, **common).rgb
    with monkeypatch.context() as plain_packets:
        plain_packets.setattr(WhittedIntegrator, "coherent_camera", False)
        plain = raytrace.render(scene, threads=1, **common).rgb
    assert (np.abs(plain - full).max(-1) > 0.05).sum() > 50  # the packets decide ties
    for pass_samples, threads in ((64, 1), (100, 2), (333, 2)):
        other = raytrace.render(scene, threads=threads, pass_samples=pass_samples,
                                **common).rgb
        assert np.array_equal(other, full), pass_samples
    x0, y0, x1, y1 = crop = (3, 2, 30, 27)
    part = raytrace.render(scene, threads=2, crop=crop, **common).rgb
    assert np.array_equal(part, full[y0:y1, x0:x1])


def test_points_in_pixel_packets_must_run_from_the_first_to_the_last():
    """``trace_points``' pixel bounds are read by kernels that check no index: bounds that do
    not run from 0 to the points' count are refused before any is traced."""
    integ = WhittedIntegrator(overlapping_grids(), RenderOptions(width=8, height=6))
    assert integ.lanes  # a scene with meshes: its camera rays go in packets
    x, y, ids = np.full(4, 4.0), np.full(4, 3.0), np.arange(4)
    for bounds in ([0, 5], [1, 4], [0, 2, 3]):
        with pytest.raises(ValueError, match="from 0 to 4"):
            integ.trace_points(x, y, ids, np.array(bounds))
    assert np.isfinite(integ.trace_points(x, y, ids, np.array([0, 2, 4]))).all()


def test_a_frame_s_passes_trace_each_camera_ray_once(monkeypatch):
    """A pass is rounded down to whole bands of the blocks camera rays go in
    (``WhittedIntegrator.pass_size``), so no pass cuts a block and the camera rays Embree
    traces are the frame's, each once: at 40×30 with ``pass_samples`` 500 (12.5 rows), passes
    of 12 rows. (Unlit, so every closest-hit query is one of camera rays.)"""
    batches = []
    monkeypatch.setattr(accel.Accelerator, "recorder",
                        staticmethod(lambda *batch: batches.append(batch)))
    monkeypatch.setattr(WhittedIntegrator, "compiled", False)  # the recorder's loop
    scene = overlapping_grids()
    scene.lights = []
    raytrace.render(scene, width=40, height=30, threads=1, pass_samples=500)
    assert {query for query, *_ in batches} == {"INTERSECT"}
    assert sum(len(far) for *_, far in batches) == 40 * 30
    assert len(batches) == 3  # 12, 12 and 6 rows
