"""Tiles and frames on a Dask cluster (raytrace.distributed, raytrace.frames on a client).

Real local clusters (raytrace.distributed.local_cluster: worker processes on 127.0.0.1, one
thread each) of 1, 2 and 3 workers, one at a time: every tiled image must be bit-identical to
the render on one process, whatever the workers or the tile size; a worker killed in the middle
of a render must not change a bit; a scene error raised on a worker is the local one-line
error. The clusters are small and shared by the tests (the file runs in about a minute on two
cores, on one xdist worker: the ``dask`` group).
"""

from __future__ import annotations

import os
import pickle
import re
import shutil
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

import raytrace
from raytrace import cli
from raytrace import distributed as rd
from raytrace.errors import ClusterError

pytest.importorskip("distributed")

pytestmark = [pytest.mark.xdist_group("dask"), pytest.mark.timeout(180)]

ROOT = Path(__file__).resolve().parents[1]
W, H = 64, 48
#: Two tile sides: one dividing the frame, one leaving cut tiles at the right and bottom.
TILES = (16, 40)


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(
        a.view(np.uint8), b.view(np.uint8))


class Clusters:
    """At most one local cluster alive at a time (two cores are shared), started on demand
    and closed by the fixture's teardown whatever the tests did."""

    def __init__(self):
        self.n, self.cluster, self.client = 0, None, None

    def get(self, n: int | None = None):
        from distributed import Client

        if self.client is None or (n is not None and n != self.n):
            self.close()
            self.cluster = rd.local_cluster(n or 3)
            self.client = Client(self.cluster, set_as_default=False)
            self.n = n or 3
        return self.client

    def close(self) -> None:
        if self.client is not None:
            self.client.close(timeout=30)
            self.cluster.close(timeout=30)
        self.client = self.cluster = None


@pytest.fixture(scope="module")
def clusters():
    c = Clusters()
    try:
        yield c
    finally:
        c.close()


@pytest.fixture(scope="module")
def mesh_scene(tmp_path_factory) -> raytrace.Scene:
    """scenes/mesh_model.toml read from a copy whose PLY file is then deleted: the workers
    can only get the triangles from the pickled scene."""
    folder = tmp_path_factory.mktemp("mesh")
    shutil.copy(ROOT / "scenes" / "mesh_model.toml", folder)
    shutil.copytree(ROOT / "scenes" / "models", folder / "models")
    scene = raytrace.load_scene(folder / "mesh_model.toml")
    shutil.rmtree(folder / "models")
    return scene


@pytest.fixture(scope="module")
def scenes(mesh_scene) -> dict:
    """name → (scene, render keywords, the reference: one process, one thread)."""
    whitted = raytrace.load_scene(ROOT / "scenes" / "whitted.toml")
    cases = {"whitted": (whitted, {"width": W, "height": H, "spp": 4,
                                   "aovs": ["depth", "normal", "albedo", "id"]}),
             "mesh": (mesh_scene, {"width": W, "height": H})}
    return {name: (s, kw, raytrace.render(s, threads=1, **kw)) for name, (s, kw) in cases.items()}


@pytest.mark.parametrize("n", [1, 2, 3])
def test_tiles_are_bit_identical_to_one_process(clusters, scenes, n):
    client = clusters.get(n)
    workers = set(client.scheduler_info()["workers"])
    assert len(workers) == n and all(w.startswith("tls://127.0.0.1:") for w in workers)
    for name, (scene, kw, reference) in scenes.items():
        builds = 0
        for tile in TILES:
            calls = []
            image = raytrace.render(scene, client=client, tile=tile,
                                    progress=lambda done, total, calls=calls: calls.append(
                                        (done, total)), **kw)
            assert same_bits(image.rgb, reference.rgb), (name, n, tile)
            for aov in kw.get("aovs", ()):
                assert same_bits(image.aov(aov), reference.aov(aov)), (name, aov, tile)
            assert image.stats["rays"] == reference.stats["rays"]
            assert image.stats["pruned"] == reference.stats["pruned"]
            grid = rd.tile_grid((0, 0, W, H), tile)
            d = image.stats["distributed"]
            assert d["tiles"] == len(grid) == sum(w["tiles"] for w in d["workers"].values())
            assert set(d["workers"]) <= workers
            assert sum(w["rays"] for w in d["workers"].values()) == reference.stats["rays"][
                "total"]
            total = W * H * kw.get("spp", 1)
            assert len(calls) == len(grid) and calls[-1] == (total, total)
            assert all(a[0] < b[0] for a, b in zip(calls, calls[1:], strict=False))
            builds += sum(w["builds"] for w in d["workers"].values())
        # One BVH build per worker at most, for both tile sizes' 16 tiles: the integrator is
        # kept by the scene's digest, whatever the window.
        assert 1 <= builds <= n, (name, builds)


def test_a_crop_is_tiled_too(clusters, scenes):
    scene, kw, reference = scenes["whitted"]
    image = raytrace.render(scene, client=clusters.get(), tile=8, crop=(5, 7, 45, 30), **kw)
    assert same_bits(image.rgb, reference.rgb[7:30, 5:45])
    assert image.crop == (5, 7, 45, 30) and image.frame == (W, H)
    assert image.stats["distributed"]["tiles"] == 5 * 3
    assert image.stats["rays"]["camera"] == 40 * 23 * 4


@contextmanager
def killing_first_tile(client, marker: Path):
    """Every worker's integrator lookup wrapped: the first tile anywhere (the marker file is
    created exclusively) writes its process id and kills its own worker process (SIGKILL,
    in the middle of the render)."""

    def install(marker=str(marker)):
        import os
        import signal

        import raytrace.distributed as d

        original = d.cached_integrator

        def killing(*args, **kwargs):
            try:
                fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                return original(*args, **kwargs)
            os.write(fd, str(os.getpid()).encode())
            os.close(fd)
            os.kill(os.getpid(), signal.SIGKILL)

        killing.original = original
        d.cached_integrator = killing

    def uninstall():
        import raytrace.distributed as d

        d.cached_integrator = getattr(d.cached_integrator, "original", d.cached_integrator)

    client.run(install)
    try:
        yield
    finally:
        client.run(uninstall)


def test_a_killed_worker_s_tiles_run_elsewhere_and_the_image_is_unchanged(clusters, scenes,
                                                                          tmp_path):
    client = clusters.get()
    scene, kw, reference = scenes["whitted"]
    marker = tmp_path / "killed.pid"
    before = client.run(os.getpid)
    with killing_first_tile(client, marker):
        image = raytrace.render(scene, client=client, tile=16, **kw)
    pid = int(marker.read_text())
    assert pid in before.values()
    with pytest.raises(ProcessLookupError):  # it really died
        os.kill(pid, 0)
    victim = next(w for w, p in before.items() if p == pid)
    d = image.stats["distributed"]
    assert victim not in d["workers"]  # its tile came back from another worker
    assert d["tiles"] == 12 and sum(w["tiles"] for w in d["workers"].values()) == 12
    assert same_bits(image.rgb, reference.rgb)
    for aov in kw["aovs"]:
        assert same_bits(image.aov(aov), reference.aov(aov))


def slow_tiles(seconds: float = 0.5) -> None:
    """On a worker: each tile's integrator lookup takes ``seconds`` more (client.run)."""
    import time

    import raytrace.distributed as d

    original = d.cached_integrator

    def slow(*args, **kwargs):
        time.sleep(seconds)
        return original(*args, **kwargs)

    d.cached_integrator = slow


def test_a_cluster_left_without_workers_stops_the_render_in_one_line(clusters, scenes):
    # The cluster's one worker is closed once the first tile is back; with nobody to run the
    # other 47, Dask would wait for ever: the render ends worker_timeout seconds later.
    scene, kw, _ = scenes["whitted"]
    client = clusters.get(1)
    closed = []

    def progress(done: int, total: int) -> None:
        if not closed:
            clusters.cluster.scale(0)
            closed.append(time.monotonic())

    try:
        client.run(slow_tiles)
        with pytest.raises(ClusterError, match=r"^the Dask cluster at tls://127\.0\.0\.1:\d+ "
                           r"has had no worker for 1\.5 s, so the render stopped \(.*"
                           r"--worker-timeout or worker_timeout= waits longer\)$"):
            raytrace.render(scene, client=client, tile=8, worker_timeout=1.5,
                            progress=progress, **kw)
        waited = time.monotonic() - closed[0]
        assert 1.5 <= waited < 30, waited
    finally:
        clusters.close()  # (its worker is gone: the next test starts a new cluster)
    with pytest.raises(raytrace.SceneError, match="^worker_timeout: must be > 0"):
        rd.check_worker_timeout(-1)
    assert rd.check_worker_timeout(None) == rd.WORKER_TIMEOUT == 60


def test_a_scene_error_on_a_worker_is_the_local_error(clusters, scenes, tmp_path):
    client = clusters.get()
    scene, kw, _ = scenes["mesh"]

    def failing():
        import raytrace.distributed as d
        from raytrace.errors import SceneError

        def fail(*args, **kwargs):
            raise SceneError("must be > 0, got -1", "objects[1].scale", "shot.toml")

        fail.original = d.cached_integrator
        d.cached_integrator = fail

    def restore():
        import raytrace.distributed as d

        d.cached_integrator = d.cached_integrator.original

    client.run(failing)
    try:
        with pytest.raises(raytrace.SceneError) as e:
            raytrace.render(scene, client=client, tile=16, **kw)
    finally:
        client.run(restore)
    assert (e.value.problem, e.value.key, e.value.file) == (
        "must be > 0, got -1", "objects[1].scale", "shot.toml")
    assert e.value.__suppress_context__ and e.value.__cause__ is None


def orbit(frame: int) -> raytrace.Scene:
    """A camera path around two spheres; frame 2's sphere has a negative radius when asked."""
    angle = 0.4 * frame
    return raytrace.Scene(
        camera=raytrace.Camera(position=[5 * np.sin(angle), 1.5, 5 * np.cos(angle)],
                               look_at=[0, 0.5, 0]),
        objects=[raytrace.Sphere([0, 0.5, 0], 0.5 + 0.1 * frame, material="brass"),
                 raytrace.Plane([0, 0, 0], [0, 1, 0], material="matte_white")],
        lights=[raytrace.PointLight([3, 5, 4])], ambient=0.1,
        render=raytrace.RenderSettings(width=24, height=16))


def test_frames_on_a_cluster_resume(clusters, tmp_path):
    client = clusters.get()
    out = str(tmp_path / "out.####.exr")

    def scene_at(frame):  # a local function: it travels by value
        return orbit(frame)

    first = raytrace.render_frames(scene_at, out, "1-3", client=client)
    assert sorted(first.rendered) == [1, 2, 3] and first.skipped == []
    for f in (1, 2, 3):
        back = raytrace.read_exr(tmp_path / f"out.{f:04d}.exr")[0]
        assert same_bits(back, raytrace.render(orbit(f), threads=1).rgb)
    (tmp_path / "out.0002.exr").unlink()
    kept = {f: (tmp_path / f"out.{f:04d}.exr").stat().st_mtime_ns for f in (1, 3)}
    again = raytrace.render_frames(scene_at, out, "1-4", client=client)
    assert sorted(again.rendered) == [2, 4] and again.skipped == [1, 3]
    assert kept == {f: (tmp_path / f"out.{f:04d}.exr").stat().st_mtime_ns for f in (1, 3)}
    assert sorted(os.listdir(tmp_path)) == [f"out.{f:04d}.exr" for f in (1, 2, 3, 4)]


def test_a_frame_function_s_error_on_a_worker_is_one_line_as_locally(clusters, tmp_path,
                                                                    monkeypatch, capsys):
    anim = tmp_path / "anim.py"
    anim.write_text("import raytrace\n\n"
                    "def scene_at(frame):\n"
                    "    return raytrace.Scene(objects=[raytrace.Sphere([0, 0, 0], 2 - frame)],"
                    " render=raytrace.RenderSettings(width=8, height=6))\n")
    client = clusters.get()

    @contextmanager
    def the_test_cluster(**kwargs):
        yield client

    lines = {}
    for where in ("local", "cluster"):
        folder = tmp_path / where
        folder.mkdir()
        args = ["render", f"{anim}:scene_at", "--frames", "1-3", "-o",
                str(folder / "f.####.exr"), "-q"]
        if where == "cluster":
            monkeypatch.setattr(rd, "connect", the_test_cluster)
            args += ["--scheduler", "tcp://127.0.0.1:1"]  # connect() yields the test's
        assert cli.main(args) == 2
        lines[where] = capsys.readouterr().err
        # Frame 1 may be written (complete) before frame 2 fails: nothing else is, and the
        # line says whether it was.
        assert set(os.listdir(folder)) <= {"f.0001.exr"}
        written = (" (written before it: frame 1, complete; a rerun without --overwrite skips "
                   "it)" if os.listdir(folder) else "")
        assert lines[where] == (f"raytrace: error: {anim}:scene_at(2): radius: must be > 0, "
                                f"got 0{written}\n")


def test_frames_on_a_cluster_keep_the_memory_ceiling_on_the_client(clusters, tmp_path):
    # 1 MiB is less than this process holds: the client stops at the first frame back, with
    # its own line. Sent to the workers, it refused each frame's peak estimate instead.
    client = clusters.get()

    def scene_at(frame):
        return orbit(frame)

    with pytest.raises(raytrace.errors.MemoryLimitError) as e:
        raytrace.render_frames(scene_at, str(tmp_path / "out.####.exr"), "1-2", client=client,
                               max_memory="1M")
    assert re.fullmatch(r"max_memory: the render reached \d+\.\d [MG]iB and was stopped, over "
                        r"the memory ceiling of 1\.0 MiB; give a larger size to raise it",
                        str(e.value)), str(e.value)
    assert os.listdir(tmp_path) == []


def test_frames_on_a_cluster_left_without_workers_stop_after_the_worker_timeout(
        clusters, tmp_path, monkeypatch, capsys):
    client = clusters.get(1)
    anim = tmp_path / "anim.py"
    anim.write_text("import raytrace\n\n"
                    "def scene_at(frame):\n"
                    "    return raytrace.Scene(\n"
                    "        render=raytrace.RenderSettings(width=8, height=6))\n")

    @contextmanager
    def the_test_cluster(**kwargs):
        yield client

    monkeypatch.setattr(rd, "connect", the_test_cluster)
    try:
        clusters.cluster.scale(0)
        deadline = time.monotonic() + 60
        while client.nthreads() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not client.nthreads()
        t0 = time.monotonic()
        assert cli.main(["render", f"{anim}:scene_at", "--frames", "1-2", "-o",
                         str(tmp_path / "f.####.exr"), "-q", "--scheduler", "tcp://127.0.0.1:1",
                         "--worker-timeout", "1.5"]) == 2
        waited = time.monotonic() - t0
        assert re.fullmatch(r"raytrace: error: the Dask cluster at tls://127\.0\.0\.1:\d+ has "
                            r"had no worker for 1\.5 s, so the render stopped \(its workers' "
                            r"logs say why they left; --worker-timeout or worker_timeout= waits "
                            r"longer\)\n", capsys.readouterr().err)
        assert 1.5 <= waited < 30, waited
        assert os.listdir(tmp_path) == ["anim.py"]
    finally:
        clusters.close()  # (its worker is gone: the next test starts a new cluster)


def test_the_workers_flag_renders_the_same_exr(tmp_path):
    scene = tmp_path / "whitted.toml"
    shutil.copy(ROOT / "scenes" / "whitted.toml", scene)
    common = [str(scene), "--width", "40", "--height", "30", "-q"]
    assert cli.main(["render", *common, "-o", str(tmp_path / "local.exr"),
                     "--stats", str(tmp_path / "local.json")]) == 0
    assert cli.main(["render", *common, "-o", str(tmp_path / "tiles.exr"), "--workers", "2",
                     "--tile", "16", "--stats", str(tmp_path / "tiles.json")]) == 0
    local, tiles = (raytrace.Image.from_exr(tmp_path / f"{n}.exr") for n in ("local", "tiles"))
    assert same_bits(tiles.rgb, local.rgb)
    import json

    a, b = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("local", "tiles"))
    assert b["rays"] == a["rays"]
    d = b["distributed"]
    assert d["tiles"] == 3 * 2 and 1 <= len(d["workers"]) <= 2
    assert all(w["seconds"] > 0 and w["tiles"] >= 1 for w in d["workers"].values())


@pytest.mark.parametrize(("args", "flag", "says"), [
    (["--workers", "0"], "--workers", "must be >= 1"),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--scheduler", "not both"),
    (["--workers", "2", "--tile", "4"], "--tile", ">= 8"),
    (["--tile", "16"], "--tile", "needs --workers or --scheduler"),
    (["--tls-cert", "c.pem"], "--tls-cert", "needs --workers or --scheduler"),
    (["--scheduler", "udp://h:1"], "--scheduler", "tcp://HOST:PORT"),
    (["--scheduler", "127.0.0.1"], "--scheduler", "missing port number"),
    (["--scheduler", "tcp://h:notaport"], "--scheduler", "tcp://HOST:PORT"),
    (["--frames", "1", "--workers", "1", "--tile", "16"], "--tile", "not used with --frames"),
    (["--frames", "1", "--png-bits", "16"], "--png-bits", "not used with --frames"),
    (["--scheduler", "tls://h:1"], "--scheduler", "needs --tls-ca-file, --tls-cert and"),
    (["--scheduler", "tls://h:1", "--tls-ca-file", "ca.pem", "--tls-cert", "c.pem"],
     "--tls-key", "missing"),
    (["--scheduler", "tls://h:1", "--tls-ca-file", "no.pem", "--tls-cert", "c.pem",
      "--tls-key", "k.pem"], "--tls-ca-file", "file not found"),
    (["--workers", "1", "--tls-ca-file", "ca.pem"], "--tls-ca-file", "for --scheduler"),
    (["--frames", "5-1"], "--frames", "ends before it starts"),
    (["--frames", "1-x"], "--frames", "not a frame list"),
    (["--overwrite"], "--overwrite", "is for --frames"),
    (["--worker-timeout", "5"], "--worker-timeout", "needs --workers or --scheduler"),
    (["--workers", "1", "--worker-timeout", "0"], "--worker-timeout", "must be > 0"),
    (["--frames", "1", "--workers", "1", "--worker-timeout", "0"], "--worker-timeout",
     "must be > 0"),
])
def test_bad_cluster_and_frame_flags_are_one_line_and_write_nothing(tmp_path, capsys,
                                                                    monkeypatch, args, flag,
                                                                    says):
    shutil.copy(ROOT / "scenes" / "whitted.toml", tmp_path / "s.toml")
    for name in ("ca.pem", "c.pem"):
        (tmp_path / name).write_text("not checked here\n")
    before = sorted(os.listdir(tmp_path))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["render", "s.toml", "-o", "o.exr", *args]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and f"{flag}: " in err and says in err, err
    assert sorted(os.listdir(tmp_path)) == before


def test_without_dask_the_cluster_flags_say_what_to_install(tmp_path, monkeypatch, capsys):
    shutil.copy(ROOT / "scenes" / "whitted.toml", tmp_path / "s.toml")
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed: ImportError
    assert cli.main(["render", str(tmp_path / "s.toml"), "-o", str(tmp_path / "o.exr"),
                     "--workers", "2"]) == 2
    assert capsys.readouterr().err == ("raytrace: error: --workers: needs Dask's distributed "
                                       "scheduler: pip install 'raytrace[distributed]'\n")
    assert os.listdir(tmp_path) == ["s.toml"]


@pytest.mark.parametrize(("out", "png"), [("o.exr", None), ("o.####.exr", "p.png")])
def test_frame_outputs_need_a_frame_number(tmp_path, capsys, out, png):
    shutil.copy(ROOT / "scenes" / "whitted.toml", tmp_path / "s_0001.toml")
    args = ["render", str(tmp_path / "s_####.toml"), "--frames", "1", "-o", str(tmp_path / out)]
    assert cli.main(args + (["--png", str(tmp_path / png)] if png else [])) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "needs one frame number" in err
    assert ("--png: " if png else "-o: ") in err
    assert os.listdir(tmp_path) == ["s_0001.toml"]


def test_the_tls_options_reach_the_client(tmp_path, monkeypatch, capsys):
    import distributed

    seen = {}

    class Refusing:
        def __init__(self, address=None, **kwargs):
            seen.update(kwargs, address=address)
            raise OSError(f"Timed out trying to connect to {address} after 20 s")

    files = {}
    for flag in ("--tls-ca-file", "--tls-cert", "--tls-key"):
        files[flag] = tmp_path / f"{flag.strip('-')}.pem"
        files[flag].write_text("-----BEGIN CERTIFICATE-----\n")
    shutil.copy(ROOT / "scenes" / "whitted.toml", tmp_path / "s.toml")
    monkeypatch.setattr(distributed, "Client", Refusing)
    rc = cli.main(["render", str(tmp_path / "s.toml"), "-o", str(tmp_path / "o.exr"),
                   "--scheduler", "tls://render-farm.example:8786",
                   *(str(x) for kv in files.items() for x in kv)])
    err = capsys.readouterr().err
    assert rc == 2 and err == ("raytrace: error: cannot reach the Dask scheduler at "
                               "tls://render-farm.example:8786: Timed out trying to connect to "
                               "tls://render-farm.example:8786 after 20 s\n")
    sec = seen["security"]
    assert seen["address"] == "tls://render-farm.example:8786"
    assert sec.require_encryption is True
    assert (sec.tls_ca_file, sec.tls_client_cert, sec.tls_client_key) == (
        str(files["--tls-ca-file"]), str(files["--tls-cert"]), str(files["--tls-key"]))
    assert seen["timeout"] == rd.CONNECT_TIMEOUT == 20
    assert not (tmp_path / "o.exr").exists()


def test_the_tls_flags_open_a_real_tls_connection_and_nothing_else_does(clusters, scenes,
                                                                       tmp_path, monkeypatch,
                                                                       capsys):
    """The local cluster's temporary certificates written to PEM files: with the three flags
    the command line renders on it over TLS; without a client certificate it is refused."""
    client = clusters.get()
    sec = clusters.cluster.security
    pem = {"--tls-ca-file": sec.tls_ca_file, "--tls-cert": sec.tls_client_cert,
           "--tls-key": sec.tls_client_key}
    flags = []
    for flag, text in pem.items():
        assert text.startswith("-----BEGIN")
        (tmp_path / f"{flag[2:]}.pem").write_text(text)
        flags += [flag, str(tmp_path / f"{flag[2:]}.pem")]
    shutil.copy(ROOT / "scenes" / "whitted.toml", tmp_path / "s.toml")
    address = client.scheduler.address
    assert address.startswith("tls://127.0.0.1:")
    common = ["render", str(tmp_path / "s.toml"), "--width", str(W), "--height", str(H),
              "--spp", "4", "--tile", "32", "--scheduler", address, "-q"]
    assert cli.main([*common, "-o", str(tmp_path / "tls.exr"), *flags]) == 0
    assert same_bits(raytrace.read_exr(tmp_path / "tls.exr")[0], scenes["whitted"][2].rgb)
    # Certificates of another authority (a stranger's) are refused, in one line.
    from distributed import Security

    other, stranger = Security.temporary(), []
    for flag, text in {"--tls-ca-file": other.tls_ca_file, "--tls-cert": other.tls_client_cert,
                       "--tls-key": other.tls_client_key}.items():
        (tmp_path / f"other-{flag[2:]}.pem").write_text(text)
        stranger += [flag, str(tmp_path / f"other-{flag[2:]}.pem")]
    monkeypatch.setattr(rd, "CONNECT_TIMEOUT", 3)
    assert cli.main([*common, "-o", str(tmp_path / "stranger.exr"), *stranger]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"raytrace: error: cannot reach the Dask scheduler at {address}: ")
    assert len(err.splitlines()) == 1 and not (tmp_path / "stranger.exr").exists()


def _connections(process) -> list:
    """A process's inet sockets; none for a process that ended since it was listed (a
    nanny's helper child can exit between ``children()`` and this call)."""
    import psutil

    try:
        return getattr(process, "net_connections", process.connections)(kind="inet")
    except psutil.NoSuchProcess:
        return []


def test_the_local_cluster_listens_on_loopback_only(clusters):
    import psutil

    client = clusters.get(3)  # not whichever size an earlier test of this worker left
    info = client.scheduler_info()
    assert all(a.startswith("tls://127.0.0.1:") for a in [info["address"], *info["workers"]])
    # Every socket listening in the scheduler (this process), the nannies and the workers
    # (its children): the Dask ports and the HTTP ones (health, metrics) alike.
    processes = [psutil.Process(), *psutil.Process().children(recursive=True)]
    assert len(processes) >= 1 + 3  # the scheduler's process and at least three workers
    listening = [c.laddr for p in processes for c in _connections(p)
                 if c.status == psutil.CONN_LISTEN]
    assert len(listening) >= 2 + 3
    assert {a.ip for a in listening} == {"127.0.0.1"}, listening


def test_a_textured_gltf_travels_as_its_file_and_renders_the_same(clusters, tmp_path):
    # scenes/gltf_scene.glb (79 kB: two textures, a camera, lights) loaded on the client: the
    # workers get the file's bytes and read it themselves, once each. Its decoded scene
    # pickles to 490 kB; the files' bytes with the rest of the scene to 83 kB.
    path = ROOT / "scenes" / "gltf_scene.glb"
    scene = raytrace.load_scene(path)
    kw = {"width": W, "height": H}
    reference = raytrace.render(scene, threads=1, **kw)
    client = clusters.get(2)
    builds = 0
    for tile in TILES:
        image = raytrace.render(scene, client=client, tile=tile, **kw)
        assert same_bits(image.rgb, reference.rgb), tile
        d = image.stats["distributed"]
        assert d["file_bytes"] == path.stat().st_size
        assert d["scene_bytes"] <= 2 * d["file_bytes"] < len(pickle.dumps(scene))
        builds += sum(w["builds"] for w in d["workers"].values())
    assert 1 <= builds <= 2  # read and built once per worker for both tile sizes
    # frames: scene files naming the model, read here and sent as their files
    shutil.copy(path, tmp_path / "model.glb")
    for f in (1, 2):
        (tmp_path / f"shot_{f}.toml").write_text(
            f"[render]\nwidth = 24\nheight = 16\n[camera]\nposition = [0, 2, {5 + f}]\n"
            "look_at = [0, 0.5, 0]\n[[lights]]\ntype = \"point\"\nposition = [2, 4, 5]\n"
            "[[objects]]\ntype = \"mesh\"\nfile = \"model.glb\"\nmaterial = \"from_file\"\n")
    raytrace.render_frames(str(tmp_path / "shot_#.toml"), str(tmp_path / "out.#.exr"), "1-2",
                           client=client)
    for f in (1, 2):
        local = raytrace.render(raytrace.load_scene(tmp_path / f"shot_{f}.toml"), threads=1)
        assert same_bits(raytrace.read_exr(tmp_path / f"out.{f}.exr")[0], local.rgb), f


def test_a_scene_with_a_file_mesh_pickles_with_its_triangles(mesh_scene, scenes):
    assert not (Path(mesh_scene.path).parent / "models").exists()  # deleted by the fixture
    back = pickle.loads(pickle.dumps(mesh_scene))
    mesh = back.objects[1]
    np.testing.assert_array_equal(mesh.vertices, mesh_scene.objects[1].vertices)
    assert same_bits(raytrace.render(back, threads=1, **scenes["mesh"][1]).rgb,
                     scenes["mesh"][2].rgb)


def test_import_and_a_local_render_do_not_import_dask():
    code = ("import sys, raytrace, raytrace.cli\n"
            "s = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])\n"
            "raytrace.render(s, width=4, height=3)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed', 'cloudpickle')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.strip() == "[]"


def test_tile_is_checked_and_needs_a_client(scenes):
    scene, kw, _ = scenes["mesh"]
    with pytest.raises(raytrace.SceneError, match="tiles need a client"):
        raytrace.render(scene, tile=16, **kw)
    with pytest.raises(raytrace.SceneError, match="a worker timeout needs a client"):
        raytrace.render(scene, worker_timeout=5, **kw)


def test_the_doctests():
    import doctest

    from raytrace import frames

    for module in (rd, frames):
        assert doctest.testmod(module).failed == 0


@pytest.mark.slow
def test_the_cluster_benchmark_s_quick_run(tmp_path):
    out = tmp_path / "cluster.json"
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "cluster.py"), "--quick",
                          "--repeat", "1", "--no-tcp", "--json", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    import json

    results = json.loads(out.read_text())
    rows = [x for c in results["clusters"] for r in c["scenes"].values() for x in r["tiles"]]
    assert [c["workers"] for c in results["clusters"]] == [1, 2]
    assert len(rows) == 2 * 2 * 2 and all(x["identical"] for x in rows)
    cold = [r["cold"] for c in results["clusters"] for r in c["scenes"].values()]
    assert all(x["identical"] and 1 <= x["builds"] <= 2 for x in cold)
    assert "dask cpu ms/tile" in run.stdout


class _Done:
    """A finished future, as gather_each's error rule sees one."""

    def __init__(self, error: Exception | None = None, cancelled: bool = False):
        self.error, self._cancelled = error, cancelled

    def cancelled(self) -> bool:
        return self._cancelled

    def exception(self):
        return self.error


def test_of_several_frame_errors_the_earliest_frame_s_is_raised():
    # Frames 2 and 3 fail side by side; frame 3's error may arrive first, but a local render
    # stops at frame 2, so that is the line.
    two, three = raytrace.SceneError("two", "radius"), raytrace.SceneError("three", "radius")
    futures = [_Done(), _Done(two), _Done(three)]
    assert rd.earliest_scene_error(futures, three) is two
    assert rd.earliest_scene_error([_Done(), _Done(three)], three) is three
    # a frame before it that died otherwise (or was cancelled): the error that arrived
    assert rd.earliest_scene_error([_Done(RuntimeError("x")), _Done(three)], three) is three
    assert rd.earliest_scene_error([_Done(cancelled=True), _Done(two)], three) is three
