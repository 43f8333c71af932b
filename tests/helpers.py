"""Small shared helpers for the tests: aiming a one-pixel camera, a scene builder, a
brute-force Möller–Trumbore intersector and a minimal PNG reader and writer.

Nothing here calls the code under test to compute an expected value: the intersector and the
PNG reader are independent references.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

import raytrace

#: The float32 image carries ~7 significant digits.
RTOL = 1e-5


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def aimed_camera(position, target, up=(0.0, 1.0, 0.0), fov: float = 40.0) -> raytrace.Camera:
    """A camera whose 1×1 image's only ray (the pixel centre: the forward direction) goes
    from ``position`` straight through ``target``."""
    position = np.asarray(position, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    up = np.asarray(up, dtype=np.float64)
    if np.linalg.norm(np.cross(unit(target - position), unit(up))) < 1e-6:
        up = np.array([1.0, 0.0, 0.0])
    return raytrace.Camera(position=position, look_at=target, up=up, fov=fov)


def make_scene(objects, lights=(), camera=None, ambient=0.0, materials=None,
               **render) -> raytrace.Scene:
    """A :class:`raytrace.Scene` built in code (``render`` keywords go to RenderSettings)."""
    return raytrace.Scene(camera=camera or raytrace.Camera(), objects=list(objects),
                          lights=list(lights), ambient=ambient, materials=materials or {},
                          render=raytrace.RenderSettings(**render))


def pixel(scene: raytrace.Scene, **kw) -> np.ndarray:
    """The one pixel of a 1×1, spp = 1 render, float64 (3,)."""
    image = raytrace.render(scene, width=1, height=1, spp=1, **kw)
    return image.rgb[0, 0].astype(np.float64)


def moller_trumbore(origins: np.ndarray, directions: np.ndarray, vertices: np.ndarray,
                    faces: np.ndarray) -> dict:
    """Brute-force ray/triangle tests of every ray against every triangle, float64.

    Möller & Trumbore, "Fast, minimum storage ray-triangle intersection" (1997). Returns a dict
    with (n,) arrays: ``t`` (closest hit, inf on a miss), ``tri`` (its triangle, −1 on a miss),
    ``t2`` (the second-closest hit distance), and ``margin``: for a hit, the smallest
    barycentric coordinate of the closest hit (how far inside its triangle it is); for a miss,
    the largest over the triangles in front of the ray of their smallest barycentric (how close
    the ray came to hitting, negative). Rays with ``|margin|`` near 0 graze an edge.
    """
    o = np.asarray(origins, dtype=np.float64)[:, None, :]       # (n, 1, 3)
    d = np.asarray(directions, dtype=np.float64)[:, None, :]
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (T, 3, 3)
    v0, e1, e2 = tri[None, :, 0], (tri[:, 1] - tri[:, 0])[None], (tri[:, 2] - tri[:, 0])[None]
    p = np.cross(d, e2)                                           # (n, T, 3)
    det = np.einsum("ntk,ntk->nt", np.broadcast_to(e1, p.shape), p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - v0
        u = np.einsum("ntk,ntk->nt", s, p) * inv
        q = np.cross(s, np.broadcast_to(e1, s.shape))
        v = np.einsum("ntk,ntk->nt", np.broadcast_to(d, q.shape), q) * inv
        t = np.einsum("ntk,ntk->nt", np.broadcast_to(e2, q.shape), q) * inv
    w = 1.0 - u - v
    bary_min = np.minimum(np.minimum(u, v), w)
    valid = np.isfinite(t) & (det != 0)
    hit = valid & (bary_min >= 0) & (t > 0)
    th = np.where(hit, t, np.inf)
    order = np.argsort(th, axis=1)
    rows = np.arange(len(th))
    best, second = order[:, 0], order[:, 1] if th.shape[1] > 1 else order[:, 0]
    t_best = th[rows, best]
    t_second = th[rows, second] if th.shape[1] > 1 else np.full(len(th), np.inf)
    is_hit = np.isfinite(t_best)
    front = valid & (t > 0)
    miss_margin = np.where(front, bary_min, -np.inf).max(axis=1)
    margin = np.where(is_hit, bary_min[rows, best], miss_margin)
    return {"t": t_best, "tri": np.where(is_hit, best, -1), "t2": t_second, "margin": margin}


def read_png(path: str | Path) -> np.ndarray:
    """(H, W, 3) uint8 pixels of an 8-bit RGB PNG without row filters (what
    :func:`raytrace.film.write_png` writes at 8 bits); a small independent decoder of the PNG
    spec."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG signature"
    pos, idat, width = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, f"bad CRC in {kind!r}"
        if kind == b"IHDR":
            width, height, depth, ctype = struct.unpack(">IIBB", body[:10])
            assert (depth, ctype) == (8, 2), "expected 8-bit RGB"
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, 1 + 3 * width)
    assert not raw[:, 0].any(), "row filters other than None are not supported here"
    return raw[:, 1:].reshape(height, width, 3).copy()


def write_png(path: str | Path, codes: np.ndarray) -> Path:
    """A PNG of ``codes`` (H, W, C) uint8 or uint16, C = 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA,
    written by hand from the PNG spec (§11.2.2 IHDR: colour types 0, 4, 2, 6; samples
    big-endian; each row led by filter byte 0), independent of the readers under test."""
    codes = np.asarray(codes)
    height, width, channels = codes.shape
    depth = 8 * codes.dtype.itemsize
    rows = codes.astype(codes.dtype.newbyteorder(">")).reshape(height, -1).view(np.uint8)
    raw = np.hstack([np.zeros((height, 1), np.uint8), rows]).tobytes()

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    ihdr = struct.pack(">IIBBBBB", width, height, depth, {1: 0, 2: 4, 3: 2, 4: 6}[channels],
                       0, 0, 0)
    Path(path).write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
                           + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    return Path(path)


def read_png_library(path: str | Path):
    """Pixels (H, W, 3) uint8 or uint16 and the ImageSpec of a PNG read back by OpenImageIO,
    the library that writes raytrace's previews."""
    import OpenImageIO as oiio

    f = oiio.ImageInput.open(str(path))
    assert f is not None, oiio.geterror()
    spec = f.spec()
    pixels = f.read_image(spec.format)
    f.close()
    return pixels, spec


def write_text(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path



def write_gltf(path: Path, nodes: list[dict], meshes: list[dict] | None = None,
               materials: list[dict] | None = None, extra: dict | None = None,
               buffer_file: str | None = None) -> Path:
    """A small glTF 2.0 file (JSON, its buffer as a data URI, or in the file ``buffer_file``
    beside it) built by scenes/models/make_models.py's ``write_gltf_doc``, which writes the
    specification's JSON by hand, independent of the loader under test. ``nodes`` and
    ``materials`` are glTF JSON objects as the specification writes them; ``extra`` is merged
    into the top level."""
    import base64
    import importlib.util
    import json

    spec = importlib.util.spec_from_file_location(
        "make_models", Path(__file__).resolve().parent.parent / "scenes/models/make_models.py")
    make_models = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_models)
    doc, blob = make_models.write_gltf_doc(nodes, meshes or [], materials, extra)
    doc["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                + base64.b64encode(blob).decode())
    if buffer_file is not None:
        (path.parent / buffer_file).write_bytes(blob)
        doc["buffers"][0]["uri"] = buffer_file
    path.write_text(json.dumps(doc))
    return path
