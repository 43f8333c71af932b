"""``raytrace.render``: one call from a :class:`~raytrace.scene.Scene` to an :class:`Image`."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

from . import values
from .aov import check_aovs
from .errors import SceneError
from .film import Image
from .scene import RenderSettings, Scene

if TYPE_CHECKING:
    from distributed import Client

    from .integrator import RenderOptions


def render(scene: Scene, *, width: int | None = None, height: int | None = None,
           spp: int | None = None, max_depth: int | None = None,
           min_weight: float | None = None, seed: int | None = None, threads: int | None = None,
           progress: Callable[[int, int], None] | None = None,
           pass_samples: int | None = None,
           crop: Sequence[int] | None = None,
           aovs: str | Iterable[str] | None = None,
           client: Client | None = None, tile: int | None = None) -> Image:
    """Render ``scene``; keyword arguments override its ``[render]`` settings.

    Returns an :class:`Image` whose ``rgb`` is (height, width, 3) float32 linear RGB and whose
    ``stats`` is the ``--stats`` dictionary. ``threads`` defaults to every core, like the
    command line; the image does not depend on it. ``pass_samples`` caps the camera samples
    per pass (default :data:`raytrace.integrator.PASS_SAMPLES`).

    ``crop`` = (x0, y0, x1, y1) renders only those pixels (half-open bounds, like pbrt's
    ``--pixelbounds``): ``rgb`` is then (y1 − y0, x1 − x0, 3), bit-identical to that window
    of the full render. ``aovs``: names from :data:`raytrace.aov.AOVS` (depth, normal,
    albedo, id) to render besides the colour, read with ``Image.aov(name)``.

    ``client``: a ``dask.distributed.Client``; the image (or the crop) is then rendered as
    ``tile``×``tile``-pixel crops (default :data:`raytrace.distributed.TILE`) on its cluster's
    workers, each on one thread, and put together: bit-identical to the render on one process
    (:func:`raytrace.distributed.render_tiles`; docs/distributed.md).

    The integrator, and with it numba, is imported on the first call, so ``import raytrace``
    (loading and checking scenes, reading EXRs) does not pay for the compiler.
    """
    options = render_options(scene, width=width, height=height, spp=spp, max_depth=max_depth,
                             min_weight=min_weight, seed=seed, threads=threads,
                             pass_samples=pass_samples, crop=crop, aovs=aovs)
    if client is not None:
        from .distributed import check_tile, render_tiles

        try:
            tile = check_tile(tile)
        except SceneError as e:
            raise SceneError(e.problem, e.key, scene.path) from None
        return render_tiles(client, scene, options, tile, progress)
    if tile is not None:
        raise SceneError("tiles need a client: render(scene, client=..., tile=...)", "tile",
                         scene.path)
    from .integrator import WhittedIntegrator

    return WhittedIntegrator(scene, options).render(progress)


def render_options(scene: Scene, *, width: int | None = None, height: int | None = None,
                   spp: int | None = None, max_depth: int | None = None,
                   min_weight: float | None = None, seed: int | None = None,
                   threads: int | None = None, pass_samples: int | None = None,
                   crop: Sequence[int] | None = None,
                   aovs: str | Iterable[str] | None = None) -> RenderOptions:
    """The integrator's options: the scene's ``[render]`` settings with the overrides that
    are not None, checked (a :class:`SceneError` locating a bad one in the scene's file)."""
    from .integrator import PASS_SAMPLES, RenderOptions

    if not isinstance(scene, Scene):
        raise TypeError(f"render() needs a raytrace.Scene, got {type(scene).__name__}")
    r = scene.render
    try:
        settings = RenderSettings(
            width=r.width if width is None else width,
            height=r.height if height is None else height,
            spp=r.spp if spp is None else spp,
            max_depth=r.max_depth if max_depth is None else max_depth,
            min_weight=r.min_weight if min_weight is None else min_weight,
            background=r.background, seed=r.seed if seed is None else seed)
        if threads is None:
            threads = os.cpu_count() or 1
        threads = values.number(threads, "threads", lo=1, hi=256, integer=True)
        window = None if crop is None else check_crop(crop, settings.width, settings.height)
        names = check_aovs(aovs)
    except SceneError as e:
        raise SceneError(e.problem, e.key, scene.path) from None
    return RenderOptions(settings.width, settings.height, settings.spp, settings.max_depth,
                         settings.min_weight, settings.background, settings.seed, threads,
                         PASS_SAMPLES if pass_samples is None else pass_samples, window, names)


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
