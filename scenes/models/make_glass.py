"""Generate ``scenes/glass_model.glb``, a glTF glass model that renders from its file alone
(run from anywhere):

    python3 scenes/models/make_glass.py
    raytrace render scenes/glass_model.glb -o glass_model.exr --png glass_model.png

On a tiled floor (baseColorTexture), lit by a KHR_lights_punctual point light and seen by the
file's camera:

* a blue-green glass ball, KHR_materials_transmission + KHR_materials_ior 1.5 +
  KHR_materials_volume (thicknessFactor > 0: a closed volume, refracting) whose
  attenuationColor (0.25, 0.6, 0.9) after attenuationDistance 0.5 darkens it by Beer's law
  towards its thick middle;
* an amber glass block, the same with attenuationColor (0.95, 0.55, 0.1) after 0.4;
* a thin-walled bubble: transmission without a volume, so light passes without bending and
  only the Fresnel reflections show.

Deterministic (no random numbers): re-running it reproduces the committed file. The helpers
(the glTF writer, the sphere, the cube, the tile texture) are make_models.py's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from make_models import cube_faces, floor_quad, png_bytes, sphere, tiles, write_glb, write_gltf_doc

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "glass_model.glb"


def glass(name: str, tint: list[float], volume: dict | None) -> dict:
    """A clear glTF glass (white base colour, metallic 0, roughness 0, transmission 1, ior
    1.5), with ``volume`` as its KHR_materials_volume (None: thin-walled)."""
    ext: dict = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                 "KHR_materials_ior": {"ior": 1.5}}
    if volume is not None:
        ext["KHR_materials_volume"] = volume
    return {"name": name, "pbrMetallicRoughness": {"baseColorFactor": [*tint, 1.0],
                                                   "metallicFactor": 0.0,
                                                   "roughnessFactor": 0.0},
            "extensions": ext}


def glass_model() -> tuple[dict, bytes]:
    """The document and its binary buffer."""
    floor_v, floor_f, floor_uv = floor_quad(4.0, 4.0)
    floor_uv = floor_uv[:, ::-1] * [1, -1] + [0, 1]  # glTF's t runs down
    ball_v, ball_f = sphere(np.zeros(3), 1.0, subdivisions=3)
    cube_v, cube_f, _ = cube_faces()
    meshes = [{"positions": floor_v, "indices": floor_f, "uv": floor_uv, "material": 0},
              {"positions": ball_v, "indices": ball_f, "normals": ball_v, "material": 1},
              {"positions": cube_v, "indices": cube_f, "material": 2},
              {"positions": ball_v, "indices": ball_f, "normals": ball_v, "material": 3}]
    materials = [
        {"name": "floor", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                   "metallicFactor": 0.0,
                                                   "roughnessFactor": 0.7}},
        glass("blue_green_glass", [1.0, 1.0, 1.0],
              {"thicknessFactor": 1.4, "attenuationColor": [0.25, 0.6, 0.9],
               "attenuationDistance": 0.5}),
        glass("amber_glass", [1.0, 1.0, 1.0],
              {"thicknessFactor": 0.9, "attenuationColor": [0.95, 0.55, 0.1],
               "attenuationDistance": 0.4}),
        glass("bubble", [1.0, 1.0, 1.0], None),
    ]
    turn = math.radians(30) / 2
    tilt = math.radians(-14) / 2
    nodes = [
        {"name": "camera", "translation": [0.0, 1.5, 4.2], "camera": 0,
         "rotation": [math.sin(tilt), 0.0, 0.0, math.cos(tilt)]},
        {"name": "floor", "mesh": 0},
        {"name": "ball", "translation": [-0.85, 0.7, -0.2], "scale": [0.7, 0.7, 0.7], "mesh": 1},
        {"name": "block", "translation": [0.95, 0.46, -0.5], "scale": [0.9, 0.9, 0.9],
         "rotation": [0.0, math.sin(turn), 0.0, math.cos(turn)], "mesh": 2},
        {"name": "bubble", "translation": [0.35, 0.35, 0.9], "scale": [0.35, 0.35, 0.35],
         "mesh": 3},
        {"name": "lamp", "translation": [2.5, 4.5, 3.0],
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
    ]
    extra = {
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.75, "aspectRatio": 4 / 3, "znear": 0.1}}],
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission",
                           "KHR_materials_ior", "KHR_materials_volume"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.97, 0.9], "intensity": 30.0}]}},
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}],
    }
    doc, blob = write_gltf_doc(nodes, meshes, materials, extra, images=[png_bytes(tiles(64, 4))])
    doc["asset"]["generator"] = "raytrace scenes/models/make_glass.py"
    doc["asset"]["extras"] = {"description": [
        "A glTF glass model alone, no TOML: two closed glass volumes (KHR_materials_volume",
        "with thickness > 0) tinted by Beer's law, attenuationColor after attenuationDistance,",
        "and a thin-walled bubble (transmission without a volume: no bending), on a tiled",
        "floor, lit by a KHR point light. Made by scenes/models/make_glass.py.",
        "Render: raytrace render scenes/glass_model.glb -o glass_model.exr --png glass_model.png"]}
    return doc, blob


if __name__ == "__main__":
    write_glb(OUT, *glass_model())
    print(f"{OUT.name}: {OUT.stat().st_size / 1024:.1f} KiB")
