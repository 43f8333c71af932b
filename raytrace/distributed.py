"""Rendering on a Dask cluster (``dask.distributed``): tiles of one image, frames of a sequence.

A Whitted render is independent per pixel, so an image is cut into tiles, each rendered as a
crop window (:func:`raytrace.render`'s ``crop``; its pixels are bit-identical to the same pixels
of the full render, docs/testing.md "Crop windows"), and the tiles are put back in place: the
image is bit-identical to a single-process render whatever the number of workers or the tile
size. Frames of a sequence are whole renders, one task each (:mod:`raytrace.frames`).

* :func:`render_tiles`: the client side of ``raytrace.render(scene, client=client)``. The scene
  travels inside one task of the graph (no shared filesystem), so the scheduler can compute it
  again if the worker holding it dies; each tile task depends on it. A scene read from files
  travels as those files' bytes and the rest of it pickled, and is read again on each worker
  (:mod:`raytrace.readers.bundle`: a 542 kB GLB sends 545 kB, not its 67 MB of decoded
  texture); a scene made in Python travels pickled (meshes as arrays).
* :func:`render_tile`: the worker side. Each worker process keeps the last :data:`KEEP` built
  integrators (Embree BVH, material table, lights) by a digest of the sent scene and
  options, so it reads and builds a scene once however many of its tiles it renders.
* A worker that dies (killed, out of memory) has its tiles run again on others (Dask
  reschedules the tasks of a lost worker); a :class:`~raytrace.errors.SceneError` raised on a
  worker is raised again on the client as the same one-line error as a local render's. A
  cluster left with no worker at all for :data:`WORKER_TIMEOUT` seconds (or the render's
  ``worker_timeout``) ends the wait with a :class:`~raytrace.errors.ClusterError`
  (:func:`gather_each`), where Dask would wait for a worker for ever.
* :func:`connect`: a client of a new :func:`local_cluster` (worker processes listening on the
  loopback interface only, with temporary TLS certificates when ``cryptography`` is installed)
  or of an existing scheduler, over TLS with a :func:`security` from certificate files.

Dask runs whatever its clients send: a scheduler reachable by others runs their code as the
user running it. docs/distributed.md has the security notes, the measured costs and the recipes
for SLURM (dask-jobqueue) and Kubernetes (the Dask Kubernetes operator).

This module imports ``distributed`` only inside the functions that need it, and ``import
raytrace`` does not import this module.
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import threading
import time
import warnings
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import values
from .errors import ClusterError, SceneError
from .film import aov as aov_images
from .film.image import Image
from .integrator import WhittedIntegrator
from .readers.bundle import Bundle, pack, unpack
from .readers.scene_file import load_scene
from .scene import Scene

if TYPE_CHECKING:
    from distributed import Client, Security

    from .integrator import RenderOptions, WhittedIntegrator

#: Default tile side in pixels. Each tile costs about 10 ms of CPU in Dask on top of its work
#: (docs/distributed.md); a 256×256 tile of the Whitted scene is about 60 ms of work.
TILE = 256
#: Built integrators (BVH and tables) a worker process keeps, most recently used first.
KEEP = 2
#: Seconds to wait for a scheduler to answer before giving up.
CONNECT_TIMEOUT = 20
#: Seconds a render waits on a cluster that has no worker before giving up (a minute: longer
#: than a worker's restart by its nanny, a few seconds, or a batch system's start of a new
#: worker that is already queued; ``--worker-timeout``, ``render(worker_timeout=)``).
WORKER_TIMEOUT = 60.0
#: Seconds between two looks at the cluster's workers while no result is ready.
WORKER_POLL = 0.5
#: Valid tile sides.
TILE_RANGE = (8, 4096)
#: The ``pip`` extra that installs Dask.
EXTRA = "pip install 'raytrace[distributed]'"


def require_distributed(key: str) -> None:
    """Import ``distributed``, or a :class:`SceneError` naming ``key`` (the flag or argument
    that asked for it) and the extra to install."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SceneError(f"needs Dask's distributed scheduler: {EXTRA}", key) from None


# -- tiles -----------------------------------------------------------------------------------

def tile_grid(window: tuple[int, int, int, int], size: int) -> list[tuple[int, int, int, int]]:
    """The tiles (x0, y0, x1, y1), half-open, of ``window``: ``size``×``size`` squares row by
    row from its top-left corner, the last column and row cut by the window's edges.

    >>> tile_grid((0, 0, 5, 3), 2)
    [(0, 0, 2, 2), (2, 0, 4, 2), (4, 0, 5, 2), (0, 2, 2, 3), (2, 2, 4, 3), (4, 2, 5, 3)]
    """
    x0, y0, x1, y1 = window
    return [(x, y, min(x + size, x1), min(y + size, y1))
            for y in range(y0, y1, size) for x in range(x0, x1, size)]


def check_tile(tile: Any, key: str = "tile") -> int:
    """A tile side in pixels, checked against :data:`TILE_RANGE`; None gives :data:`TILE`."""
    if tile is None:
        return TILE
    return values.number(tile, key, lo=TILE_RANGE[0], hi=TILE_RANGE[1], integer=True)


def check_worker_timeout(seconds: Any, key: str = "worker_timeout") -> float:
    """Seconds a render waits on a cluster without workers, checked (> 0, finite); None
    gives :data:`WORKER_TIMEOUT`."""
    if seconds is None:
        return WORKER_TIMEOUT
    return values.number(seconds, key, lo=0, lo_open=True)


def scene_payload(scene: Scene, options: RenderOptions) -> tuple[bytes, RenderOptions, str]:
    """What a tile task needs: the scene as it travels (a :class:`Bundle`,
    :func:`raytrace.readers.bundle.pack`: its files' bytes and the rest pickled, or the whole
    scene pickled), pickled; the options of the whole window on one thread (each tile is then
    a crop of them); and a digest (SHA-256) of both: the key of the worker's integrator
    cache."""
    return bundle_payload(pack(scene), options)


def bundle_payload(bundle: Bundle, options: RenderOptions) -> tuple[bytes, RenderOptions, str]:
    """:func:`scene_payload` of a scene already packed as ``bundle``."""
    payload = pickle.dumps(bundle, protocol=pickle.HIGHEST_PROTOCOL)
    base = replace(options, crop=None, threads=1)
    digest = hashlib.sha256(payload)
    digest.update(pickle.dumps(base, protocol=pickle.HIGHEST_PROTOCOL))
    return payload, base, digest.hexdigest()


def load_payload(payload: bytes) -> Bundle:
    """The scene as :func:`scene_payload` sent it (a worker task, whose result each worker
    that renders a tile gets once: for a scene read from files, their bytes)."""
    return pickle.loads(payload)


def load_bundle(bundle: Bundle) -> Scene:
    """The scene of ``bundle``, read again from its files on this worker (once per process:
    :func:`raytrace.readers.bundle.unpack`) or unpickled."""
    return unpack(bundle, load_scene)


@dataclass
class TileResult:
    """One tile back from a worker: its pixels (and AOVs), its statistics, who rendered it,
    whether that worker built the scene for it, and the worker's wall and CPU (its thread's)
    seconds on it."""

    crop: tuple[int, int, int, int]
    rgb: np.ndarray
    aovs: dict[str, np.ndarray]
    stats: dict
    metadata: dict
    worker: str
    pid: int
    build_seconds: float
    seconds: float
    cpu_seconds: float
    built: bool


_integrators: OrderedDict[str, WhittedIntegrator] = OrderedDict()
_integrators_lock = threading.Lock()


def cached_integrator(key: str, bundle: Bundle, options: RenderOptions
                      ) -> tuple[WhittedIntegrator, bool]:
    """This process's integrator for ``key``, built (the scene read from ``bundle`` and the
    BVH included) only when it is not among the last :data:`KEEP` used; and whether it was
    built now. Threads of one worker wait for a build in progress rather than build the same
    scene twice."""
    with _integrators_lock:
        found = _integrators.get(key)
        if found is not None:
            _integrators.move_to_end(key)
            return found, False
        built = WhittedIntegrator(load_bundle(bundle), options)
        _integrators[key] = built
        while len(_integrators) > KEEP:
            _integrators.popitem(last=False)
        return built, True


def worker_name() -> str:
    """The address of the Dask worker running the calling task (``pid N`` outside one)."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def render_tile(bundle: Bundle, key: str, options: RenderOptions,
                crop: tuple[int, int, int, int]) -> TileResult:
    """Render the window ``crop`` of ``options``' frame on one thread, with this worker's
    integrator for ``key`` (:func:`cached_integrator`): a worker task."""
    t0, c0 = time.perf_counter(), time.thread_time()
    base, built = cached_integrator(key, bundle, options)
    image = base.for_window(crop, threads=1).render()
    return TileResult(crop, image.rgb, image.aovs, image.stats, image.metadata, worker_name(),
                      os.getpid(), base.build_seconds if built else 0.0,
                      time.perf_counter() - t0, time.thread_time() - c0, built)


def render_tiles(client: Client, scene: Scene, options: RenderOptions, tile: int | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 worker_timeout: float | None = None) -> Image:
    """``options``' window (its crop, or the whole frame) rendered as tiles of ``tile`` pixels
    on ``client``'s cluster, put together as one :class:`Image`, bit-identical to
    ``raytrace.render`` on one process. ``progress(done, total)`` counts camera samples, as a
    local render's does, after each tile. A cluster without workers for ``worker_timeout``
    seconds (:func:`check_worker_timeout`) is a :class:`ClusterError`
    (:func:`gather_each`). ``stats`` sums the tiles' ray counts and adds
    ``distributed``: the scheduler, tiles, tile size, the bytes of the scene sent to each
    worker and of the files among them, and per worker its tiles, wall and CPU seconds on
    them, builds and rays."""
    t_start = time.perf_counter()
    tile, worker_timeout = check_tile(tile), check_worker_timeout(worker_timeout)
    window = options.crop or (0, 0, options.width, options.height)
    tiles = tile_grid(window, tile)
    bundle = pack(scene)
    payload, base, digest = bundle_payload(bundle, options)
    with warnings.catch_warnings():  # "Sending large graph": the scene is meant to be in it
        warnings.simplefilter("ignore", UserWarning)
        scene_task = client.submit(load_payload, payload, key=f"raytrace-scene-{digest}")
        token = time.time_ns()
        futures = [client.submit(render_tile, scene_task, digest, base, crop, pure=False,
                                 key=f"raytrace-tile-{digest[:12]}-{token}-{i}")
                   for i, crop in enumerate(tiles)]
    results = gather_each(client, futures, worker_timeout)
    total = sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in tiles) * options.spp
    done, parts = 0, []
    for result in results:
        parts.append(result)
        x0, y0, x1, y1 = result.crop
        done += (x1 - x0) * (y1 - y0) * options.spp
        if progress is not None:
            progress(done, total)
    return assemble(parts, options, window, time.perf_counter() - t_start, tile,
                    (len(payload), bundle.file_bytes), client.scheduler.address)


def gather_each(client: Client, futures: list,
                worker_timeout: float = WORKER_TIMEOUT) -> Iterator:
    """The results of ``futures`` as each finishes. A failure cancels the others and is
    raised: a :class:`SceneError` from a worker as a fresh one (the same line as a local
    render's, without the remote traceback), and of several, the one of the earliest future
    in ``futures``' order (:func:`earliest_scene_error`), as a local loop over them would
    meet it; a task that killed workers or was cancelled as a :class:`ClusterError`, and so
    is a cluster that has had no worker for ``worker_timeout`` seconds while results are
    due (looked at every :data:`WORKER_POLL` seconds while none is ready)."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    results = as_completed(futures, loop=client.loop, with_results=True)
    alone_since = None  # when the cluster was first seen without a worker
    try:
        while not results.is_empty():
            if not results.has_ready():
                alone_since = no_worker_since(client, alone_since, worker_timeout)
                with results.thread_condition:  # woken by the next result
                    if not results.has_ready():
                        results.thread_condition.wait(WORKER_POLL)
                continue
            future, result = next(results)  # one is ready: no wait (a task's error raised)
            if future.cancelled():  # its data lost with no way to compute it again, say
                raise ClusterError(f"task {future.key} was cancelled: {result}")
            yield result
    except SceneError as first:
        e = earliest_scene_error(futures, first)
        raise SceneError(e.problem, e.key, e.file) from None
    except KilledWorker as e:
        raise ClusterError(f"task {e.task} died with each of the {e.allowed_failures + 1} "
                           "workers that ran it (Dask's distributed.scheduler.allowed-failures; "
                           "the workers' logs say why: out of memory?)") from None
    finally:
        client.cancel([f for f in futures if not f.done()])


def no_worker_since(client: Client, since: float | None, timeout: float) -> float | None:
    """When ``client``'s cluster was first seen without workers, ``since`` (None: it had
    some), updated by a look now; a :class:`ClusterError` once that is ``timeout`` seconds
    ago."""
    try:
        if client.nthreads():
            return None
    except OSError:  # the scheduler is not answering: no worker reachable either
        pass
    now = time.monotonic()
    since = now if since is None else since
    if now - since >= timeout:
        raise ClusterError(f"the Dask cluster at {client.scheduler.address} has had no worker "
                           f"for {timeout:g} s, so the render stopped (its workers' logs say "
                           f"why they left; --worker-timeout or worker_timeout= waits longer)")
    return since


def earliest_scene_error(futures: list, first: SceneError) -> SceneError:
    """The :class:`SceneError` of the earliest of ``futures`` (in their order) that fails
    with one, waiting for those before ``first``'s to finish; ``first`` where none before it
    does. Frames run side by side on a cluster, so the first error to arrive may be a later
    frame's: a local render stops at the earliest."""
    for future in futures:
        if future.cancelled():
            return first
        try:
            e = future.exception()  # waits for the future (None where it succeeded)
        except Exception:  # cancelled meanwhile, or the cluster went away
            return first
        if e is not None:
            return e if isinstance(e, SceneError) else first
    return first


def assemble(parts: list[TileResult], options: RenderOptions, window: tuple[int, int, int, int],
             wall: float, tile: int, scene_bytes: tuple[int, int], scheduler: str) -> Image:
    """The image of ``window`` from its tiles (in any order), with the merged statistics;
    ``scene_bytes``: the bytes of the scene sent to each worker, and of the files in them."""
    wx0, wy0, wx1, wy1 = window
    rgb = np.empty((wy1 - wy0, wx1 - wx0, 3), np.float32)
    aovs = {name: aov_images.empty(name, rgb.shape[:2]) for name in options.aovs}
    for p in parts:
        x0, y0, x1, y1 = p.crop
        rows, cols = slice(y0 - wy0, y1 - wy0), slice(x0 - wx0, x1 - wx0)
        rgb[rows, cols] = p.rgb
        for name, a in p.aovs.items():
            aovs[name][rows, cols] = a
    stats = merge_stats([p.stats for p in parts])
    stats["seconds"] = {
        "build": sum(p.build_seconds for p in parts),
        "trace": sum(p.stats["seconds"]["trace"] for p in parts),
        "shade": sum(p.stats["seconds"]["shade"] for p in parts),
        "tiles": sum(p.seconds for p in parts),
        "tiles_cpu": sum(p.cpu_seconds for p in parts),
        "total": wall}
    stats["threads"] = 1
    workers: dict[str, dict] = {}
    for p in sorted(parts, key=lambda p: p.worker):
        w = workers.setdefault(p.worker, {"tiles": 0, "seconds": 0.0, "cpu_seconds": 0.0,
                                          "builds": 0, "build_seconds": 0.0, "rays": 0})
        w["tiles"] += 1
        w["seconds"] += p.seconds
        w["cpu_seconds"] += p.cpu_seconds
        w["builds"] += int(p.built)
        w["build_seconds"] += p.build_seconds
        w["rays"] += p.stats["rays"]["total"]
    stats["distributed"] = {"scheduler": scheduler, "tiles": len(parts), "tile": tile,
                            "scene_bytes": scene_bytes[0], "file_bytes": scene_bytes[1],
                            "workers": workers}
    crop = options.crop
    if crop:
        stats["crop"] = list(crop)
    else:
        stats.pop("crop", None)
    metadata = dict(parts[0].metadata)
    metadata.pop("crop", None)
    if crop:
        metadata["crop"] = " ".join(map(str, crop))
    return Image(rgb, stats, metadata, aovs, crop, (options.width, options.height))


#: Counters of ``--stats`` that add up over tiles (besides ``rays`` and ``pruned``).
ADDITIVE = ("total_internal_reflections", "nonfinite_pixels")


def merge_stats(parts: list[dict]) -> dict:
    """One ``--stats`` dictionary from the tiles': ray counts, pruned rays and the
    :data:`ADDITIVE` counters summed, everything else (settings, triangles) from the first."""
    merged = {k: v for k, v in parts[0].items()}
    merged["rays"] = {k: sum(p["rays"][k] for p in parts) for k in parts[0]["rays"]}
    merged["pruned"] = {k: sum(p["pruned"][k] for p in parts) for k in parts[0]["pruned"]}
    for k in ADDITIVE:
        merged[k] = sum(p[k] for p in parts)
    # the first non-finite pixel in reading order (frame coordinates), whichever tile ran first
    firsts = [p["nonfinite_first_pixel"] for p in parts if p.get("nonfinite_first_pixel")]
    merged["nonfinite_first_pixel"] = min(firsts, key=lambda xy: (xy[1], xy[0])) if firsts else None
    return merged


# -- clusters --------------------------------------------------------------------------------

def security(ca_file: str | None = None, cert: str | None = None, key: str | None = None,
             flags: tuple[str, str, str] = ("tls_ca_file", "tls_cert", "tls_key")
             ) -> Security | None:
    """A Dask ``Security`` requiring TLS, from a CA certificate file and this client's
    certificate and key files (PEM); None when none is given (Dask's configuration then
    applies: ``distributed.comm.tls.*``). A :class:`SceneError` naming the flag when one of
    the three is missing or not a file."""
    given = {flag: v for flag, v in zip(flags, (ca_file, cert, key), strict=True) if v}
    if not given:
        return None
    for flag, value in zip(flags, (ca_file, cert, key), strict=True):
        if not value:
            raise SceneError(f"TLS needs all of {', '.join(flags)}; missing this one", flag)
        if not Path(value).is_file():
            raise SceneError(f"file not found: {value}", flag)
    from distributed import Security

    return Security(tls_ca_file=ca_file, tls_client_cert=cert, tls_client_key=key,
                    require_encryption=True)


def local_cluster(workers: int, threads_per_worker: int = 1, tls: bool = True):
    """A ``LocalCluster`` of ``workers`` processes with ``threads_per_worker`` threads each,
    listening on 127.0.0.1 only, without a dashboard; with ``tls`` (and ``cryptography``
    installed) over TLS with temporary certificates that only this process and its workers
    hold, since on a shared machine other users reach the loopback interface too."""
    from distributed import LocalCluster

    secure = None
    if tls:
        try:
            import cryptography  # noqa: F401

            secure = True  # Security.temporary(): a self-signed pair, in memory
        except ImportError:
            pass
    return LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker,
                        processes=True, host="127.0.0.1", dashboard_address=None,
                        # its HTTP routes (health, metrics) on a free loopback port, not 8787
                        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                        security=secure, silence_logs=logging.ERROR)


@contextmanager
def connect(workers: int | None = None, scheduler: str | None = None,
            security: Security | None = None, timeout: float | None = None
            ) -> Iterator[Client]:
    """A Dask client, closed (with its local cluster) at the end of the block: of a new
    :func:`local_cluster` of ``workers`` processes, or of the scheduler at ``scheduler``
    (``tcp://host:8786``, ``tls://host:8786``) with ``security`` (None: Dask's configuration,
    ``distributed.comm.tls.*``). A scheduler that does not answer within ``timeout`` seconds
    (default :data:`CONNECT_TIMEOUT`) is a :class:`ClusterError`."""
    from distributed import Client

    if (workers is None) == (scheduler is None):
        raise ValueError("give workers or scheduler, not both")
    if scheduler is not None:
        try:
            client = Client(scheduler, security=security,
                            timeout=timeout or CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError) as e:
            raise ClusterError(f"cannot reach the Dask scheduler at {scheduler}: "
                               f"{str(e).splitlines()[0] if str(e) else type(e).__name__}"
                               ) from None
        with client:
            yield client
        return
    with local_cluster(workers) as cluster, Client(cluster, set_as_default=False) as client:
        yield client
