"""``raytrace.render``: one call from a :class:`~raytrace.scene.Scene` to an :class:`Image`.

Also the memory a render may use. Every render has a memory ceiling (:func:`memory_ceiling`):
``max_memory`` (``--max-memory``) or by default the memory this process holds when the render
starts plus the memory the machine has available then. The estimated peak
(:func:`peak_bytes`) is checked against the memory available and the ceiling before any work
(:func:`check_memory`), and while the render runs a thread reads the process's resident
memory every :data:`WATCH_SECONDS` and stops the render once it is over the ceiling
(:func:`watch_memory`), through the same stop as a Ctrl-C (:class:`raytrace.integrator.Stop`):
a :class:`~raytrace.errors.MemoryLimitError` naming the ceiling and how to raise it.
"""

from __future__ import annotations

import os
import re
import threading
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import psutil

from . import values
from .distributed import check_tile, check_worker_timeout, render_tiles
from .errors import MemoryLimitError, RenderWarning, SceneError
from .film import writers
from .film.aov import check_aovs
from .film.image import Image
from .integrator import PASS_SAMPLES, RenderOptions, Stop, WhittedIntegrator
from .mipmap import point_sampled
from .scene import RenderSettings, Scene, object_materials

if TYPE_CHECKING:
    from distributed import Client

    from .integrator import RenderOptions

#: Peak resident memory of a render, measured (``ru_maxrss`` at 3000² and 6000² pixels, 2
#: threads; docs/robustness.md, "Memory"): a fixed part (the interpreter, numba, Embree, a
#: pass of rays per thread) plus bytes a pixel for the step that holds the most: the render
#: (the float32 image and a mask), or writing an output (each writer's own figure,
#: :data:`raytrace.film.writers.WRITERS`). AOVs are not counted.
PEAK_BASE_BYTES = 300 * 2**20
PEAK_RENDER_BYTES_PER_PIXEL = 15
#: Seconds between two readings of the process's memory while a render runs
#: (:func:`watch_memory`); each costs about 0.2 ms (psutil reading /proc on Linux).
WATCH_SECONDS = 0.1
#: A memory size's units (``--max-memory 4G``): binary multiples, as ``ulimit``, Docker and
#: Slurm read them (1G = 1024³ bytes), with an optional ``B`` or ``iB``.
SIZE_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}
SIZE = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([KMGT]?)(?:i?B)?\s*", re.IGNORECASE)


def peak_bytes(width: int, height: int, steps: Iterable[str] = ()) -> int:
    """Estimated peak memory of a ``width`` × ``height`` render followed by ``steps``
    (writers' names, ``"exr"``, ``"png"``): the base plus the pixels times the largest
    step's bytes."""
    per_pixel = max([PEAK_RENDER_BYTES_PER_PIXEL,
                     *(writers.named(s).peak_bytes_per_pixel for s in steps)])
    return PEAK_BASE_BYTES + per_pixel * width * height


def available_bytes() -> int | None:
    """Memory this machine can give now without swapping (psutil's ``available``, on Linux
    the kernel's MemAvailable), or None where unknown."""
    try:
        return int(psutil.virtual_memory().available)
    except (OSError, NotImplementedError, AttributeError):  # a platform psutil cannot read
        return None


def rss_bytes() -> int:
    """This process's resident memory now (psutil's ``rss``), bytes."""
    return int(psutil.Process().memory_info().rss)


def memory_size(value: Any, key: str = "max_memory") -> int:
    """Bytes of a memory size: a whole number of bytes, or a string of a number and a unit
    of :data:`SIZE_UNITS` (``"4G"``, ``"512M"``, ``"1.5GiB"``, ``"1000000"``); a
    :class:`SceneError` naming ``key`` otherwise.

    >>> memory_size("4G"), memory_size("512m"), memory_size(1000)
    (4294967296, 536870912, 1000)
    """
    if isinstance(value, str):
        m = SIZE.fullmatch(value)
        if m is None:
            raise SceneError(f"must be a size such as 4G, 512M or a number of bytes, got "
                             f"{value!r}", key)
        value = float(m[1]) * SIZE_UNITS[m[2].upper()]
        if m[2]:  # a size in a unit: to the nearest byte ("1.5G")
            value = round(value)
    return values.number(value, key, lo=1, integer=True)


def size_text(n: int, digits: int = 1) -> str:
    """A number of bytes in the units of :data:`SIZE_UNITS`, to ``digits`` decimals.

    >>> size_text(4 * 2**30), size_text(1536 * 2**20), size_text(100), size_text(2**30, 3)
    ('4.0 GiB', '1.5 GiB', '100 bytes', '1.000 GiB')
    """
    for unit in ("T", "G", "M", "K"):
        if n >= SIZE_UNITS[unit]:
            return f"{n / SIZE_UNITS[unit]:.{digits}f} {unit}iB"
    return f"{n} bytes"


def size_texts(a: int, b: int) -> tuple[str, str]:
    """Two sizes (:func:`size_text`) to the fewest decimals, one to six, that tell them apart.

    >>> size_texts(2**30 + 2**20, 2**30), size_texts(3 * 2**30, 2**30)
    (('1.001 GiB', '1.000 GiB'), ('3.0 GiB', '1.0 GiB'))
    """
    for digits in range(1, 7):
        texts = size_text(a, digits), size_text(b, digits)
        if texts[0] != texts[1]:
            break
    return texts


@dataclass(frozen=True)
class Ceiling:
    """A render's memory ceiling: the most resident memory its process may hold, bytes, and
    whether it was asked for (``max_memory``) or is the default (:func:`memory_ceiling`)."""

    bytes: int
    given: bool

    def over(self, what: str, size: int) -> MemoryLimitError:
        """The error of ``what`` (e.g. "the render reached {} and was stopped", the ``{}``
        for ``size`` bytes) over this ceiling, which names the ceiling and how to raise it,
        keyed ``max_memory`` (``--max-memory``); both sizes to the decimals that tell them
        apart."""
        size_said, ceiling_said = size_texts(size, self.bytes)
        default = "" if self.given else (" (the default: the memory this process held and "
                                         "the memory available when the render started)")
        return MemoryLimitError(f"{what.format(size_said)}, over the memory ceiling of "
                                f"{ceiling_said}{default}; give a larger size to raise it",
                                "max_memory")


def memory_ceiling(max_memory: Any = None) -> Ceiling | None:
    """The memory ceiling of a render starting now: ``max_memory`` (:func:`memory_size`), or
    by default what this process holds plus what the machine has available
    (:func:`rss_bytes` + :func:`available_bytes`): the most the render can hold without
    swapping or meeting the kernel's out-of-memory killer as the machine stands when it
    starts. None where the platform does not tell the memory available."""
    if max_memory is not None:
        return Ceiling(memory_size(max_memory), True)
    have = available_bytes()
    return None if have is None else Ceiling(rss_bytes() + have, False)


def check_memory(width: int, height: int, steps: Iterable[str] = (),
                 key: str = "render.width", ceiling: Ceiling | None = None) -> None:
    """Refuse, before any work, a render (and ``steps``) whose estimated peak
    (:func:`peak_bytes`) is more than the memory available (:func:`available_bytes`) or
    than its ``ceiling`` (a :class:`~raytrace.errors.MemoryLimitError`)."""
    steps = tuple(steps)
    need, have = peak_bytes(width, height, steps), available_bytes()
    what = f"render{''.join(' + ' + s for s in steps)}"
    if have is not None and need > have:
        need_said, have_said = size_texts(need, have)
        raise MemoryLimitError(f"{width}x{height} needs about {need_said} of memory at its "
                               f"peak ({what}), more than the {have_said} available on this "
                               "machine", key)
    if ceiling is not None and need > ceiling.bytes:
        raise ceiling.over(f"{width}x{height} needs about {{}} of memory at its peak ({what})",
                           need)


@contextmanager
def watch_memory(ceiling: Ceiling | None, stop: Stop) -> Iterator[None]:
    """While the block runs, a thread reads this process's resident memory
    (:func:`rss_bytes`) at once and then every :data:`WATCH_SECONDS`, and asks ``stop`` to
    end the render with the ceiling's :class:`~raytrace.errors.MemoryLimitError` once it is
    over ``ceiling`` (None: no thread)."""
    if ceiling is None:
        yield
        return
    done = threading.Event()

    def watch() -> None:
        while True:
            rss = rss_bytes()
            if rss > ceiling.bytes:
                stop.request(ceiling.over("the render reached {} and was stopped", rss))
                return
            if done.wait(WATCH_SECONDS):
                return

    thread = threading.Thread(target=watch, name="raytrace-memory", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def render(scene: Scene, *, width: int | None = None, height: int | None = None,
           spp: int | None = None, max_depth: int | None = None,
           min_weight: float | None = None, seed: int | None = None, threads: int | None = None,
           progress: Callable[[int, int], None] | None = None,
           pass_samples: int | None = None,
           crop: Sequence[int] | None = None,
           aovs: str | Iterable[str] | None = None, filter: str | None = None,
           aa: str | None = None, aa_threshold: float | None = None,
           aa_depth: int | None = None, aa_min_depth: int | None = None,
           noise_threshold: float | None = None, min_spp: int | None = None,
           max_spp: int | None = None, target_error: float | None = None,
           time_limit: float | None = None,
           client: Client | None = None, tile: int | None = None,
           max_memory: int | str | None = None,
           worker_timeout: float | None = None,
           texture_filter: str | None = None) -> Image:
    """Render ``scene``; keyword arguments override its ``[render]`` settings.

    Returns an :class:`Image` whose ``rgb`` is (height, width, 3) float32 linear RGB and whose
    ``stats`` is the ``--stats`` dictionary. ``threads`` defaults to every core, like the
    command line; the image does not depend on it. ``pass_samples`` caps the camera samples
    per pass (default :data:`raytrace.integrator.PASS_SAMPLES`).

    ``crop`` = (x0, y0, x1, y1) renders only those pixels (half-open bounds, like pbrt's
    ``--pixelbounds``): ``rgb`` is then (y1 − y0, x1 − x0, 3), bit-identical to that window
    of the full render. ``aovs``: names from :data:`raytrace.film.aov.AOVS` (depth, normal,
    albedo, id, uv, position, samples) to render besides the colour, read with
    ``Image.aov(name)``. ``filter`` (:data:`raytrace.sampling.FILTERS`), ``aa`` ("uniform",
    "adaptive" or "noise"),
    ``aa_threshold``, ``aa_depth``, ``aa_min_depth``, ``noise_threshold``, ``min_spp`` and
    ``max_spp`` override the scene's ``[render]`` keys of the same names, and so does
    ``texture_filter`` ("bilinear" or "trilinear": mip-mapped by ray cones,
    :mod:`raytrace.mipmap`).

    ``target_error`` (a relative RMSE, e.g. 0.01) and ``time_limit`` (seconds) render by noise-
    driven sampling (``aa = "noise"``, :mod:`raytrace.noise`; the scene's ``aa`` unless it is
    uniform and ``aa`` is not given) until the renderer's estimate of the relative RMSE is at
    most the target or the time is up, whichever comes first; ``stats["aa"]`` and the EXR's
    metadata then record the estimate, the samples spent and why the render stopped.

    Every argument is checked before any work (a SceneError, or a TypeError for a
    ``progress`` that is not callable or a ``client`` that is no Client), including the
    memory the image needs (:func:`check_memory`), and so is the scene, as at its
    construction: fields set and arrays edited since, objects appended, material names
    (:meth:`~raytrace.scene.Scene.check`). A scene without objects, and pixels that
    overflowed float32 (written as 0, counted in ``stats["nonfinite_pixels"]``), give a
    :class:`~raytrace.errors.RenderWarning`.

    ``max_memory``: the memory ceiling of this process while it renders, bytes or a size
    such as ``"4G"`` (:func:`memory_size`; default: :func:`memory_ceiling`'s). A render
    whose estimate is over it is refused before any work, and one that reaches it is stopped
    within :data:`WATCH_SECONDS` and a batch of each pass: a
    :class:`~raytrace.errors.MemoryLimitError`. A Ctrl-C stops the passes as quickly and is
    raised as the KeyboardInterrupt it is (:class:`raytrace.integrator.Stop`).

    ``client``: a ``dask.distributed.Client``; the image (or the crop) is then rendered as
    ``tile``×``tile``-pixel crops (default :data:`raytrace.distributed.TILE`) on its cluster's
    workers, each on one thread, and put together: bit-identical to the render on one process
    (:func:`raytrace.distributed.render_tiles`; docs/distributed.md). A cluster left without
    any worker for ``worker_timeout`` seconds (default
    :data:`raytrace.distributed.WORKER_TIMEOUT`) ends the render with a
    :class:`~raytrace.errors.ClusterError`; the ceiling bounds this process, not the
    workers (each has Dask's own ``memory_limit``).

    Rendering the same ``scene`` object again reuses its acceleration structure while its
    geometry and camera position are unchanged (:mod:`raytrace.accel_cache`).

    The integrator, and with it numba, is imported on the first call, so ``import raytrace``
    (loading and checking scenes, reading EXRs) does not pay for the compiler.
    """
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be a callable progress(done, total) or None, got "
                        f"{type(progress).__name__}")
    if client is not None and not callable(getattr(client, "submit", None)):
        raise TypeError(f"client must be a dask.distributed.Client or None, got "
                        f"{type(client).__name__}")
    options = render_options(scene, width=width, height=height, spp=spp, max_depth=max_depth,
                             min_weight=min_weight, seed=seed, threads=threads,
                             pass_samples=pass_samples, crop=crop, aovs=aovs, filter=filter,
                             aa=aa, aa_threshold=aa_threshold, aa_depth=aa_depth,
                             aa_min_depth=aa_min_depth, noise_threshold=noise_threshold,
                             min_spp=min_spp, max_spp=max_spp, target_error=target_error,
                             time_limit=time_limit, texture_filter=texture_filter)
    x0, y0, x1, y1 = options.crop or (0, 0, options.width, options.height)
    try:
        ceiling = memory_ceiling(max_memory)
        check_memory(x1 - x0, y1 - y0, ceiling=ceiling)
        if client is None and tile is not None:
            raise SceneError("tiles need a client: render(scene, client=..., tile=...)", "tile")
        if client is None and worker_timeout is not None:
            raise SceneError("a worker timeout needs a client: render(scene, client=..., "
                             "worker_timeout=...)", "worker_timeout")
        if client is not None and (target_error is not None or time_limit is not None):
            raise SceneError("a target error or time limit is the whole image's: render it "
                             "on one process (no client)",
                             "target_error" if target_error is not None else "time_limit")
        if client is not None:
            tile, worker_timeout = check_tile(tile), check_worker_timeout(worker_timeout)
    except SceneError as e:
        raise type(e)(e.problem, e.key, scene.path) from None
    where = f"{scene.path}: " if scene.path else ""
    if not scene.objects:
        warnings.warn(f"{where}the scene has no objects: the image is the background",
                      RenderWarning, stacklevel=2)
    if (tree := ray_tree_warning(scene, options.max_depth, options.min_weight)) is not None:
        warnings.warn(f"{where}{tree}", RenderWarning, stacklevel=2)
    if (unseen := invisible_warning(scene)) is not None:
        warnings.warn(f"{where}{unseen}", RenderWarning, stacklevel=2)
    if point_sampled(options) and options.texture_filter == "trilinear":
        warnings.warn(f"{where}texture_filter: \"trilinear\" is not used by noise-driven "
                      "sampling, which reads textures bilinearly so that its image converges "
                      "to each pixel's mean and its error estimate holds", RenderWarning,
                      stacklevel=2)
    stop = Stop()
    try:
        with watch_memory(ceiling, stop):
            if client is not None:
                image = render_tiles(client, scene, options, tile, progress, worker_timeout)
            else:
                image = WhittedIntegrator(scene, options).render(progress, stop)
        stop.check()  # the ceiling reached after the last pass
    except MemoryLimitError as e:
        raise MemoryLimitError(e.problem, e.key, scene.path) from None
    bad = image.stats.get("nonfinite_pixels", 0)
    if bad:
        first = image.stats.get("nonfinite_first_pixel")  # tiles sum counts, not places
        at = f" (the first at x={first[0]}, y={first[1]})" if first else ""
        warnings.warn(f"{where}{bad} pixel{'s' if bad > 1 else ''} overflowed to inf or NaN"
                      f"{at}, written as 0", RenderWarning, stacklevel=2)
    return image


#: Rays a camera sample may grow into before :func:`ray_tree_warning` speaks: 2^24, which a tree
#: of two rays a hit passes at depth 24 (at the default depth, 5, it has at most 63).
RAY_TREE_RAYS = 2**24


def ray_tree_warning(scene: Scene, max_depth: int, min_weight: float) -> str | None:
    """A warning where ``max_depth`` lets a ray tree grow past :data:`RAY_TREE_RAYS` a camera
    sample: a material that spawns b ≥ 2 rays a hit (:attr:`Material.branches`) and no
    ``min_weight`` to prune with give up to (b^(D+1) − 1)/(b − 1) rays, which two touching
    glass spheres reach (depth 100: 24 s for 16×12 pixels; 150: no end). None otherwise."""
    if min_weight > 0:
        return None
    used = [(m.branches, repr(m.name) if m.name else f"objects[{i}].material")
            for i, o in enumerate(scene.objects) for m in object_materials(o)]
    b, name = max(used, default=(0, ""), key=lambda t: t[0])
    if b < 2:
        return None
    rays = (b ** (max_depth + 1) - 1) // (b - 1)
    if rays <= RAY_TREE_RAYS:
        return None
    return (f"render.max_depth: {max_depth} with min_weight 0 lets a ray tree grow to about "
            f"10^{len(str(rays)) - 1} rays a camera sample, as material {name} spawns {b} rays a "
            f"hit; where such surfaces face each other the render may not end: set "
            f"render.min_weight (POV-Ray's adc_bailout, 1/255 there) or a lower max_depth")


def invisible_warning(scene: Scene) -> str | None:
    """A warning naming the objects whose every material is invisible
    (:attr:`Material.invisible`: opacity 0, as an MTL ``Tr 1`` makes it), so that nothing of
    them is drawn; None where there are none."""
    unseen = [f"objects[{i}]" for i, o in enumerate(scene.objects)
              if all(m.invisible for m in object_materials(o))]
    if not unseen:
        return None
    return (f"{', '.join(unseen)}: every surface has opacity 0 (MTL d 0 or Tr 1, glTF alpha 0), "
            f"so nothing of {'it' if len(unseen) == 1 else 'them'} is drawn")


def render_options(scene: Scene, *, width: int | None = None, height: int | None = None,
                   spp: int | None = None, max_depth: int | None = None,
                   min_weight: float | None = None, seed: int | None = None,
                   threads: int | None = None, pass_samples: int | None = None,
                   crop: Sequence[int] | None = None,
                   aovs: str | Iterable[str] | None = None, filter: str | None = None,
                   aa: str | None = None, aa_threshold: float | None = None,
                   aa_depth: int | None = None,
                   aa_min_depth: int | None = None, noise_threshold: float | None = None,
                   min_spp: int | None = None, max_spp: int | None = None,
                   target_error: float | None = None,
                   time_limit: float | None = None,
                   texture_filter: str | None = None) -> RenderOptions:
    """The integrator's options: the scene's ``[render]`` settings with the overrides that
    are not None, checked (a :class:`SceneError` locating a bad one in the scene's file),
    after the scene itself (:meth:`~raytrace.scene.Scene.check`): every render, ``explain``
    and command passes here."""
    if not isinstance(scene, Scene):
        raise TypeError(f"render() needs a raytrace.Scene, got {type(scene).__name__}")
    scene.check()  # edits since it was made: checked as at construction, materials resolved
    r = scene.render
    try:
        settings = RenderSettings(
            width=r.width if width is None else width,
            height=r.height if height is None else height,
            spp=r.spp if spp is None else spp,
            max_depth=r.max_depth if max_depth is None else max_depth,
            min_weight=r.min_weight if min_weight is None else min_weight,
            background=r.background, seed=r.seed if seed is None else seed,
            filter=r.filter if filter is None else filter, aa=r.aa if aa is None else aa,
            aa_threshold=r.aa_threshold if aa_threshold is None else aa_threshold,
            aa_depth=r.aa_depth if aa_depth is None else aa_depth,
            aa_min_depth=r.aa_min_depth if aa_min_depth is None else aa_min_depth,
            noise_threshold=r.noise_threshold if noise_threshold is None else noise_threshold,
            min_spp=r.min_spp if min_spp is None else min_spp,
            max_spp=r.max_spp if max_spp is None else max_spp,
            texture_filter=r.texture_filter if texture_filter is None else texture_filter)
        target_error, time_limit = stopping_rules(settings, aa, target_error, time_limit)
        if threads is None:
            threads = os.cpu_count() or 1
        threads = values.number(threads, "threads", lo=1, hi=256, integer=True)
        if pass_samples is None:
            pass_samples = PASS_SAMPLES
        # (no upper bound: a pass never holds more samples than the image has)
        pass_samples = values.number(pass_samples, "pass_samples", lo=1, integer=True)
        window = None if crop is None else check_crop(crop, settings.width, settings.height)
        names = check_aovs(aovs)
        if names and settings.aa == "adaptive":
            raise SceneError('not available with aa = "adaptive" (its pixels are no mean of '
                             'their own samples); render AOVs with aa = "uniform"', "aovs")
        if set(names) - {"samples"} and settings.aa == "noise":
            raise SceneError('only "samples" is available with aa = "noise" (its pixels have '
                             'different sample counts); render the others with aa = '
                             '"uniform"', "aovs")
    except SceneError as e:
        raise SceneError(e.problem, e.key, scene.path) from None
    return RenderOptions(**vars(settings), threads=threads,
                         pass_samples=pass_samples,
                         crop=window, aovs=names, target_error=target_error,
                         time_limit=time_limit)


def stopping_rules(settings: RenderSettings, aa: str | None, target_error: float | None,
                   time_limit: float | None) -> tuple[float | None, float | None]:
    """``target_error`` (> 0) and ``time_limit`` (seconds > 0) checked; either one makes a
    render noise-driven: ``settings.aa`` becomes "noise" where it is "uniform" and no ``aa``
    was given, and any other ``aa`` is a :class:`SceneError` (its samples are fixed in
    advance)."""
    if target_error is not None:
        target_error = values.number(target_error, "target_error", lo=0, lo_open=True)
    if time_limit is not None:
        time_limit = values.number(time_limit, "time_limit", lo=0, lo_open=True)
    if target_error is None and time_limit is None:
        return None, None
    if settings.aa == "uniform" and aa is None:
        settings.aa = "noise"
    if settings.aa != "noise":
        raise SceneError(f'needs aa = "noise" (the samples of aa = "{settings.aa}" are fixed '
                         'in advance)', "target_error" if target_error is not None
                         else "time_limit")
    return target_error, time_limit


def check_crop(crop: Sequence[int], width: int, height: int,
               key: str = "crop") -> tuple[int, int, int, int]:
    """Pixel bounds (x0, y0, x1, y1), half-open, checked: whole numbers with
    0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height (a non-empty window inside the frame);
    a :class:`SceneError` saying which bound is wrong otherwise."""
    if isinstance(crop, str) or not hasattr(crop, "__len__") or len(crop) != 4:
        raise SceneError(f"must be 4 pixel bounds x0 y0 x1 y1, got {crop!r}", key)
    x0, y0, x1, y1 = (values.number(v, key, integer=True) for v in crop)
    for lo, hi, side, axis in ((x0, x1, width, "x"), (y0, y1, height, "y")):
        if not 0 <= lo < hi <= side:
            raise SceneError(f"{axis} bounds {lo}..{hi} must satisfy 0 <= {axis}0 < {axis}1 <= "
                             f"{side} (half-open, inside the {width}x{height} frame)", key)
    return x0, y0, x1, y1
