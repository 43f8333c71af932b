"""Pixel regression testing: compare a render with a reference and say what differs.

* :func:`assert_image_close` - the assertion for any test suite: per-pixel tolerances
  ``atol + rtol·|expected|`` (numpy's ``isclose``), a budget of bad pixels, optionally a
  metric threshold; on failure a message with the metric values, the number of bad pixels and
  the worst ones, and an artefact folder (actual EXR, expected EXR, diff heatmap PNG,
  side-by-side PNG).
* :func:`compare_images` - the same measurements without asserting, as a :class:`Comparison`
  (``raytrace compare --json`` prints its :meth:`Comparison.to_dict`).
* :func:`artefact_dir` - where a failing comparison writes: ``$RAYTRACE_ARTEFACTS`` or
  ``./raytrace-artefacts``, then a folder named after the running pytest test;
  :func:`clear_artefacts` deletes them once that comparison passes.

The pytest plugin (``raytrace_pytest``: the ``raytrace_golden`` fixture and
``--raytrace-update-goldens``) is built on these. docs/testing.md shows the whole workflow.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image as PILImage
from PIL import ImageDraw, ImageFont

from .film import metrics as _metrics
from .film.compare import Comparison, ImageLike, compare_images, load_image, write_diff
from .film.compare import size as _size
from .film.exr import write_exr
from .film.image import Image
from .film.png import write_png_pixels
from .film.previews import preview

#: The environment variable naming the artefact root folder.
ARTEFACTS_ENV = "RAYTRACE_ARTEFACTS"
#: The artefact root when the variable is unset, relative to the working directory.
DEFAULT_ARTEFACTS = "raytrace-artefacts"
#: The files a failing comparison writes into its artefact folder.
ARTEFACT_FILES = ("actual.exr", "expected.exr", "diff.png", "side_by_side.png")
#: Pixels around a caption of ``side_by_side.png``.
CAPTION_MARGIN = 2

def artefact_dir(name: str | None = None, root: str | os.PathLike | None = None) -> Path:
    """The artefact folder of a comparison: ``root`` (default ``$RAYTRACE_ARTEFACTS``, else
    ``./raytrace-artefacts``) / the running pytest test (module.test, from
    ``PYTEST_CURRENT_TEST``; ``assert_image_close`` outside pytest) [/ ``name``]."""
    root = _artefact_root(root)
    current = os.environ.get("PYTEST_CURRENT_TEST")
    if current:
        nodeid = current.rsplit(" (", 1)[0]
        path, _, rest = nodeid.partition("::")
        test = ".".join([Path(path).stem, *rest.split("::")])
    else:
        test = "assert_image_close"
    parts = [test] + ([name] if name else [])
    return root.joinpath(*(re.sub(r"[^\w.\-\[\]]+", "_", p) for p in parts))


def _artefact_root(root: str | os.PathLike | None) -> Path:
    return Path(root or os.environ.get(ARTEFACTS_ENV) or DEFAULT_ARTEFACTS)


def clear_artefacts(name: str | None = None, root: str | os.PathLike | None = None) -> None:
    """Delete what an earlier failure of this comparison left (:data:`ARTEFACT_FILES` in
    :func:`artefact_dir` with ``name`` and ``root``), then its folders that this empties, up
    to the root (kept): for a comparison that passes now, whose artefacts are stale."""
    folder, top = artefact_dir(name, root), _artefact_root(root)
    for f in ARTEFACT_FILES:
        (folder / f).unlink(missing_ok=True)
    while folder != top and folder.is_relative_to(top):
        try:
            folder.rmdir()
        except OSError:  # not empty (another comparison's, or the user's files), or gone
            break
        folder = folder.parent


def write_artefacts(folder: str | os.PathLike, actual: ImageLike, expected: ImageLike | None,
                    metadata: dict | None = None,
                    inputs: Sequence[str | os.PathLike] = ()) -> Path:
    """Write :data:`ARTEFACT_FILES` into ``folder`` (created): the actual and expected images
    as float EXR (``expected`` may be None: a missing golden), the diff heatmap
    (:func:`raytrace.film.metrics.heatmap`) and expected | actual | difference side by side as
    sRGB previews (clip tone map), each under its caption (:func:`_captioned`), replacing those
    of an earlier failure. Refuses to write over any of ``inputs``."""
    folder = Path(folder)
    targets = [folder / f for f in ARTEFACT_FILES]
    for p in inputs:
        if Path(p).resolve() in {t.resolve() for t in targets}:
            raise ValueError(f"artefact folder {folder} would overwrite the input {p}")
    folder.mkdir(parents=True, exist_ok=True)
    for t in targets:  # the folder holds the latest failure only: no stale diff beside it
        t.unlink(missing_ok=True)
    a = load_image(actual, "actual")
    write_exr(targets[0], _rgb(a), metadata)
    panels = {"actual": _rgb(a)}
    if expected is not None:
        e = load_image(expected, "expected")
        write_exr(targets[1], _rgb(e))
        panels = {"expected": _rgb(e), "actual": _rgb(a)}
        if e.shape == a.shape:
            panels["difference"] = write_diff(targets[2], a, e)[0]
    pngs = [_captioned(p if p.dtype == np.uint8 else preview(p), caption)
            for caption, p in panels.items()]
    height = max(p.shape[0] for p in pngs)
    gap = np.full((height, 2, 3), 64, np.uint8)
    row = []
    for p in pngs:
        pad = np.zeros((height - p.shape[0], p.shape[1], 3), np.uint8)
        row += [np.concatenate([p, pad]), gap]
    write_png_pixels(targets[3], np.concatenate(row[:-1], axis=1))
    return folder


def assert_image_close(actual: ImageLike, expected: ImageLike, *, rtol: float, atol: float,
                       max_bad_fraction: float = 0.0, metric: str | None = None,
                       threshold: float | None = None, name: str | None = None,
                       artefacts: str | os.PathLike | None = None) -> Comparison:
    """Assert that ``actual`` matches ``expected`` (each an :class:`Image`, an array or an EXR
    path) pixel by pixel.

    A pixel is bad when a channel is off by more than ``atol + rtol·|expected|`` (NaN matches
    only NaN); at most ``floor(max_bad_fraction · pixels)`` may be. With ``metric`` (a name in
    :data:`raytrace.film.metrics.METRICS`, e.g. ``"flip"``) that metric is reported too, and with
    ``threshold`` it must also be within it (``<=``; ``>=`` for PSNR).

    On failure raises AssertionError whose message gives the metrics, the bad pixel count, the
    worst pixels with their coordinates and values, and the artefact folder
    (:func:`artefact_dir` with ``name`` and root ``artefacts``) that now holds
    :data:`ARTEFACT_FILES`. Returns the :class:`Comparison` when it passes.
    """
    __tracebackhide__ = True
    if not 0.0 <= max_bad_fraction <= 1.0:
        raise ValueError(f"max_bad_fraction must be in [0, 1], got {max_bad_fraction!r}")
    if threshold is not None:
        if metric is None:
            raise ValueError("threshold needs a metric (e.g. metric='flip', threshold=0.05)")
        threshold = _metrics.check_threshold(threshold)
    names = list(_metrics.BASIC) + ([metric] if metric and metric not in _metrics.BASIC else [])
    if metric is not None:
        _metrics.get(metric)
    a, e = load_image(actual, "actual"), load_image(expected, "expected")
    inputs = [p for p in (actual, expected) if isinstance(p, (str, os.PathLike))]
    metadata = actual.metadata if isinstance(actual, Image) else None
    folder = artefact_dir(name, artefacts)
    if a.shape != e.shape:
        write_artefacts(folder, a, e, metadata, inputs)
        raise AssertionError(f"image size differs: actual is {_size(a)}, expected is "
                             f"{_size(e)}\nartefacts: {folder}")
    c = compare_images(a, e, rtol=rtol, atol=atol, metrics=names)
    allowed = math.floor(max_bad_fraction * c.pixels)
    problems = []
    if c.bad > allowed:
        problems.append(f"{c.bad} of {c.pixels} pixels ({100 * c.bad / c.pixels:.3g} %) are off "
                        f"by more than atol + rtol·|expected| (atol={atol:g}, rtol={rtol:g}); "
                        f"at most {allowed} may be (max_bad_fraction={max_bad_fraction:g})")
    if threshold is not None:
        m = _metrics.get(metric)
        if not m.within(c.metrics[metric], threshold):
            problems.append(f"{metric} = {c.metrics[metric]:.6g}{m.unit} is "
                            f"{'below' if m.higher_is_better else 'over'} the threshold "
                            f"{threshold:g}{m.unit}")
    if problems:
        write_artefacts(folder, a, e, metadata, inputs)
        raise AssertionError("images differ: " + "\n  ".join(problems) + "\n"
                             + format_report(c) + f"\nartefacts: {folder}/ "
                             f"({', '.join(ARTEFACT_FILES)})")
    return c


def format_report(c: Comparison) -> str:
    """The metrics and the worst pixels of a :class:`Comparison`, a few lines of text."""
    lines = ["metrics: " + "  ".join(f"{k}={v:.6g}{_metrics.METRICS[k].unit}"
                                     for k, v in c.metrics.items())]
    if c.worst:
        lines.append("worst pixels (x, y from the top left): actual vs expected")
        for w in c.worst:
            lines.append(f"  ({w['x']}, {w['y']}): {_vec(w['actual'])} vs "
                         f"{_vec(w['expected'])}")
    return "\n".join(lines)


def _captioned(pixels: np.ndarray, caption: str) -> np.ndarray:
    """An (H, W, 3) uint8 panel under a strip naming it (Pillow's default font, white on
    black), widened with black to the caption where the panel is narrower."""
    font = ImageFont.load_default()
    right = font.getbbox(caption)[2]
    rows, cols = pixels.shape[:2]
    strip = font.getbbox("Ag|")[3] + 2 * CAPTION_MARGIN  # one height for every caption
    canvas = PILImage.new("RGB", (max(cols, right + 2 * CAPTION_MARGIN), strip + rows))
    ImageDraw.Draw(canvas).text((CAPTION_MARGIN, CAPTION_MARGIN), caption, font=font,
                                fill=(255, 255, 255))
    out = np.array(canvas)
    out[strip:, :cols] = pixels
    return out


def _vec(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"


def _rgb(a: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 for the EXR and preview writers: one channel as grey, the first
    three of more."""
    a = np.repeat(a, 3, axis=-1) if a.shape[-1] == 1 else a[..., :3]
    if a.shape[-1] == 2:
        a = np.concatenate([a, np.zeros_like(a[..., :1])], axis=-1)
    return np.ascontiguousarray(a, dtype=np.float32)


