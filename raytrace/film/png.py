"""PNG files of sRGB codes, 8 or 16 bits, written by OpenImageIO band by band, atomically
(:func:`.files.atomic_path`). The codes of a preview come from :mod:`.previews`."""

from __future__ import annotations

import os

import numpy as np

from .files import atomic_path

#: PNG encoder settings (OpenImageIO's PNG writer, libpng underneath), measured on a
#: 4000×3000 render (docs/performance.md, "Previews"): 8-bit with no row filter at zlib level 6
#: was the fastest and smallest on renders; 16-bit with the Up filter at level 1 halves the file
#: of no filter for the same time.
PNG_SETTINGS = {8: {"png:filter": 0x08, "png:compressionLevel": 6},
                16: {"png:filter": 0x20, "png:compressionLevel": 1}}


def write_png_pixels(path: str | os.PathLike, pixels: np.ndarray) -> None:
    """Write (H, W, 3) sRGB codes, uint8 or uint16, as a PNG, atomically (diff heatmaps and
    side-by-side pictures, whose codes are made already)."""
    pixels = np.ascontiguousarray(pixels)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"expected (H, W, 3) uint8 or uint16 codes, got {pixels.dtype} "
                         f"{pixels.shape}")
    write_png_bands(path, pixels.shape[1], pixels.shape[0], 8 * pixels.itemsize,
                     [(0, pixels.shape[0], pixels)])


def write_png_bands(path: str | os.PathLike, width: int, height: int, bits: int,
                     bands) -> None:
    """The PNG writer: OpenImageIO with :data:`PNG_SETTINGS` for ``bits``, band by band
    (``(y0, y1, codes)`` from ``bands``), into a temporary file renamed into place."""
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(width, height, 3, oiio.UINT8 if bits == 8 else oiio.UINT16)
    spec.attribute("oiio:ColorSpace", "sRGB")
    for name, value in PNG_SETTINGS[bits].items():
        spec.attribute(name, value)
    with atomic_path(path, ".png") as tmp:
        out = oiio.ImageOutput.create("png")
        if out is None or not out.open(str(tmp), spec):
            raise OSError(f"{path}: {out.geterror() if out else oiio.geterror()}")
        try:
            for y0, y1, band in bands:
                if not out.write_scanlines(y0, y1, 0, band):
                    raise OSError(f"{path}: {out.geterror()}")
        finally:
            closed = out.close()
        if not closed:
            raise OSError(f"{path}: {out.geterror()}")
