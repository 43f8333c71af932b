"""Scene → arrays: the tables the kernels read, built once per render.

:class:`MaterialTable` turns the scene's materials into :class:`raytrace.records.Materials`
(one row per material, colours per channel, checker patterns by reference); the emitters
(:func:`raytrace.lights.emitters`) and the camera-relative triangle tables
(:class:`raytrace.accel.Accelerator`) are the other two; :func:`scene_record` puts what the
shading kernels need into one :class:`raytrace.records.Scene`.
"""

from __future__ import annotations

import numpy as np

from .material import COLOR_KEYS, Checker, Material
from .records import Materials, Scene, Triangles
from .shading import FRESNEL_CODES, HIGHLIGHT_CODES
from .texture import WRAPS, Texture


class MaterialTable:
    """Per-material coefficients, looked up by material index at the hits.

    ``colors`` (M, 18) holds the constant colours ka kd ks kr kt ke, three columns each
    (``shading_kernels.KA`` …); where colour k of material m is a :class:`Checker`,
    ``pattern[m, k]`` indexes its row of ``checkers`` (colour 0, colour 1, scale), evaluated
    at the world points of the hits; −1 means constant. :attr:`record` is the whole table as
    the kernels take it (:class:`raytrace.records.Materials`).
    """

    def __init__(self, materials: list[Material]):
        self.materials = materials
        self.colors = np.zeros((len(materials), 3 * len(COLOR_KEYS)))
        self.pattern = np.full((len(materials), len(COLOR_KEYS)), -1, np.int64)
        self.texture = np.full((len(materials), len(COLOR_KEYS)), -1, np.int64)
        checkers, textures = [], []
        for i, m in enumerate(materials):
            for k, key in enumerate(COLOR_KEYS):
                c = m.ambient if key == "ka" else getattr(m, key)
                if isinstance(c, Checker):
                    self.pattern[i, k] = len(checkers)
                    checkers.append([*c.colors[0], *c.colors[1], c.scale])
                elif isinstance(c, Texture):
                    if c not in textures:
                        textures.append(c)
                    self.texture[i, k] = textures.index(c)
                else:
                    self.colors[i, 3 * k:3 * k + 3] = c
        self.alpha = np.full(len(materials), -1, np.int64)
        for i, m in enumerate(materials):
            if m.alpha is not None:
                if m.alpha not in textures:
                    textures.append(m.alpha)
                self.alpha[i] = textures.index(m.alpha)
        self.alpha_cutoff = np.array([m.alpha_cutoff for m in materials], np.float64)
        self.textured = (self.texture >= 0).any(axis=1) | (self.alpha >= 0)
        # only scenes with textures pay for them: one float a texture channel, else none
        sizes = [t.texels.size for t in textures]
        self.tex_info = np.array(
            [[off, t.texels.shape[1], t.texels.shape[0], WRAPS[t.wrap[0]], WRAPS[t.wrap[1]]]
             for off, t in zip(np.cumsum([0, *sizes])[:-1], textures, strict=True)],
            np.int64).reshape(-1, 5)
        self.texels = (np.concatenate([t.texels.reshape(-1) for t in textures])
                       if textures else np.zeros(0, np.float32))
        self.checkers = np.array(checkers, dtype=np.float64).reshape(-1, 7)
        self.shininess = np.array([m.shininess for m in materials], dtype=np.float64)
        self.highlight = np.array([HIGHLIGHT_CODES[m.highlight] for m in materials], np.int64)
        self.ior = np.array([m.ior for m in materials], dtype=np.float64)
        self.opacity = np.array([m.opacity for m in materials], dtype=np.float64)
        self.lit = np.array([m.lit for m in materials], dtype=bool)
        self.reflects = np.array([m.reflects for m in materials], dtype=bool)
        self.transmits = np.array([m.transmits for m in materials], dtype=bool)
        self.transparent = np.array([m.transparent for m in materials], dtype=bool)
        self.emits = np.array([m.emits for m in materials], dtype=bool)
        self.fresnel = np.array([FRESNEL_CODES[m.fresnel] for m in materials], np.int64)
        self.record = Materials(self.colors, self.pattern, self.checkers, self.shininess,
                                self.highlight, self.ior, self.opacity, self.lit,
                                self.reflects, self.transmits, self.emits, self.fresnel,
                                self.texture, self.textured, self.texels, self.tex_info,
                                self.alpha, self.alpha_cutoff)


def scene_record(origin: np.ndarray, table: MaterialTable, triangles: Triangles) -> Scene:
    """What every shading kernel needs of the scene, as one record."""
    return Scene(np.ascontiguousarray(origin, dtype=np.float64), table.record, triangles)
