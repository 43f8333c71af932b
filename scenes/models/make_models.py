"""Generate the mesh files used by the example scenes (run from anywhere):

    python3 scenes/models/make_models.py

Writes, next to this script:

* ``torus_knot.ply`` — a (2, 3) torus knot (the trefoil) swept as a round tube along the curve
  with its Frenet frame; 8 192 triangles, binary PLY. Used by ``scenes/mesh_model.toml``.
* ``icosphere.obj`` — a once-subdivided icosahedron (80 triangles, trimesh's ``icosphere``), low
  enough in polygons that flat, smooth (Phong) and Gouraud shading look clearly different.
  Used by ``scenes/flat_vs_smooth.toml``.
* ``torus.obj`` — a coarse torus (24 × 12 sections, trimesh's ``torus``), also for
  ``scenes/flat_vs_smooth.toml``.

The output is deterministic (no random numbers), so re-running it reproduces the committed files.
The (p, q) torus knot winds p times around the z axis and q times through the hole:

    r(s) = ((R + cos(q·s))·cos(p·s), (R + cos(q·s))·sin(p·s), −sin(q·s)),  s ∈ [0, 2π),

with R = 2. The tube of radius ρ around it is ``r(s) + ρ·(cos φ·N(s) + sin φ·B(s))``, where N and
B are the principal normal and binormal of the Frenet frame (T = r'/|r'|, B = r'×r''/|r'×r''|,
N = B×T). The curvature of a torus knot never vanishes, so the frame is defined everywhere and
closes on itself without a twist at the seam.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def torus_knot_curve(s: np.ndarray, p: int = 2, q: int = 3, big_r: float = 2.0):
    """Points r(s), first and second derivatives, each (n, 3), of the (p, q) torus knot."""
    cq, sq, cp, sp = np.cos(q * s), np.sin(q * s), np.cos(p * s), np.sin(p * s)
    rho = big_r + cq
    r = np.column_stack([rho * cp, rho * sp, -sq])
    # d/ds of each component (product rule), then the second derivative.
    d1 = np.column_stack([-q * sq * cp - p * rho * sp, -q * sq * sp + p * rho * cp, -q * cq])
    d2 = np.column_stack([
        -q * q * cq * cp + 2 * p * q * sq * sp - p * p * rho * cp,
        -q * q * cq * sp - 2 * p * q * sq * cp - p * p * rho * sp,
        q * q * sq,
    ])
    return r, d1, d2


def tube(curve_pts: np.ndarray, d1: np.ndarray, d2: np.ndarray, radius: float,
         sides: int) -> trimesh.Trimesh:
    """A closed tube of ``radius`` around a closed curve sampled at ``len(curve_pts)`` points.

    Faces wind counter-clockwise seen from outside (outward normals).
    """
    n = len(curve_pts)
    t = d1 / np.linalg.norm(d1, axis=1, keepdims=True)
    b = np.cross(d1, d2)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    nrm = np.cross(b, t)
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(phi)[None, :, None] * nrm[:, None, :] + np.sin(phi)[None, :, None] * b[:, None]
    verts = (curve_pts[:, None, :] + radius * ring).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(sides), indexing="ij")
    a = i * sides + j
    b_ = ((i + 1) % n) * sides + j
    c = ((i + 1) % n) * sides + (j + 1) % sides
    d = i * sides + (j + 1) % sides
    faces = np.concatenate([np.stack([a, b_, c], -1).reshape(-1, 3),
                            np.stack([a, c, d], -1).reshape(-1, 3)])
    mesh = trimesh.Trimesh(verts, faces, process=False)
    # The (N, B) frame may be left- or right-handed relative to T: make the winding outward.
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def torus_knot(segments: int = 256, sides: int = 16, radius: float = 0.4) -> trimesh.Trimesh:
    s = 2 * np.pi * np.arange(segments) / segments
    r, d1, d2 = torus_knot_curve(s)
    return tube(r, d1, d2, radius, sides)


def main() -> None:
    knot = torus_knot()
    assert knot.is_watertight and knot.is_winding_consistent and knot.volume > 0
    knot.export(HERE / "torus_knot.ply", encoding="binary")

    ico = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    ico.export(HERE / "icosphere.obj", include_normals=False, include_texture=False,
               digits=6, header=None)

    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.4, major_sections=24,
                                   minor_sections=12)
    torus.export(HERE / "torus.obj", include_normals=False, include_texture=False,
                 digits=6, header=None)

    for name in ("torus_knot.ply", "icosphere.obj", "torus.obj"):
        path = HERE / name
        m = trimesh.load(path, process=False)
        print(f"{name}: {len(m.vertices)} vertices, {len(m.faces)} faces, "
              f"{path.stat().st_size / 1024:.1f} KiB")


if __name__ == "__main__":
    main()
