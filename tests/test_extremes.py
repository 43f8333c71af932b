"""Extreme but representable values: each scene is refused in one line or renders the same
picture as the scene at unit size (raytrace/values.py's bounds; docs/robustness.md, "Bounds").

A small scene (16×12: a shape, a checker floor, a light) is described in unit-size parameters,
each with its dimension: a position or length scales by s, a direction, colour, angle or
exponent does not, attenuation ``a_i`` scales by s⁻ⁱ (1/(a0 + a1·d + a2·d²) is invariant
under d → s·d). Hypothesis draws the scale s log-uniformly from 1e-308..1e308 (and, half the
time, from the accepted decades around 1) and may put an extreme value (±1e308, 1e-308, the
smallest subnormal, 1e±200, 0, NaN, ±inf) into any parameter of the unit scene (scaled with
it). The scene at s and at unit size are each either refused with a one-line SceneError or
rendered; where both render, the pictures are compared by the torture suite's scale-invariance
check (tests/test_torture.py: hit ids agree on 99 % of pixels, and away from silhouettes and
sharp edges every pixel within 1e-5 relative).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_torture import edge_mask, hit_ids, rel_err

import raytrace
from raytrace import (
    AreaLight,
    Camera,
    DirectionalLight,
    Disk,
    Material,
    Mesh,
    Plane,
    PointLight,
    RenderSettings,
    Scene,
    SceneError,
    Sphere,
    SpotLight,
    values,
)
from raytrace.material import Checker

W, H = 16, 12
ICO = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
SHAPES = ("sphere", "disk", "mesh", "plane")
LIGHTS = ("point", "spot", "area", "directional")
EXTREMES = (1e308, -1e308, 1e-308, 5e-324, 1e200, 1e-200, -1e-200, 0.0, math.nan, math.inf,
            -math.inf)

#: The unit scene's parameters: name → (value, dimension). Dimension 1 scales with s (points
#: and lengths), 0 does not; "att" is the attenuation a_i, scaled by s⁻ⁱ.
UNIT = {
    "camera.position": ([0.0, 1.2, 5.0], 1), "camera.look_at": ([0.0, 0.6, 0.0], 1),
    "camera.up": ([0.0, 1.0, 0.0], 0), "camera.fov": (45.0, 0),
    "shape.center": ([0.0, 0.7, -0.5], 1), "shape.radius": (0.7, 1),
    "shape.normal": ([0.0, 0.3, 1.0], 0), "floor.point": ([0.0, 0.0, 0.0], 1),
    "floor.normal": ([0.0, 1.0, 0.0], 0), "checker.scale": (1.0, 1),
    "light.position": ([2.0, 4.0, 3.0], 1), "light.direction": ([-1.0, -2.0, -1.0], 0),
    "light.color": ([0.9, 0.8, 0.7], 0), "light.attenuation": ([1.0, 0.05, 0.01], "att"),
    "light.cutoff": (40.0, 0), "light.exponent": (4.0, 0),
    "light.edge_u": ([1.0, 0.0, 0.0], 1), "light.edge_v": ([0.0, 0.0, 1.0], 1),
    "material.kd": ([0.8, 0.1, 0.1], 0), "material.ks": (0.5, 0), "material.shininess": (50.0, 0),
    "material.ior": (1.5, 0), "ambient": (0.1, 0),
}


def scaled(params: dict, s: float) -> dict:
    """The parameters of the unit scene scaled by ``s`` (overflow to inf and underflow to 0
    are what a user scaling the scene would write)."""
    out = {}
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        for name, value in params.items():
            dim = UNIT[name][1]
            v = np.asarray(value, dtype=np.float64)
            if dim == "att":
                v = v * np.array([1.0, 1.0 / s, 1.0 / s / s])
            elif dim == 1:
                v = v * s
            out[name] = v.tolist()
    return out


def build(p: dict, shape: str, light: str) -> Scene:
    """The scene of parameters ``p`` (a shape and a checker floor lit by one light)."""
    red = Material(kd=p["material.kd"], ks=p["material.ks"], shininess=p["material.shininess"],
                   ior=p["material.ior"], kt=0.3 if shape == "sphere" else 0.0)
    floor = Material(kd=Checker((np.array([0.8, 0.8, 0.8]), np.array([0.2, 0.3, 0.4])),
                                p["checker.scale"]), ks=0.3, shininess=20, kr=0.2)
    c, r, n = p["shape.center"], p["shape.radius"], p["shape.normal"]
    objects = {"sphere": lambda: [Sphere(c, r, red)], "disk": lambda: [Disk(c, n, r, red)],
               "mesh": lambda: [Mesh(vertices=ICO.vertices, faces=ICO.faces, shading="smooth",
                                     scale=r, translate=c, material=red)],
               "plane": lambda: []}[shape]()
    lp, col, att = p["light.position"], p["light.color"], p["light.attenuation"]
    lights = {"point": lambda: PointLight(lp, col, att),
              "spot": lambda: SpotLight(lp, p["light.direction"], p["light.cutoff"],
                                        p["light.exponent"], col, att),
              "area": lambda: AreaLight(lp, p["light.edge_u"], p["light.edge_v"], 4, False, col,
                                        att),
              "directional": lambda: DirectionalLight(p["light.direction"], col)}[light]()
    return Scene(camera=Camera(p["camera.position"], p["camera.look_at"], p["camera.up"],
                               p["camera.fov"]),
                 objects=[*objects, Plane(p["floor.point"], p["floor.normal"], floor)],
                 lights=[lights], ambient=p["ambient"],
                 render=RenderSettings(width=W, height=H, background=[0.1, 0.2, 0.3]))


def build_or_refuse(p: dict, shape: str, light: str) -> Scene | None:
    """The scene, or None where it is refused: in one line."""
    try:
        return build(p, shape, light)
    except SceneError as e:
        line = str(e)
        assert line and "\n" not in line, line
        return None


#: Each render's memory ceiling, on the whole process: a 16×12 render in a fresh process peaks
#: at 0.22 GB (the interpreter, numba, Embree); a test worker holds more after hundreds of
#: tests. A render that grew without end would be stopped (its MemoryLimitError fails the test).
MAX_MEMORY = "4G"


def render(scene: Scene) -> tuple[np.ndarray, int]:
    with warnings.catch_warnings():  # overflowed pixels warn; the counts are compared below
        warnings.simplefilter("ignore", raytrace.RenderWarning)
        image = raytrace.render(scene, threads=1, max_memory=MAX_MEMORY)
    assert np.isfinite(image.rgb).all()
    return image.rgb.astype(np.float64), image.stats["nonfinite_pixels"]


def assert_same_picture(scene: Scene, unit: Scene) -> None:
    """tests/test_torture.py's scale-invariance check, at this size."""
    ref, ref_bad = render(unit)
    img, bad = render(scene)
    assert bad == ref_bad
    ids = hit_ids(unit, W, H)
    assert (ids == hit_ids(scene, W, H)).mean() > 0.99
    keep = ~edge_mask(ids, ref, radius=1, contrast=0.25)
    err = rel_err(img, ref, 1e-3).max(axis=2)
    assert err[keep].max(initial=0.0) < 1e-5


@st.composite
def extreme_scenes(draw):
    shape, light = draw(st.sampled_from(SHAPES)), draw(st.sampled_from(LIGHTS))
    exponent = draw(st.one_of(st.floats(-308, 308), st.floats(-14, 14)))
    params = {name: value for name, (value, _) in UNIT.items()}
    if draw(st.booleans()):
        name = draw(st.sampled_from(sorted(UNIT)))
        value = draw(st.sampled_from(EXTREMES))
        if isinstance(params[name], list):
            params[name] = list(params[name])
            params[name][draw(st.integers(0, len(params[name]) - 1))] = value
        else:
            params[name] = value
    return shape, light, 10.0**exponent, params


@settings(derandomize=True, max_examples=500, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(extreme_scenes())
def test_a_scene_at_any_scale_is_refused_in_one_line_or_renders_as_at_unit_size(case):
    shape, light, s, params = case
    unit = build_or_refuse(params, shape, light)
    scene = build_or_refuse(scaled(params, s), shape, light)
    event(f"{'refused' if unit is None else 'rendered'} at unit size, "
          f"{'refused' if scene is None else 'rendered'} at s")
    if scene is not None and unit is not None:
        assert_same_picture(scene, unit)
    elif scene is not None:  # its unit-size twin is refused: it must still render
        render(scene)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("s", [values.MIN_LENGTH / 0.7, values.MAX_COORDINATE / 5.0],
                         ids=["1.4e-12", "2e11"])
def test_the_bounds_render_as_at_unit_size(shape, s):
    """At the ends of the accepted range every shape renders as at unit size: the unit
    scene's smallest length is a radius of 0.7, its farthest point the camera 5 units out."""
    params = {name: value for name, (value, _) in UNIT.items()}
    for light in LIGHTS:
        assert_same_picture(build(scaled(params, s), shape, light), build(params, shape, light))


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("s", [1e-13, 1e13], ids=["1e-13", "1e13"])
def test_just_beyond_the_bounds_every_shape_is_refused(shape, s):
    """1e13: meshes vanish in Embree's float32 (measured from 1e13); 1e-13: below the
    smallest length. Refused, whichever shape (the camera alone is out of range)."""
    params = {name: value for name, (value, _) in UNIT.items()}
    with pytest.raises(SceneError, match=r"must be within .*1e[+-]12"):
        build(scaled(params, s), shape, "point")


#: The parameters that are colours: not bounded (a pixel beyond float32 is counted in
#: ``stats["nonfinite_pixels"]``, written as 0 and warned of; docs/robustness.md).
COLOURS = ("light.color", "material.kd", "material.ks", "ambient")
#: The light, or the shape, that uses a parameter where the point light and sphere do not.
USED_BY = {"light.cutoff": "spot", "light.exponent": "spot", "light.direction": "spot",
           "light.edge_u": "area", "light.edge_v": "area", "shape.normal": "disk"}


@pytest.mark.parametrize("name", [n for n in sorted(UNIT) if n not in COLOURS])
def test_any_other_parameter_at_an_extreme_is_refused_or_renders_finite(name):
    """Every component of every parameter that is not a colour, at each extreme value, in the
    scene that uses it (a sphere or disk, a point, spot or area light): refused in one line,
    or rendered with no non-finite pixel."""
    base = {n: value for n, (value, _) in UNIT.items()}
    slots = range(len(base[name])) if isinstance(base[name], list) else [None]
    for slot in slots:
        for x in EXTREMES:
            params = dict(base)
            if slot is None:
                params[name] = x
            else:
                params[name] = [*params[name][:slot], x, *params[name][slot + 1:]]
            shape = "disk" if name == "shape.normal" else "sphere"
            light = USED_BY.get(name, "point") if shape == "sphere" else "point"
            scene = build_or_refuse(params, shape, light)
            if scene is not None:
                assert render(scene)[1] == 0, (slot, x)
