"""The film's product: :class:`Image`, the rendered picture (linear float32 RGB, AOVs, stats,
the crop it is of), written by the writers of :mod:`.writers` (EXR, PNG preview), shown in
Jupyter (``_repr_png_``: the default preview, reduced by a box filter to at most
:data:`REPR_MAX_SIZE` pixels a side)."""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .aov import AOVS, channels, from_channels
from .exr import read_exr_channels
from .outputs import Outputs
from .previews import preview, write_png
from .writers import Settings, writer_for


@dataclass
class Image:
    """A rendered image: ``rgb`` (H, W, 3) float32 linear, ``stats`` as in ``--stats``.

    ``aovs``: the AOV images asked for, by name (:mod:`raytrace.film.aov`; :meth:`aov`). ``crop``:
    for a crop, its pixel bounds (x0, y0, x1, y1), half-open, in a ``frame`` of (width,
    height) pixels; then ``rgb`` holds only the crop's pixels. None for a whole frame.
    """

    rgb: np.ndarray
    stats: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    aovs: dict[str, np.ndarray] = field(default_factory=dict)
    crop: tuple[int, int, int, int] | None = None
    frame: tuple[int, int] | None = None

    def aov(self, name: str) -> np.ndarray:
        """The AOV ``name``: ``depth`` (H, W) float32, ``normal`` and ``albedo`` (H, W, 3)
        float32, ``id`` (H, W) int32; a KeyError naming those rendered otherwise."""
        if name not in self.aovs:
            known = ", ".join(self.aovs) or "none"
            hint = "" if name in AOVS else f"; AOVs are {', '.join(AOVS)}"
            raise KeyError(f"no AOV {name!r} in this image (rendered: {known}{hint})")
        return self.aovs[name]

    @classmethod
    def from_exr(cls, path: str | os.PathLike) -> Image:
        """An EXR read back: RGB, the AOVs whose channels it has, the ``raytrace:`` header
        attributes as ``metadata``, and a data window smaller than the display window as
        ``crop`` in ``frame``."""
        rgb, ch, header = read_exr_channels(path)
        metadata = {k.removeprefix("raytrace:"): v for k, v in header.items()
                    if k.startswith("raytrace:")}
        crop = frame = None
        if "dataWindow" in header and "displayWindow" in header:
            (x0, y0), (x1, y1) = (tuple(int(v) for v in c) for c in header["dataWindow"])
            (d0, e0), (d1, e1) = (tuple(int(v) for v in c) for c in header["displayWindow"])
            if (x0, y0, x1, y1) != (d0, e0, d1, e1):
                crop, frame = (x0, y0, x1 + 1, y1 + 1), (d1 - d0 + 1, e1 - e0 + 1)
        return cls(rgb, {}, metadata, from_channels(ch), crop, frame)

    @property
    def width(self) -> int:
        return self.rgb.shape[1]

    @property
    def height(self) -> int:
        return self.rgb.shape[0]

    def save(self, path: str | os.PathLike, exposure: float | str = 0.0, tonemap: str = "clip",
             threads: int = 1, compression: str = "zip", *, bits: int = 8,
             params: dict | None = None) -> None:
        """Write ``path`` by the writer of its suffix (:data:`~raytrace.film.writers.WRITERS`;
        a ValueError naming the valid suffixes otherwise): ``.exr`` (float, linear;
        ``compression`` one of :data:`EXR_COMPRESSIONS`, run on ``threads`` threads) or
        ``.png`` (the sRGB preview of :func:`preview` with ``exposure``, ``tonemap``, its
        ``params`` and ``bits`` 8 or 16); a writer ignores the arguments it has no use for.
        Like the command line's outputs, the file is written whole or not at all
        (:mod:`raytrace.film.outputs`); errors name ``path``, never a temporary file.
        """
        writer = writer_for(path)
        settings = Settings(exposure=exposure, tonemap=tonemap, bits=bits, params=params,
                            threads=threads, compression=compression)
        with Outputs() as outputs:
            out = outputs.add(path, "path", writer.suffix)
            outputs.preflight()
            with outputs.stage(out) as tmp:
                writer.write(tmp, self, settings)
            outputs.commit()

    def channels(self) -> dict[str, np.ndarray]:
        """The AOVs as EXR channels (``Z``, ``N.X`` …), float32 (H, W) each."""
        if not self.aovs:
            return {}
        return {c: a for name, image in self.aovs.items() for c, a in channels(name, image).items()}

    def preview(self, exposure: float | str = 0.0, tonemap: str = "clip", *, bits: int = 8,
                params: dict | None = None) -> np.ndarray:
        """The sRGB preview as an (H, W, 3) uint8 array (uint16 for ``bits=16``): the pixels
        :meth:`save` writes to a ``.png`` (see :func:`preview`)."""
        return preview(self.rgb, exposure, tonemap, bits=bits, params=params)

    def _repr_png_(self) -> bytes:
        """PNG bytes for Jupyter: the default preview (exposure 0, ``clip``) of the image
        reduced by an integer box filter (in linear light) to at most :data:`REPR_MAX_SIZE`
        pixels a side."""
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "image.png"
            write_png(path, reduce(self.rgb, REPR_MAX_SIZE))
            return path.read_bytes()


#: The longest side of the picture an :class:`Image` shows in Jupyter.
REPR_MAX_SIZE = 1024


def reduce(rgb: np.ndarray, max_size: int) -> np.ndarray:
    """(H, W, 3) linear RGB shrunk by the smallest integer factor f that brings both sides to
    ``max_size`` or less, each output pixel the mean of an f×f block (a box filter; the
    blocks on the right and bottom edges may be smaller). Non-finite and negative values
    count as 0, as they show in a preview. Returned as is when already small enough."""
    rgb = np.asarray(rgb)
    f = -(-max(rgb.shape[:2]) // max_size)
    if f <= 1:
        return rgb
    rows, cols = np.arange(0, rgb.shape[0], f), np.arange(0, rgb.shape[1], f)
    out = np.empty((len(rows), len(cols), 3), np.float32)
    for i, y0 in enumerate(rows):  # f rows at a time: no float copy of the whole image
        block = np.nan_to_num(rgb[y0:y0 + f].astype(np.float64), nan=0.0, posinf=0.0,
                              neginf=0.0)
        np.maximum(block, 0.0, out=block)
        sums = np.add.reduceat(block.sum(axis=0), cols, axis=0)
        counts = len(block) * np.diff(np.append(cols, rgb.shape[1]))
        out[i] = sums / counts[:, None]
    return out
