"""OpenEXR: float32 R, G, B, linear and unclamped, with the sRGB/Rec. 709 chromaticities and the
render settings in the header (OpenEXR's Python binding, which needs C-contiguous channels: a
strided view silently writes wrong pixels, so every channel is copied contiguous); AOVs as more
channels of the same file (:mod:`.aov`); a crop as the data window inside the full frame's
display window (OpenEXR, "Technical Introduction": windows are inclusive pixel bounds).
Written atomically (:func:`.files.atomic_path`)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .files import atomic_path

#: Rec. 709 / sRGB primaries and D65 white: (red xy, green xy, blue xy, white xy).
SRGB_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)

#: The EXR compressions offered, by name → the OpenEXR binding's constant. All are lossless on
#: float32 (bit-exact round trips); the lossy ones (PXR24, B44, DWAA/DWAB) are left out. ZSTD
#: files need OpenEXR >= 3.5 to read them (and that binding to write them).
EXR_COMPRESSIONS = {"none": "NO_COMPRESSION", "rle": "RLE_COMPRESSION",
                    "zips": "ZIPS_COMPRESSION", "zip": "ZIP_COMPRESSION",
                    "piz": "PIZ_COMPRESSION", "zstd": "ZSTD_COMPRESSION"}


def exr_compression(name: str):
    """The OpenEXR binding's compression constant for one of :data:`EXR_COMPRESSIONS`' names
    (any case); a ValueError naming the valid ones otherwise."""
    import OpenEXR

    key = name.lower() if isinstance(name, str) else None
    if key not in EXR_COMPRESSIONS:
        raise ValueError(f"unknown EXR compression {name!r} "
                         f"(choose from {', '.join(EXR_COMPRESSIONS)})")
    if not hasattr(OpenEXR, EXR_COMPRESSIONS[key]):
        raise ValueError(f"EXR compression {key!r} needs a newer OpenEXR module than "
                         f"{getattr(OpenEXR, '__version__', 'the one installed')}")
    return getattr(OpenEXR, EXR_COMPRESSIONS[key])


def write_exr(path: str | os.PathLike, rgb: np.ndarray, metadata: dict | None = None,
              threads: int = 1, compression: str = "zip", *,
              channels: dict[str, np.ndarray] | None = None,
              crop: tuple[int, int, int, int] | None = None,
              frame: tuple[int, int] | None = None) -> None:
    """Write (H, W, 3) linear RGB as float32 OpenEXR, atomically, with a lossless
    ``compression`` from :data:`EXR_COMPRESSIONS` (default ``"zip"``: zlib per 16 scanlines).
    ``threads`` > 1 compresses the scanline blocks on OpenEXR's pool of that many workers
    (process-wide, restored afterwards); the file's bytes do not depend on it. Whitted
    1280×960 on 2 cores: ZIP 123 ms on 1 thread, 71 ms on 2, 7.3 MB either way. At 2 threads:
    ZIPS 74 ms/8.9 MB, PIZ 242 ms/6.9 MB, RLE 36 ms/14 MB, none 20 ms/15 MB, ZSTD 72 ms/3.9 MB
    but unreadable before OpenEXR 3.5 (docs/performance.md).

    ``channels``: more (H, W) float32 channels by name (the AOVs). ``crop`` (x0, y0, x1, y1),
    half-open, places the image in a ``frame`` of (width, height) pixels: the data window is
    the crop, the display window the frame (as pbrt and compositors do).
    """
    import OpenEXR

    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) image, got shape {rgb.shape}")
    header = {"compression": exr_compression(compression), "type": OpenEXR.scanlineimage,
              "chromaticities": SRGB_CHROMATICITIES}
    if crop is not None:
        if frame is None:
            raise ValueError("a crop needs the frame (width, height) it is a window of")
        x0, y0, x1, y1 = crop
        width, height = frame
        if (y1 - y0, x1 - x0) != rgb.shape[:2]:
            raise ValueError(f"crop {crop} does not match the image's {rgb.shape[1]}x"
                             f"{rgb.shape[0]} pixels")
        header["dataWindow"] = ((x0, y0), (x1 - 1, y1 - 1))
        header["displayWindow"] = ((0, 0), (width - 1, height - 1))
    for k, v in (metadata or {}).items():
        header[f"raytrace:{k}"] = v if isinstance(v, (int, float)) else str(v)
    extra = {name: np.ascontiguousarray(c, dtype=np.float32)
             for name, c in (channels or {}).items()}
    channels = {c: np.ascontiguousarray(rgb[..., i]) for i, c in enumerate("RGB")}
    channels.update(extra)
    workers = int(threads) if threads > 1 else 0  # 0: compress on the calling thread
    # A binding without the pool setting writes single-threaded.
    has_pool = hasattr(OpenEXR, "global_thread_count")
    before = OpenEXR.global_thread_count() if has_pool else workers
    if workers != before:
        OpenEXR.set_global_thread_count(workers)
    try:
        with atomic_path(path, ".exr") as tmp, OpenEXR.File(header, channels) as f:
            f.write(str(tmp))
    finally:
        if workers != before:
            OpenEXR.set_global_thread_count(before)


def read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """(H, W, 3) float32 RGB (the data window: a crop's pixels) and the header of an EXR
    file; other channels (AOVs) are left out: :meth:`Image.from_exr` reads them."""
    rgb, _, header = read_exr_channels(path)
    return rgb, header


def read_exr_channels(path: str | os.PathLike) -> tuple[np.ndarray, dict, dict]:
    """RGB as :func:`read_exr` reads it, every other channel by name (H, W), the header. A
    missing file is a :class:`FileNotFoundError` (checked first: the binding would print to
    stderr); a file the binding cannot read (damaged, truncated, another format) or without
    R, G and B is a :class:`~raytrace.errors.SceneError` naming it, in one line: the binding
    itself raises a bare RuntimeError, or for a truncated file a ValueError about "0
    parts", or a UnicodeDecodeError for a damaged header."""
    import OpenEXR

    if Path(path).is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder, not an EXR file", os.fspath(path))
    if not Path(path).is_file():
        raise FileNotFoundError(errno.ENOENT, "no such EXR file", os.fspath(path))
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = {name: c.pixels for name, c in f.channels().items()}
            header = dict(f.header())
    except (RuntimeError, ValueError) as e:
        raise SceneError(f"not a readable OpenEXR file: damaged, truncated or another format "
                         f"(OpenEXR: {e})", file=os.fspath(path)) from None
    missing = [c for c in "RGB" if c not in ch]
    if missing:
        raise SceneError(f"no channel(s) {', '.join(missing)} (has {', '.join(sorted(ch))})",
                         file=os.fspath(path))
    rgb = np.stack([np.asarray(ch.pop(c), dtype=np.float32) for c in "RGB"], axis=-1)
    return rgb, ch, header
