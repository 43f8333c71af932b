"""Generate ``scenes/normal_mapped.glb``, a normal-mapped glTF model alone (run from anywhere):

    python3 scenes/models/make_normal_mapped.py

A UV sphere (32 rings × 64 segments, NORMAL = the position, TANGENT = the analytic ∂P/∂s
with w = +1) whose ``normalTexture`` embosses a pattern of bricks: a height field of raised
bricks with bevelled edges and mortar grooves, 16 around and 12 rows from pole to pole, turned
into a tangent-space normal map by its finite differences. Its base colour is a constant
terracotta (roughness 0.55), so every bit of relief in the picture comes from the map.

The sphere, with u = s and t the glTF texture coordinates (t = 0 at the image's top), is

    P(θ, φ) = (−sin θ·sin φ, cos θ, −sin θ·cos φ),   s = φ/2π,  t = θ/π,

so the seam (s = 0 and 1) lies at the back (−z) and ``∂P/∂s`` points to the right (+x)
seen from the front (+z), the default camera's side. A height field h(x, y) over the
image (x along s, y down t) gives the tangent-space normal ``n_t ∝ (−k·∂h/∂x, +k·∂h/∂y, 1)``
(+Y of a normal map is up the image, glTF 2.0 §3.9.3, while y runs down), stored as
``(n_t + 1)/2`` in 8-bit codes. The output is deterministic: re-running it reproduces the
committed file. tests/test_gltf.py renders the model with and without its TANGENT.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "normal_mapped.glb"


def _make_models():
    """scenes/models/make_models.py (its glTF writer and PNG encoder)."""
    spec = importlib.util.spec_from_file_location("make_models", HERE / "make_models.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def sphere(rings: int = 32, segments: int = 64):
    """Positions (V, 3), normals, texture coordinates (V, 2), tangents (V, 4) and faces
    (F, 3), counter-clockwise from outside, without the zero-area triangles at the poles."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2 * np.pi, segments + 1)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([-np.sin(th) * np.sin(ph), np.cos(th), -np.sin(th) * np.cos(ph)], -1)
    uv = np.stack([ph / (2 * np.pi), th / np.pi], -1)
    # ∂P/∂φ = sin θ·(−cos φ, 0, sin φ): its direction, w = +1 (B = N × T = ∂P/∂v, v = −t)
    tangent = np.stack([-np.cos(ph), np.zeros_like(ph), np.sin(ph), np.ones_like(ph)], -1)
    index = np.arange(th.size).reshape(th.shape)
    faces = []
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = index[i, j], index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]
            if i < rings - 1:
                faces.append([a, b, c])
            if i > 0:
                faces.append([a, c, d])
    pos = pos.reshape(-1, 3)
    return pos, pos.copy(), uv.reshape(-1, 2), tangent.reshape(-1, 4), np.array(faces)


def bricks(width: int = 512, height: int = 256, columns: int = 16, rows: int = 12,
           bevel: float = 5.0) -> np.ndarray:
    """The height field (height, width) in [0, 1]: bricks (every other row shifted by half a
    brick) whose height rises over ``bevel`` texels from their edges, 0 in the grooves."""
    y, x = np.mgrid[0:height, 0:width] + 0.5
    bw, bh = width / columns, height / rows
    row = np.floor(y / bh)
    xs = (x + (row % 2) * bw / 2) % bw
    ys = y % bh
    edge = np.minimum(np.minimum(xs, bw - xs), np.minimum(ys, bh - ys))
    return np.clip((edge - 1.5) / bevel, 0.0, 1.0)


def normal_map(h: np.ndarray, strength: float = 2.5) -> np.ndarray:
    """8-bit RGB codes (H, W, 3) of the tangent-space normals of height field ``h`` (module
    docstring), central differences with the image wrapping around in s."""
    dx = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) / 2
    dy = (np.vstack([h[1:], h[-1:]]) - np.vstack([h[:1], h[:-1]])) / 2
    n = np.stack([-strength * dx, strength * dy, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n + 1) / 2 * 255).astype(np.uint8)


def normal_mapped(tangents: bool = True) -> tuple[dict, bytes]:
    """The glTF document and its buffer (``tangents`` False: without the TANGENT attribute,
    so a reader must make MikkTSpace's)."""
    mm = _make_models()
    pos, normals, uv, tangent, faces = sphere()
    mesh = {"positions": pos, "normals": normals, "uv": uv, "indices": faces, "material": 0,
            "tangents": tangent if tangents else None}
    materials = [{"name": "embossed terracotta",
                  "pbrMetallicRoughness": {"baseColorFactor": [0.72, 0.33, 0.2, 1.0],
                                           "metallicFactor": 0.0, "roughnessFactor": 0.55},
                  "normalTexture": {"index": 0, "scale": 1.0}}]
    extra = {"textures": [{"source": 0, "sampler": 0}],
             "samplers": [{"wrapS": 10497, "wrapT": 33071}]}
    doc, blob = mm.write_gltf_doc([{"name": "ball", "mesh": 0}], [mesh], materials, extra,
                                  images=[mm.png_bytes(normal_map(bricks()))])
    doc["asset"]["extras"] = {"description": [
        "A normal-mapped glTF model alone, no TOML, no camera, no light: a smooth UV sphere",
        "(3,968 triangles) whose normalTexture embosses bevelled bricks; the base colour is",
        "constant, so all the relief is the map's (tangent frames from its TANGENT attribute;",
        "without it, MikkTSpace's). The default camera and light. Made by",
        "scenes/models/make_normal_mapped.py.",
        "Shows: glTF normalTexture, TANGENT, a model file rendered with the defaults.",
        "Render: raytrace render scenes/normal_mapped.glb -o normal_mapped.exr"]}
    return doc, blob


def main() -> None:
    _make_models().write_glb(OUT, *normal_mapped())
    print(f"{OUT}: {OUT.stat().st_size} bytes")


if __name__ == "__main__":
    main()
