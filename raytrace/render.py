"""``raytrace.render``: one call from a :class:`~raytrace.scene.Scene` to an :class:`Image`."""

from __future__ import annotations

import os
from collections.abc import Callable

from . import values
from .errors import SceneError
from .film import Image
from .scene import RenderSettings, Scene


def render(scene: Scene, *, width: int | None = None, height: int | None = None,
           spp: int | None = None, max_depth: int | None = None,
           min_weight: float | None = None, seed: int | None = None, threads: int | None = None,
           progress: Callable[[int, int], None] | None = None,
           pass_samples: int | None = None) -> Image:
    """Render ``scene``; keyword arguments override its ``[render]`` settings.

    Returns an :class:`Image` whose ``rgb`` is (height, width, 3) float32 linear RGB and whose
    ``stats`` is the ``--stats`` dictionary. ``threads`` defaults to every core, like the
    command line; the image does not depend on it. ``pass_samples`` caps the camera samples
    per pass (default :data:`raytrace.integrator.PASS_SAMPLES`).

    The integrator, and with it numba, is imported on the first call, so ``import raytrace``
    (loading and checking scenes, reading EXRs) does not pay for the compiler.
    """
    from .integrator import PASS_SAMPLES, RenderOptions, WhittedIntegrator

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
    except SceneError as e:
        raise SceneError(e.problem, e.key, scene.path) from None
    options = RenderOptions(settings.width, settings.height, settings.spp, settings.max_depth,
                            settings.min_weight, settings.background, settings.seed, threads,
                            PASS_SAMPLES if pass_samples is None else pass_samples)
    return WhittedIntegrator(scene, options).render(progress)
