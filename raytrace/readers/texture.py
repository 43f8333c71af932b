"""Image textures for a material colour: ``kd = { texture = "wood.png" }``, MTL ``map_Kd``,
glTF ``baseColorTexture``.

A :class:`Texture` holds the image as linear float32 RGBA (H, W, 4), row 0 at the top: 8- and
16-bit sRGB images are decoded with colour-science (``colour.cctf_decoding(x,
function="sRGB")``, IEC 61966-2-1), alpha stays linear. The renderer samples it at the hit's
texture coordinates (s, t) (t = 0 at the top row, as in glTF; OBJ's t is flipped on loading)
with bilinear filtering between texel centres (texel (i, j) is at ((i + ½)/W, (j + ½)/H)),
and the wrap mode per axis from :data:`WRAPS` (:func:`raytrace.kernels.core.texture1`). Images are
read with Pillow, but for 16-bit PNGs (grey, grey + alpha, RGB, RGBA): Pillow opens a 16-bit
colour PNG as 8-bit, so those are read by OpenImageIO at the file's 16 bits (a code c is
c / 65535), their alpha kept unassociated as the PNG stores it (PNG spec §12.8).
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import values
from ..errors import SceneError
from ..film.tonemap import colour as quiet_colour
from .inputs import input_file

#: Wrap modes by name → the code :func:`raytrace.kernels.core.wrap1` reads.
WRAPS = {"repeat": 0, "clamp": 1, "mirror": 2}
#: glTF sampler wrap codes (§5.26: REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT).
GLTF_WRAPS = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
TEXTURE_KEYS = ("texture", "wrap", "srgb", "scale")


class Texture:
    """An image as a colour: linear RGBA texels (H, W, 4) float32, wrap modes, a tint."""

    def __init__(self, texels: np.ndarray, wrap: tuple[str, str] = ("repeat", "repeat"),
                 file: Path | None = None):
        self.texels = np.ascontiguousarray(texels, np.float32)
        if self.texels.ndim != 3 or self.texels.shape[2] != 4 or 0 in self.texels.shape:
            raise SceneError(f"texels must be (H, W, 4), got {self.texels.shape}", "texture")
        self.wrap = tuple(values.string(w, "wrap", WRAPS) for w in wrap)
        self.file = file

    @classmethod
    def from_file(cls, file: Path, key: str, *, srgb: bool = True,
                  wrap: tuple[str, str] = ("repeat", "repeat"), where: str | None = None,
                  data: bytes | None = None) -> Texture:
        """An image file (or its bytes) decoded to linear RGBA."""
        import io

        from PIL import Image, UnidentifiedImageError

        if data is None:
            input_file(file, "texture file", key, where)
        try:
            if png_bit_depth(data if data is not None else _head(file)) == 16:
                rgba = _png16(file, data)
            else:
                with Image.open(io.BytesIO(data) if data is not None else file) as im:
                    im.load()
                    rgba = _pixels(im)
        except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError) as e:
            raise SceneError(f"cannot read texture {file}: {e}", key, where) from None
        if srgb:
            colour = quiet_colour()
            rgba[..., :3] = colour.cctf_decoding(rgba[..., :3], function="sRGB")
        return cls(rgba, wrap, Path(file) if data is None else None)

    def scaled(self, factor: Any) -> Texture:
        """The texture times a colour (glTF's baseColorFactor), alpha kept."""
        t = self.texels.copy()
        t[..., :3] *= np.asarray(factor, np.float32)
        return Texture(t, self.wrap, self.file)

    @property
    def max(self) -> np.ndarray:
        return self.texels[..., :3].reshape(-1, 3).max(axis=0).astype(np.float64)


#: The eight bytes every PNG file begins with (PNG spec §5.2).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_bit_depth(head: bytes) -> int | None:
    """The bit depth a PNG's header chunk states, or None for bytes that are not a PNG: the
    signature, then IHDR (length, ``IHDR``, width, height), its bit depth at byte 24 (PNG spec
    §5.2, §11.2.2).

    >>> png_bit_depth(PNG_SIGNATURE + bytes(4) + b"IHDR" + bytes(8) + bytes([16]))
    16
    """
    if head[:8] == PNG_SIGNATURE and head[12:16] == b"IHDR" and len(head) > 24:
        return head[24]
    return None


def _head(file: Path) -> bytes:
    with open(file, "rb") as f:
        return f.read(25)


def _png16(file: Path, data: bytes | None) -> np.ndarray:
    """RGBA in [0, 1] of a 16-bit PNG (the file, or its bytes), read by OpenImageIO at 16
    bits. OpenImageIO's Python binding reads only from a path, so bytes (a glTF image in a
    buffer or a data URI) pass through a temporary file."""
    import OpenImageIO as oiio  # a library's import: where it is used

    if data is not None:
        with tempfile.TemporaryDirectory(prefix="raytrace-texture-") as folder:
            copy = Path(folder) / "texture.png"
            copy.write_bytes(data)
            return _png16(copy, None)
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # the PNG's own alpha, not premultiplied
    f = oiio.ImageInput.open(str(file), config)
    if f is None:
        raise OSError(oiio.geterror())
    try:
        codes = f.read_image(oiio.UINT16)
        if codes is None:
            raise OSError(f.geterror())
    finally:
        f.close()
    c = np.asarray(codes, np.float64).reshape(codes.shape[0], codes.shape[1], -1) / 65535.0
    if c.shape[2] <= 2:  # grey (and alpha): the grey in R, G and B
        c = np.concatenate([c[..., :1].repeat(3, axis=2), c[..., 1:]], axis=2)
    return c if c.shape[2] == 4 else np.dstack([c, np.ones(c.shape[:2])])


def _pixels(im: Any) -> np.ndarray:
    """RGBA in [0, 1] from any Pillow image (8 or 16 bits a channel)."""
    if im.mode in ("I;16", "I;16B", "I;16L", "I"):
        grey = np.asarray(im, np.float64) / 65535.0
        return np.dstack([grey, grey, grey, np.ones_like(grey)])
    if im.mode == "F":
        grey = np.asarray(im, np.float64)
        return np.dstack([grey, grey, grey, np.ones_like(grey)])
    return np.asarray(im.convert("RGBA"), np.float64) / 255.0


def parse_texture(table: Mapping, key: str) -> Texture:
    """``{ texture = "file.png", wrap = "repeat" | "clamp" | "mirror", srgb = true, scale }``;
    a relative file is relative to the scene file's folder (the loader makes it so)."""
    values.check_keys(table, TEXTURE_KEYS, key)
    file = Path(values.string(table["texture"], f"{key}.texture"))
    wrap = values.string(table.get("wrap", "repeat"), f"{key}.wrap", WRAPS)
    srgb = values.boolean(table.get("srgb", True), f"{key}.srgb")
    t = Texture.from_file(file, f"{key}.texture", srgb=srgb, wrap=(wrap, wrap))
    if "scale" in table:
        t = t.scaled(values.color(table["scale"], f"{key}.scale"))
    return t


def mtl_texture(file: Path, options: dict, key: str, where: str) -> Texture:
    """An MTL ``map_Kd`` (sRGB; ``-clamp on`` clamps, else repeats)."""
    wrap = options.get("wrap", "repeat")
    return Texture.from_file(file, key, wrap=(wrap, wrap), where=where)
