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
* ``still_life.obj`` + ``still_life.mtl`` + ``tiles.png`` — an OBJ with its MTL: a tiled floor
  (``map_Kd``) and four balls in illum 2 (plastic), 3 (mirror), 5 (Fresnel reflection) and 7
  (Fresnel glass). Used by ``scenes/obj_mtl.toml``.
* ``../gltf_scene.glb`` — a glTF scene alone: camera, a point and a spot light
  (KHR_lights_punctual), a textured crate under a rotated and scaled parent node, a gold, a
  glass and a plastic ball on a floor; rendered by ``raytrace render scenes/gltf_scene.glb``.

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


def write_gltf_doc(nodes: list[dict], meshes: list[dict], materials: list[dict] | None = None,
                   extra: dict | None = None, images: list[bytes] = ()) -> tuple[dict, bytes]:
    """A glTF 2.0 document (JSON as a dict) and its one binary buffer. ``meshes``:
    ``{"positions": (n, 3), "indices": (m, 3), "uv": (n, 2) or None, "material": index or
    None}`` (and ``"normals": (n, 3)`` for a NORMAL attribute, ``"tangents": (n, 4)`` for a
    TANGENT one, ``"uv1": (n, 2)`` for TEXCOORD_1, ``"colors": (n, 3 or 4)`` float or uint8
    for COLOR_0); ``images``: PNG bytes stored
    in buffer views; nodes with ``"_child": True`` are not scene roots."""
    blob = b""
    accessors, views, gl_meshes = [], [], []

    def view(data: bytes, target: int | None) -> int:
        nonlocal blob
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        if target:
            views[-1]["target"] = target
        blob += data + b"\0" * (-len(data) % 4)
        return len(views) - 1

    def add(array: np.ndarray, kind: str, ctype: int, target: int) -> int:
        acc = {"bufferView": view(np.ascontiguousarray(array).tobytes(), target),
               "componentType": ctype, "count": len(array), "type": kind}
        if kind == "VEC3":
            acc.update(min=array.min(axis=0).tolist(), max=array.max(axis=0).tolist())
        accessors.append(acc)
        return len(accessors) - 1

    for m in meshes:
        attrs = {"POSITION": add(np.asarray(m["positions"], np.float32), "VEC3", 5126, 34962)}
        if m.get("uv") is not None:
            attrs["TEXCOORD_0"] = add(np.asarray(m["uv"], np.float32), "VEC2", 5126, 34962)
        if m.get("normals") is not None:
            attrs["NORMAL"] = add(np.asarray(m["normals"], np.float32), "VEC3", 5126, 34962)
        if m.get("tangents") is not None:
            attrs["TANGENT"] = add(np.asarray(m["tangents"], np.float32), "VEC4", 5126, 34962)
        if m.get("uv1") is not None:
            attrs["TEXCOORD_1"] = add(np.asarray(m["uv1"], np.float32), "VEC2", 5126, 34962)
        if m.get("colors") is not None:  # float, or uint8 codes as normalised integers
            c = np.asarray(m["colors"])
            byte = c.dtype == np.uint8
            attrs["COLOR_0"] = add(c if byte else c.astype(np.float32), f"VEC{c.shape[1]}",
                                   5121 if byte else 5126, 34962)
            if byte:
                accessors[-1]["normalized"] = True
        idx = add(np.asarray(m["indices"], np.uint32).reshape(-1), "SCALAR", 5125, 34963)
        prim = {"attributes": attrs, "indices": idx}
        if m.get("material") is not None:
            prim["material"] = m["material"]
        gl_meshes.append({"primitives": [prim]})
    roots = [i for i, n in enumerate(nodes) if not n.pop("_child", False)]
    doc = {"asset": {"version": "2.0", "generator": "raytrace scenes/models/make_models.py"},
           "scene": 0, "scenes": [{"nodes": roots}], "nodes": nodes, "meshes": gl_meshes,
           "accessors": accessors, "bufferViews": views}
    if images:
        doc["images"] = [{"bufferView": view(png, None), "mimeType": "image/png"}
                         for png in images]
    doc["buffers"] = [{"byteLength": len(blob)}]
    if materials:
        doc["materials"] = materials
    doc.update(extra or {})
    return doc, blob


def write_glb(path: Path, doc: dict, blob: bytes) -> None:
    """A GLB file (one JSON chunk and one binary chunk) written with pygltflib."""
    import json

    import pygltflib

    gltf = pygltflib.GLTF2().from_json(json.dumps(doc))
    gltf.set_binary_blob(blob)
    gltf.save_binary(str(path))


def png_bytes(rgb: np.ndarray) -> bytes:
    import io

    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(np.asarray(rgb, np.uint8)).save(out, format="PNG", optimize=True)
    return out.getvalue()


def tiles(n: int = 64, cells: int = 4) -> np.ndarray:
    """An n×n sRGB image of cells×cells terracotta tiles with light grout lines."""
    x = (np.arange(n) + 0.5) * cells / n
    fx, fy = np.meshgrid(x - np.floor(x), x - np.floor(x))
    grout = (np.minimum(fx, 1 - fx) < 0.06) | (np.minimum(fy, 1 - fy) < 0.06)
    shade = 0.85 + 0.15 * np.cos(2 * np.pi * (np.floor(x)[None, :] + np.floor(x)[:, None]) / 3)
    rgb = np.stack([200 * shade, 105 * shade, 70 * shade], axis=-1)
    rgb[grout] = (225, 220, 205)
    return np.round(rgb).astype(np.uint8)


def crate(n: int = 64) -> np.ndarray:
    """An n×n sRGB image of a wooden crate face: planks with a dark frame and a diagonal."""
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    plank = 0.8 + 0.2 * np.cos(2 * np.pi * (4 * y + 0.3 * np.sin(9 * x)))
    rgb = np.stack([180 * plank, 130 * plank, 75 * plank], axis=-1)
    frame = (np.minimum(np.minimum(x, 1 - x), np.minimum(y, 1 - y)) < 0.1) | (np.abs(x - y) < 0.06)
    rgb[frame] = (95, 60, 30)
    return np.round(rgb).astype(np.uint8)


def sphere(center, radius: float, subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    ico = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(ico.vertices) + center, np.asarray(ico.faces)


def cube_faces() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A unit cube |x|, |y|, |z| ≤ ½ with 4 vertices a face and uv (0..1) on every face."""
    pos, uv, idx = [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.roll(n, 1) if sign > 0 else -np.roll(n, 1)
            v = np.cross(n, u)
            k = len(pos)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos.append(0.5 * (n + a * u + b * v))
                uv.append(((a + 1) / 2, (1 - b) / 2))
            idx += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
    return np.array(pos), np.array(idx), np.array(uv)


def still_life_obj() -> tuple[str, str]:
    """The OBJ and MTL text of the still life (6 decimals)."""
    groups = [("floor", *floor_quad(6.0, 4.0))]
    for name, center, r in (("plastic", (-2.4, 0.6, 0.0), 0.6), ("mirror", (-0.8, 0.6, -0.4), 0.6),
                            ("fresnel", (0.8, 0.6, -0.4), 0.6), ("glass", (2.4, 0.6, 0.0), 0.6)):
        v, f = sphere(np.array(center), r)
        groups.append((name, v, f, None))
    lines, offset = ["mtllib still_life.mtl"], 0
    for name, v, f, uv in groups:
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
        if uv is not None:
            lines += [f"vt {s:.6f} {t:.6f}" for s, t in uv]
        lines += [f"usemtl {name}"]
        fmt = "f {0}/{0} {1}/{1} {2}/{2}" if uv is not None else "f {0} {1} {2}"
        lines += [fmt.format(*(f_ + offset + 1)) for f_ in f]
        offset += len(v)
    mtl = """# illum 1 with a texture, 2 plastic, 3 mirror, 5 Fresnel reflection, 7 Fresnel glass
newmtl floor
Kd 1 1 1
Ka 0.4 0.4 0.4
illum 1
map_Kd tiles.png

newmtl plastic
Kd 0.05 0.25 0.6
Ks 0.6 0.6 0.6
Ns 120
illum 2

newmtl mirror
Kd 0.05 0.05 0.05
Ks 0.85 0.85 0.85
Ns 400
illum 3

newmtl fresnel
Kd 0.5 0.06 0.04
Ks 0.04 0.04 0.04
Ns 200
illum 5

newmtl glass
Kd 0 0 0
Ks 0.5 0.5 0.5
Ns 300
Ni 1.5
Tf 0.85 1 0.9
illum 7
"""
    return "\n".join(lines) + "\n", mtl


def floor_quad(half: float, repeats: float):
    """The square y = 0, |x|, |z| ≤ half, facing +y, with uv repeating ``repeats`` times."""
    v = np.array([[-half, 0, half], [half, 0, half], [half, 0, -half], [-half, 0, -half]])
    uv = np.array([[0, 0], [repeats, 0], [repeats, repeats], [0, repeats]])
    return v, np.array([[0, 1, 2], [0, 2, 3]]), uv


def gltf_scene() -> tuple[dict, bytes]:
    """The glTF scene: camera, two lights, a crate in a node hierarchy, three balls, a floor."""
    box_v, box_f, box_uv = cube_faces()
    floor_v, floor_f, floor_uv = floor_quad(5.0, 5.0)
    floor_uv = floor_uv[:, ::-1] * [1, -1] + [0, 1]  # glTF's t runs down
    gold_v, gold_f = sphere(np.zeros(3), 0.55)
    meshes = [{"positions": box_v, "indices": box_f, "uv": box_uv, "material": 0},
              {"positions": floor_v, "indices": floor_f, "uv": floor_uv, "material": 1},
              {"positions": gold_v, "indices": gold_f, "material": 2},
              {"positions": gold_v, "indices": gold_f, "material": 3},
              {"positions": gold_v, "indices": gold_f, "material": 4}]
    pbr = "pbrMetallicRoughness"
    materials = [
        {"name": "crate", pbr: {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                "roughnessFactor": 0.8}},
        {"name": "floor", pbr: {"baseColorFactor": [0.8, 0.8, 0.8, 1],
                                "baseColorTexture": {"index": 1}, "metallicFactor": 0.0,
                                "roughnessFactor": 0.6}},
        {"name": "gold", pbr: {"baseColorFactor": [1.0, 0.78, 0.34, 1], "metallicFactor": 1.0,
                               "roughnessFactor": 0.0}},
        {"name": "glass", pbr: {"baseColorFactor": [0.9, 1.0, 0.95, 1], "metallicFactor": 0.0,
                                "roughnessFactor": 0.0},
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_ior": {"ior": 1.5},
                        # a closed ball (its diameter): it refracts; no volume = thin-walled
                        "KHR_materials_volume": {"thicknessFactor": 1.1}}},
        {"name": "red_plastic", pbr: {"baseColorFactor": [0.7, 0.05, 0.04, 1],
                                      "metallicFactor": 0.0, "roughnessFactor": 0.35}},
    ]
    half = np.sqrt(0.5)
    nodes = [
        {"name": "camera", "translation": [0.0, 2.2, 6.5], "camera": 0,
         "rotation": [float(np.sin(np.radians(-9))), 0.0, 0.0, float(np.cos(np.radians(-9)))]},
        {"name": "floor", "mesh": 1},
        # a parent turned 30° about y and scaled 1.2: the crate is its child
        {"name": "stack", "translation": [-1.6, 0.0, -0.6], "scale": [1.2, 1.2, 1.2],
         "rotation": [0.0, float(np.sin(np.radians(15))), 0.0, float(np.cos(np.radians(15)))],
         "children": [3]},
        {"name": "crate", "translation": [0.0, 0.5, 0.0], "mesh": 0, "_child": True},
        {"name": "gold", "translation": [0.3, 0.55, 0.4], "mesh": 2},
        {"name": "glass", "translation": [1.6, 0.55, 0.9], "mesh": 3},
        {"name": "plastic", "translation": [2.0, 0.55, -1.2], "mesh": 4},
        {"name": "lamp", "translation": [3.0, 5.0, 4.0],
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "spot", "translation": [-2.0, 4.0, 2.0],
         "rotation": [float(-np.sin(np.radians(32))) * half, 0.0,
                      float(np.sin(np.radians(32))) * half, float(np.cos(np.radians(32)))],
         "extensions": {"KHR_lights_punctual": {"light": 1}}},
    ]
    extra = {
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.7, "aspectRatio": 4 / 3, "znear": 0.1}}],
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission",
                           "KHR_materials_ior", "KHR_materials_volume"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.95, 0.85], "intensity": 40.0},
            {"type": "spot", "color": [0.7, 0.8, 1.0], "intensity": 25.0,
             "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.6}}]}},
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}],
    }
    doc, blob = write_gltf_doc(nodes, meshes, materials, extra,
                               images=[png_bytes(crate()), png_bytes(tiles(64, 4))])
    doc["asset"]["extras"] = {"description": [
        "A glTF scene alone, no TOML: its own camera (yfov 0.7 rad, aspect 4:3), a point and a",
        "spot light (KHR_lights_punctual), a textured crate (baseColorTexture) that is the child",
        "of a rotated and scaled node, a polished gold ball (metallic 1, roughness 0: a tinted",
        "mirror), a glass ball (KHR_materials_transmission + ior + volume: refracting Fresnel",
        "glass) and a red plastic ball (roughness 0.35) on a tiled floor. Made by",
        "scenes/models/make_models.py.",
        "Shows: raytrace render on a GLB, the glTF material mapping, textures, KHR lights.",
        "Render: raytrace render scenes/gltf_scene.glb -o gltf_scene.exr --png gltf_scene.png"]}
    return doc, blob


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

    obj, mtl = still_life_obj()
    (HERE / "still_life.obj").write_text(obj)
    (HERE / "still_life.mtl").write_text(mtl)
    (HERE / "tiles.png").write_bytes(png_bytes(tiles()))
    write_glb(HERE.parent / "gltf_scene.glb", *gltf_scene())

    for name in ("torus_knot.ply", "icosphere.obj", "torus.obj"):
        path = HERE / name
        m = trimesh.load(path, process=False)
        print(f"{name}: {len(m.vertices)} vertices, {len(m.faces)} faces, "
              f"{path.stat().st_size / 1024:.1f} KiB")


if __name__ == "__main__":
    main()
