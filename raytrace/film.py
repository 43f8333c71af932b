"""The film: the rendered image, its EXR output and tone-mapped previews.

* EXR: float32 R, G, B, linear and unclamped, with the sRGB/Rec. 709 chromaticities and the
  render settings in the header (OpenEXR's Python binding, which needs C-contiguous channels:
  a strided view silently writes wrong pixels, so every channel is copied contiguous); AOVs
  as more channels of the same file (:mod:`raytrace.aov`); a crop as the data window inside
  the full frame's display window (OpenEXR, "Technical Introduction": windows are inclusive
  pixel bounds).
* PNG preview, 8- or 16-bit: exposure (stops, or automatic) → tone map (colour-hdri's
  operators) → clip to [0, 1] → sRGB encoding by colour-science (:mod:`raytrace.tonemap`),
  written by OpenImageIO band by band; all three are imported only when a preview is made.
* In Jupyter an :class:`Image` shows itself (``_repr_png_``: the default preview, reduced by
  a box filter to at most :data:`REPR_MAX_SIZE` pixels a side).

Every file is written atomically: to a temporary file in the same folder, then renamed, so an
interrupted write leaves the old file (or none), never a truncated one.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .tonemap import TONEMAPS  # noqa: F401  (the tone maps by name, as before)

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


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[Path]:
    """A temporary path beside ``path`` that replaces it only if the block completes."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix + ".tmp", dir=folder)
    os.close(fd)
    try:
        yield Path(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs follow the umask
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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
    rgb, _, header = _read_exr(path)
    return rgb, header


def _read_exr(path: str | os.PathLike) -> tuple[np.ndarray, dict, dict]:
    """RGB as :func:`read_exr` reads it, every other channel by name (H, W), the header. A
    missing file is a :class:`FileNotFoundError` (checked first: the binding would print to
    stderr)."""
    import OpenEXR

    if Path(path).is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder, not an EXR file", os.fspath(path))
    if not Path(path).is_file():
        raise FileNotFoundError(errno.ENOENT, "no such EXR file", os.fspath(path))
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {name: c.pixels for name, c in f.channels().items()}
        header = dict(f.header())
    missing = [c for c in "RGB" if c not in ch]
    if missing:
        raise ValueError(f"{path}: no channel(s) {', '.join(missing)} "
                         f"(has {', '.join(sorted(ch))})")
    rgb = np.stack([np.asarray(ch.pop(c), dtype=np.float32) for c in "RGB"], axis=-1)
    return rgb, ch, header


#: PNG encoder settings (OpenImageIO's PNG writer, libpng underneath), measured on a
#: 4000×3000 render (docs/performance.md, "Previews"): 8-bit with no row filter at zlib level 6
#: was the fastest and smallest on renders; 16-bit with the Up filter at level 1 halves the file
#: of no filter for the same time.
PNG_SETTINGS = {8: {"png:filter": 0x08, "png:compressionLevel": 6},
                16: {"png:filter": 0x20, "png:compressionLevel": 1}}


def preview(rgb: np.ndarray, exposure: float | str = 0.0, tonemap: str = "clip", *,
            bits: int = 8, params: dict | None = None) -> np.ndarray:
    """The sRGB preview (H, W, 3) uint8 (uint16 for ``bits=16``) of linear RGB: ``2^exposure``
    (``"auto"``: the key value of Reinhard 2002), the colour-hdri operator ``tonemap``, clip,
    sRGB encoding by colour-science (:func:`raytrace.tonemap.preview`). Non-finite values show
    black."""
    from . import tonemap as tm

    return tm.preview(rgb, exposure, tonemap, bits=bits, params=params)


def write_png(path: str | os.PathLike, rgb: np.ndarray, exposure: float | str = 0.0,
              tonemap: str = "clip", *, bits: int = 8, params: dict | None = None) -> None:
    """Write the sRGB preview of linear RGB (see :func:`preview`) as an 8- or 16-bit PNG,
    atomically, through OpenImageIO: band by band as they are tone-mapped, so neither a float
    copy nor the whole 8-bit image is held. Bad arguments are a ValueError before any file is
    made; a failing write an OSError that leaves the old file."""
    from . import tonemap as tm

    rgb = np.asarray(rgb)
    codes = tm.bands(rgb, exposure, tonemap, bits=bits, params=params)  # checks first
    _write_png_bands(path, rgb.shape[1], rgb.shape[0], bits, codes)


def write_png_pixels(path: str | os.PathLike, pixels: np.ndarray) -> None:
    """Write (H, W, 3) sRGB codes, uint8 or uint16, as a PNG, atomically (diff heatmaps and
    side-by-side pictures, whose codes are made already)."""
    pixels = np.ascontiguousarray(pixels)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"expected (H, W, 3) uint8 or uint16 codes, got {pixels.dtype} "
                         f"{pixels.shape}")
    _write_png_bands(path, pixels.shape[1], pixels.shape[0], 8 * pixels.itemsize,
                     [(0, pixels.shape[0], pixels)])


def _write_png_bands(path: str | os.PathLike, width: int, height: int, bits: int,
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


@dataclass
class Image:
    """A rendered image: ``rgb`` (H, W, 3) float32 linear, ``stats`` as in ``--stats``.

    ``aovs``: the AOV images asked for, by name (:mod:`raytrace.aov`; :meth:`aov`). ``crop``:
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
            from .aov import AOVS

            known = ", ".join(self.aovs) or "none"
            hint = "" if name in AOVS else f"; AOVs are {', '.join(AOVS)}"
            raise KeyError(f"no AOV {name!r} in this image (rendered: {known}{hint})")
        return self.aovs[name]

    @classmethod
    def from_exr(cls, path: str | os.PathLike) -> Image:
        """An EXR read back: RGB, the AOVs whose channels it has, the ``raytrace:`` header
        attributes as ``metadata``, and a data window smaller than the display window as
        ``crop`` in ``frame``."""
        from .aov import from_channels

        rgb, ch, header = _read_exr(path)
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
        """Write ``.exr`` (float, linear; ``compression`` one of :data:`EXR_COMPRESSIONS`, run
        on ``threads`` threads) or ``.png`` (the sRGB preview of :func:`preview` with
        ``exposure``, ``tonemap``, its ``params`` and ``bits`` 8 or 16; ``compression``
        unused). Like the command line's outputs, the file is written whole or not at all
        (:mod:`raytrace.outputs`); errors name ``path``, never a temporary file.
        """
        from .outputs import Outputs

        suffix = Path(path).suffix.lower()
        if suffix not in (".exr", ".png"):
            raise ValueError(f"{path}: unknown image type {suffix!r} (use .exr or .png)")
        with Outputs() as outputs:
            out = outputs.add(path, "path", suffix)
            outputs.preflight()
            with outputs.stage(out) as tmp:
                if suffix == ".exr":
                    write_exr(tmp, self.rgb, self.metadata, threads, compression,
                              channels=self.channels(), crop=self.crop, frame=self.frame)
                else:
                    write_png(tmp, self.rgb, exposure, tonemap, bits=bits, params=params)
            outputs.commit()

    def channels(self) -> dict[str, np.ndarray]:
        """The AOVs as EXR channels (``Z``, ``N.X`` …), float32 (H, W) each."""
        if not self.aovs:
            return {}
        from .aov import channels

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
