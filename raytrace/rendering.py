"""``raytrace.render``: one call from a :class:`~raytrace.scene.Scene` to an :class:`Image`.

Also the memory a render needs (:func:`peak_bytes`), checked against what the machine has
before any work (:func:`check_memory`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from . import values
from .distributed import check_tile, render_tiles
from .errors import RenderWarning, SceneError
from .film import writers
from .film.aov import check_aovs
from .film.image import Image
from .integrator import PASS_SAMPLES, RenderOptions, WhittedIntegrator
from .scene import RenderSettings, Scene

if TYPE_CHECKING:
    from distributed import Client

    from .integrator import RenderOptions

#: Peak resident memory of a render, measured (``ru_maxrss`` at 3000² and 6000² pixels, 2
#: threads; docs/robustness.md, "Memory"): a fixed part (the interpreter, numba, Embree, a
#: pass of rays per thread) plus bytes a pixel for the step that holds the most: the render
#: (the float32 image and a mask), or writing an output (each writer's own figure,
#: :data:`raytrace.film.writers.WRITERS`). AOVs are not counted.
PEAK_BASE_BYTES = 256 * 2**20
PEAK_RENDER_BYTES_PER_PIXEL = 15


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
    import psutil

    try:
        return int(psutil.virtual_memory().available)
    except (OSError, NotImplementedError, AttributeError):  # a platform psutil cannot read
        return None


def check_memory(width: int, height: int, steps: Iterable[str] = (),
                 key: str = "render.width") -> None:
    """Refuse, before any work, a render (and ``steps``) whose estimated peak
    (:func:`peak_bytes`) is more than the memory available (:func:`available_bytes`)."""
    steps = tuple(steps)
    need, have = peak_bytes(width, height, steps), available_bytes()
    if have is not None and need > have:
        raise SceneError(f"{width}x{height} needs about {need / 1e9:.1f} GB of memory at its "
                         f"peak (render{''.join(' + ' + s for s in steps)}), more than the "
                         f"{have / 1e9:.1f} GB available on this machine", key)


def render(scene: Scene, *, width: int | None = None, height: int | None = None,
           spp: int | None = None, max_depth: int | None = None,
           min_weight: float | None = None, seed: int | None = None, threads: int | None = None,
           progress: Callable[[int, int], None] | None = None,
           pass_samples: int | None = None,
           crop: Sequence[int] | None = None,
           aovs: str | Iterable[str] | None = None, filter: str | None = None,
           aa: str | None = None, aa_threshold: float | None = None,
           aa_depth: int | None = None, aa_min_depth: int | None = None,
           client: Client | None = None, tile: int | None = None) -> Image:
    """Render ``scene``; keyword arguments override its ``[render]`` settings.

    Returns an :class:`Image` whose ``rgb`` is (height, width, 3) float32 linear RGB and whose
    ``stats`` is the ``--stats`` dictionary. ``threads`` defaults to every core, like the
    command line; the image does not depend on it. ``pass_samples`` caps the camera samples
    per pass (default :data:`raytrace.integrator.PASS_SAMPLES`).

    ``crop`` = (x0, y0, x1, y1) renders only those pixels (half-open bounds, like pbrt's
    ``--pixelbounds``): ``rgb`` is then (y1 − y0, x1 − x0, 3), bit-identical to that window
    of the full render. ``aovs``: names from :data:`raytrace.film.aov.AOVS` (depth, normal,
    albedo, id, uv, position) to render besides the colour, read with ``Image.aov(name)``.
    ``filter`` (:data:`raytrace.sampling.FILTERS`), ``aa`` ("uniform" or "adaptive"),
    ``aa_threshold``, ``aa_depth`` and ``aa_min_depth`` override the scene's ``[render]`` keys
    of the same names.

    Every argument is checked before any work (a SceneError, or a TypeError for a
    ``progress`` that is not callable or a ``client`` that is no Client), including the
    memory the image needs (:func:`check_memory`), and so is the scene, as at its
    construction: fields set and arrays edited since, objects appended, material names
    (:meth:`~raytrace.scene.Scene.check`). A scene without objects, and pixels that
    overflowed float32 (written as 0, counted in ``stats["nonfinite_pixels"]``), give a
    :class:`~raytrace.errors.RenderWarning`.

    ``client``: a ``dask.distributed.Client``; the image (or the crop) is then rendered as
    ``tile``×``tile``-pixel crops (default :data:`raytrace.distributed.TILE`) on its cluster's
    workers, each on one thread, and put together: bit-identical to the render on one process
    (:func:`raytrace.distributed.render_tiles`; docs/distributed.md).

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
                             aa_min_depth=aa_min_depth)
    x0, y0, x1, y1 = options.crop or (0, 0, options.width, options.height)
    try:
        check_memory(x1 - x0, y1 - y0)
        if client is None and tile is not None:
            raise SceneError("tiles need a client: render(scene, client=..., tile=...)", "tile")
        if client is not None:
            tile = check_tile(tile)
    except SceneError as e:
        raise SceneError(e.problem, e.key, scene.path) from None
    where = f"{scene.path}: " if scene.path else ""
    if not scene.objects:
        warnings.warn(f"{where}the scene has no objects: the image is the background",
                      RenderWarning, stacklevel=2)
    if client is not None:
        image = render_tiles(client, scene, options, tile, progress)
    else:
        image = WhittedIntegrator(scene, options).render(progress)
    bad = image.stats.get("nonfinite_pixels", 0)
    if bad:
        first = image.stats.get("nonfinite_first_pixel")  # tiles sum counts, not places
        at = f" (the first at x={first[0]}, y={first[1]})" if first else ""
        warnings.warn(f"{where}{bad} pixel{'s' if bad > 1 else ''} overflowed to inf or NaN"
                      f"{at}, written as 0", RenderWarning, stacklevel=2)
    return image


def render_options(scene: Scene, *, width: int | None = None, height: int | None = None,
                   spp: int | None = None, max_depth: int | None = None,
                   min_weight: float | None = None, seed: int | None = None,
                   threads: int | None = None, pass_samples: int | None = None,
                   crop: Sequence[int] | None = None,
                   aovs: str | Iterable[str] | None = None, filter: str | None = None,
                   aa: str | None = None, aa_threshold: float | None = None,
                   aa_depth: int | None = None,
                   aa_min_depth: int | None = None) -> RenderOptions:
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
            aa_min_depth=r.aa_min_depth if aa_min_depth is None else aa_min_depth)
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
    except SceneError as e:
        raise SceneError(e.problem, e.key, scene.path) from None
    return RenderOptions(**vars(settings), threads=threads,
                         pass_samples=pass_samples,
                         crop=window, aovs=names)


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
