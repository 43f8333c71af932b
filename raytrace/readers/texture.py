"""Image textures for a material colour: ``kd = { texture = "wood.png" }``, MTL ``map_Kd``,
glTF ``baseColorTexture``.

A :class:`Texture` reads an image, a :class:`Texels`: linear float32 RGBA (H, W, 4), row 0 at
the top, or an 8- or 16-bit image's codes, kept as they are until a render's material table
decodes them (or a load-time edit asks for floats). sRGB codes are decoded with
colour-science's values (``colour.cctf_decoding(x, function="sRGB")``, IEC 61966-2-1), code by
code through a table (:func:`decoding_table`; at 8 bits the table colour-science gave, stored
in :data:`SRGB8_FILE`), alpha stays linear. The renderer samples it at the hit's
texture coordinates (s, t) (t = 0 at the top row, as in glTF; OBJ's t is flipped on loading)
with bilinear filtering between texel centres (texel (i, j) is at ((i + ½)/W, (j + ½)/H)),
and the wrap mode per axis from :data:`WRAPS` (:func:`raytrace.kernels.core.texture1`). Images are
read with Pillow, but for 16-bit PNGs (grey, grey + alpha, RGB, RGBA): Pillow opens a 16-bit
colour PNG as 8-bit, so those are read by OpenImageIO at the file's 16 bits (a code c is
c / 65535), their alpha kept unassociated as the PNG stores it (PNG spec §12.8).
"""

from __future__ import annotations

import functools
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
TEXTURE_KEYS = ("texture", "wrap", "srgb", "scale", "uv_set", "uv_offset", "uv_rotation",
                "uv_scale")


class Texels:
    """One image's texels, shared by every :class:`Texture` that reads it: linear RGBA float32
    (H, W, 4), or an 8- or 16-bit image's integer codes (H, W, 4) with the tables that decode
    them (``colour`` for R, G and B, ``alpha`` for A: :func:`decoding_table`). Codes are
    decoded the first time :attr:`floats` is asked for (a load-time edit of the texture: a
    factor, an occlusion or alpha map, a mip pyramid); a render's material table decodes
    them itself, straight into its texel array (:func:`raytrace.tables.texel_array`), so a
    model's load does not decode the images the render will."""

    def __init__(self, floats: np.ndarray | None = None, codes: np.ndarray | None = None,
                 colour: np.ndarray | None = None, alpha: np.ndarray | None = None):
        self.codes, self.colour, self.alpha = codes, colour, alpha
        self._floats = floats
        image = floats if floats is not None else codes
        if image.ndim != 3 or image.shape[2] != 4 or 0 in image.shape:
            raise SceneError(f"texels must be (H, W, 4), got {image.shape}", "texture")
        self.shape: tuple[int, int, int] = image.shape

    @property
    def floats(self) -> np.ndarray:
        """The linear RGBA float32 texels (H, W, 4): each colour code through ``colour``, the
        alpha code through ``alpha``, decoded once."""
        if self._floats is None:
            self._floats = np.take(self.colour, self.codes)
            self._floats[..., 3] = np.take(self.alpha, self.codes[..., 3])
        return self._floats

    @property
    def nbytes(self) -> int:
        """The bytes it keeps (and pickles): its codes, or its float texels."""
        return (self.codes if self.codes is not None else self._floats).nbytes

    def __getstate__(self) -> dict:
        """Pickled without the float texels where the codes make them again."""
        return {**self.__dict__, "_floats": None if self.codes is not None else self._floats}

    @property
    def decoded(self) -> bool:
        """Whether the float texels exist (given, or decoded already)."""
        return self._floats is not None

    @functools.cached_property
    def max(self) -> np.ndarray:
        """The largest value of each colour channel (3,) float64, found once; for codes the
        table's value at the largest code (the tables increase with the code)."""
        if self._floats is None:
            return np.array([self.colour[self.codes[..., c].max()] for c in range(3)],
                            np.float64)
        return np.array([self._floats[..., c].max() for c in range(3)], np.float64)


class Texture:
    """An image as a colour: its texels (:attr:`texels`, linear RGBA (H, W, 4) float32), wrap
    modes, and its mapping: which texture-coordinate set it reads (``uv_set``: 0 the mesh's
    first, 1 a glTF TEXCOORD_1) and an affine ``transform`` (2, 3) of those coordinates,
    ``(s', t') = M · (s, t, 1)``, or None for the identity (:meth:`mapped`). Its :attr:`image`
    (a :class:`Texels`) is shared with the textures that read the same image another way."""

    uv_set: int = 0
    transform: np.ndarray | None = None

    def __init__(self, texels: np.ndarray | Texels, wrap: tuple[str, str] = ("repeat", "repeat"),
                 file: Path | None = None):
        self.image = (texels if isinstance(texels, Texels)
                      else Texels(np.ascontiguousarray(texels, np.float32)))
        self.wrap = tuple(values.string(w, "wrap", WRAPS) for w in wrap)
        self.file = file

    @property
    def texels(self) -> np.ndarray:
        """The linear RGBA float32 texels (H, W, 4) (:attr:`Texels.floats`)."""
        return self.image.floats

    def mapped(self, uv_set: int = 0, transform: Any = None) -> Texture:
        """The same image (its texels shared, stored once in the material table) read through
        another mapping; ``transform`` (2, 3), or None (or the identity) for none. Itself
        where the mapping is the one it has."""
        if transform is not None:
            transform = np.asarray(transform, np.float64).reshape(2, 3)
            if np.array_equal(transform, IDENTITY):
                transform = None
        if uv_set == self.uv_set and (transform is None and self.transform is None or (
                transform is not None and self.transform is not None
                and np.array_equal(transform, self.transform))):
            return self
        out = Texture(self.image, self.wrap, self.file)
        out.uv_set, out.transform = uv_set, transform
        return out

    def _like(self, texels: np.ndarray) -> Texture:
        """New texels, this texture's wrap, file and mapping."""
        return Texture(texels, self.wrap, self.file).mapped(self.uv_set, self.transform)

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
                codes, bits = _png16(file, data), 16
            else:
                with Image.open(io.BytesIO(data) if data is not None else file) as im:
                    im.load()
                    codes, bits = _pixels(im)
        except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError) as e:
            raise SceneError(f"cannot read texture {file}: {e}", key, where) from None
        if bits is None:  # float values (Pillow's "I" and "F" modes)
            image = Texels(codes.astype(np.float32))
            if srgb:
                image.floats[..., :3] = quiet_colour().cctf_decoding(codes[..., :3],
                                                                     function="sRGB")
        else:  # integer codes: each colour through its decoded value, alpha c / (2^bits − 1)
            image = Texels(codes=np.ascontiguousarray(codes),
                           colour=decoding_table(bits, srgb), alpha=decoding_table(bits, False))
        return cls(image, wrap, Path(file) if data is None else None)

    def scaled(self, factor: Any) -> Texture:
        """The texture times a colour (glTF's baseColorFactor), alpha kept; the texture itself
        for a factor of 1 (no copy, so a material's colour and alpha can share it)."""
        factor = np.asarray(factor, np.float32)
        if np.all(factor == 1):
            return self
        t = self.texels.copy()
        t[..., :3] *= factor
        return self._like(t)

    def as_alpha(self) -> Texture:
        """A scalar texture (MTL ``map_d``) as an alpha texture: its alpha where the image
        has one that is not all 1, else its luminance Y = 0.2126·R + 0.7152·G + 0.0722·B
        (ITU-R BT.709; the MTL spec's default channel for a scalar texture, ``-imfchan l``);
        its colour white."""
        t = np.ones_like(self.texels)
        a = self.texels[..., 3]
        t[..., 3] = a if np.any(a < 1) else self.texels[..., :3] @ np.float32(
            [0.2126, 0.7152, 0.0722])
        return self._like(t)

    def occlusion(self, strength: float) -> Texture:
        """An ambient-occlusion map as the factor it multiplies the ambient term by, ``1 +
        strength·(R − 1)`` in R, G and B (glTF 2.0 §3.9.3, occlusionTexture: "the occlusion
        values are linearly sampled from the R channel", ``1.0 + strength * (occlusion -
        1.0)``); alpha 1. Linear in R, so bilinear filtering of the factor is filtering of R."""
        t = np.ones_like(self.texels)
        t[..., :3] = (1.0 + strength * (self.texels[..., :1] - 1.0))
        return self._like(t)

    @property
    def max(self) -> np.ndarray:
        """The largest value of each colour channel (3,) float64, found once: a texture's
        texels are not edited after it is made (the material table asks for it at every
        build)."""
        return self.image.max


#: A mapping's identity transform (2, 3): (s', t') = (s, t).
IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

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
    """RGBA codes (H, W, 4) uint16 of a 16-bit PNG (the file, or its bytes), read by
    OpenImageIO at 16 bits. OpenImageIO's Python binding reads only from a path, so bytes
    (a glTF image in a buffer or a data URI) pass through a temporary file."""
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
    return _rgba(codes.reshape(codes.shape[0], codes.shape[1], -1), 65535)


def _rgba(c: np.ndarray, opaque: Any) -> np.ndarray:
    """(H, W, 4) from grey (1), grey and alpha (2), RGB (3) or RGBA (4) channels: grey in R,
    G and B; ``opaque`` as the alpha where there is none."""
    if c.shape[2] <= 2:
        c = np.concatenate([c[..., :1].repeat(3, axis=2), c[..., 1:]], axis=2)
    if c.shape[2] == 3:
        c = np.concatenate([c, np.full((*c.shape[:2], 1), opaque, c.dtype)], axis=2)
    return c


def _pixels(im: Any) -> tuple[np.ndarray, int | None]:
    """RGBA (H, W, 4) from any Pillow image: integer codes and their bits (8 or 16), or floats
    in [0, 1] and None (32-bit "I" read as 16-bit codes, "F")."""
    if im.mode in ("I;16", "I;16B", "I;16L"):
        return _rgba(np.asarray(im, np.uint16)[..., None], 65535), 16
    if im.mode in ("I", "F"):
        scale = 65535.0 if im.mode == "I" else 1.0
        return _rgba(np.asarray(im, np.float64)[..., None] / scale, 1.0), None
    return np.asarray(im.convert("RGBA")), 8


#: sRGB codes 0..255 decoded to linear by colour-science, one value a line, as
#: :func:`srgb_decoding` gives them (``np.savetxt(SRGB8_FILE, srgb_decoding(8), fmt="%.17g")``;
#: tests/test_texture.py checks that they still are): importing colour-science takes
#: longer (2.7 s) than reading a textured model, so 8-bit images are decoded without it.
SRGB8_FILE = Path(__file__).with_name("srgb8.txt")


def srgb_decoding(bits: int) -> np.ndarray:
    """The linear values (2^bits,) float64 of the sRGB codes c = 0 … 2^bits − 1 at
    ``bits`` bits: colour-science's ``cctf_decoding(c / (2^bits − 1), function="sRGB")``
    (IEC 61966-2-1)."""
    codes = np.arange(2**bits) / (2.0**bits - 1)
    return quiet_colour().cctf_decoding(codes, function="sRGB")


@functools.cache
def decoding_table(bits: int, srgb: bool) -> np.ndarray:
    """float32 value of each code at ``bits`` bits: sRGB-decoded (:data:`SRGB8_FILE` at 8
    bits, :func:`srgb_decoding` at 16), or c / (2^bits − 1) read as linear."""
    if not srgb:
        values = np.arange(2**bits) / (2.0**bits - 1)
    else:
        values = np.loadtxt(SRGB8_FILE) if bits == 8 else srgb_decoding(bits)
    return values.astype(np.float32)


def uv_transform(offset: Any, rotation: float, scale: Any) -> np.ndarray:
    """The affine map (2, 3) of (s, t) by glTF KHR_texture_transform's T·R·S: scale
    (kₛ, kₜ), then rotate by ``rotation`` radians counter-clockwise as the image is seen (t
    runs down it), then offset (oₛ, oₜ)::

        s' = kₛ·cos r·s + kₜ·sin r·t + oₛ
        t' = −kₛ·sin r·s + kₜ·cos r·t + oₜ

    R = [[cos r, sin r], [−sin r, cos r]] is the matrix of the extension's own example
    (offset (0, 1), rotation π/2, scale ½ read "the lower left quadrant of the source image,
    rotated clockwise 90°") and of CesiumGltf's ``KhrTextureTransform::applyTransform``; the
    README's GLSL, read as GLSL's column-major constructors, would be its transpose.

    >>> uv_transform((0.0, 1.0), np.pi / 2, (0.5, 0.5)).round(12).tolist()
    [[0.0, 0.5, 0.0], [-0.5, 0.0, 1.0]]
    """
    (ox, oy), (kx, ky) = offset, scale
    c, s = np.cos(rotation), np.sin(rotation)
    return np.array([[kx * c, ky * s, ox], [-kx * s, ky * c, oy]])


def parse_texture(table: Mapping, key: str) -> Texture:
    """``{ texture = "file.png", wrap = "repeat" | "clamp" | "mirror", srgb = true, scale,
    uv_set = 0, uv_offset = [0, 0], uv_rotation = 0, uv_scale = [1, 1] }`` (the mapping of
    :func:`uv_transform`, the rotation in degrees); a relative file is relative to the scene
    file's folder (the loader makes it so)."""
    values.check_keys(table, TEXTURE_KEYS, key)
    file = Path(values.string(table["texture"], f"{key}.texture"))
    wrap = values.string(table.get("wrap", "repeat"), f"{key}.wrap", WRAPS)
    srgb = values.boolean(table.get("srgb", True), f"{key}.srgb")
    t = Texture.from_file(file, f"{key}.texture", srgb=srgb, wrap=(wrap, wrap))
    if "scale" in table:
        t = t.scaled(values.color(table["scale"], f"{key}.scale"))
    return t.mapped(*parse_mapping(table, key))


def parse_mapping(table: Mapping, key: str) -> tuple[int, np.ndarray | None]:
    """A texture table's mapping, ``uv_set = 0``, ``uv_offset = [0, 0]``, ``uv_rotation = 0``
    (degrees), ``uv_scale = [1, 1]``: the uv set and the :func:`uv_transform` (None where no
    ``uv_*`` key is given), as :meth:`Texture.mapped` takes them (colour textures and
    normal and height maps alike)."""
    transform = None
    if {"uv_offset", "uv_rotation", "uv_scale"} & table.keys():
        transform = uv_transform(
            values.vector(table.get("uv_offset", [0.0, 0.0]), f"{key}.uv_offset", 2),
            np.radians(values.number(table.get("uv_rotation", 0.0), f"{key}.uv_rotation")),
            values.vector(table.get("uv_scale", [1.0, 1.0]), f"{key}.uv_scale", 2))
    uv_set = values.number(table.get("uv_set", 0), f"{key}.uv_set", lo=0, hi=1, integer=True)
    return uv_set, transform


def mtl_texture(file: Path, options: dict, key: str, where: str) -> Texture:
    """An MTL map (``key``: ``map_Kd``, ``map_Ke``, sRGB colours; ``map_d``, a scalar read as
    linear, :meth:`Texture.as_alpha`; ``options["srgb"]`` False: codes read as linear, as
    ``norm`` and ``bump`` are): ``-clamp on`` clamps, else repeats; ``-o`` and ``-s`` as its
    mapping (:func:`mtl_transform`)."""
    wrap = options.get("wrap", "repeat")
    scalar = key == "map_d"
    t = Texture.from_file(file, key, wrap=(wrap, wrap), where=where,
                          srgb=options.get("srgb", not scalar))
    if scalar:
        t = t.as_alpha()
    return t.mapped(0, mtl_transform(options.get("offset", (0.0, 0.0)),
                                     options.get("scale", (1.0, 1.0))))


def mtl_transform(offset: Any, scale: Any) -> np.ndarray:
    """The affine map (2, 3) of raytrace's (s, t) of MTL ``-o u v`` and ``-s u v`` (Wavefront
    MTL, "Options for texture map statements": -o shifts the map's origin, -s scales the
    map): in OBJ's (u, v) ``(u', v') = (sᵤ·u + oᵤ, sᵥ·v + oᵥ)``; OBJ's v runs up the image
    and raytrace's t = 1 − v down it, so ``s' = sᵤ·s + oᵤ``, ``t' = sᵥ·t + 1 − sᵥ − oᵥ``.

    >>> mtl_transform((0.5, 0.25), (2.0, 1.0)).tolist()
    [[2.0, 0.0, 0.5], [0.0, 1.0, -0.25]]
    """
    (ou, ov), (su, sv) = offset, scale
    return np.array([[su, 0.0, ou], [0.0, sv, 1.0 - sv - ov]])
