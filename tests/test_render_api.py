"""``raytrace.render`` (raytrace/rendering.py; not test_render.py, a name the pytest-plugin tests
give the test files they generate): its arguments are checked before any work, the memory
an image needs is checked against the machine, and renders that are probably not what was
meant (no objects, pixels beyond float32) say so: a RenderWarning, one line from the CLI.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import subprocess
import sys
import warnings

import numpy as np
import pytest

import raytrace
from raytrace import cli
from raytrace.film import read_exr
from raytrace.film.writers import WRITERS

RENDER = importlib.import_module("raytrace.rendering")  # (raytrace.render: the function)

# Camera at y = 1 looking level with an even height: exactly the lower half of the rows look
# down and hit the floor (test_cli.py's FLOOR_SCENE). A 1e39 light (beyond float32's 3.4e38)
# straight down on a kd = 1 floor makes every floor pixel 1e39: the first one in reading order
# is x = 0, y = H/2, and there are W·H/2 of them.
HOT_FLOOR = """\
[render]
width = 8
height = 6
[camera]
position = [0.0, 1.0, 0.0]
look_at = [0.0, 1.0, -1.0]
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
color = 1e39
[[objects]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = { kd = 1.0, ka = 0.0 }
"""


def test_progress_that_is_not_callable_is_a_type_error_before_the_render():
    scene = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])
    with pytest.raises(TypeError, match=r"progress must be a callable progress\(done, total\)"
                                        r" or None, got int"):
        raytrace.render(scene, width=4, height=4, progress=5)


# One bad value for every keyword of raytrace.render, and what its error says: each is
# refused before any work, in one line naming the keyword (a TypeError where the type is
# what is wrong). test_every_keyword_of_render_has_a_bad_value_here keeps the table whole.
BAD_KEYWORDS = {
    "width": (0, raytrace.SceneError, "render.width: must be >= 1"),
    "height": ("x", raytrace.SceneError, "render.height: must be a number, got a string"),
    "spp": (0, raytrace.SceneError, "render.spp: must be >= 1"),
    "max_depth": (-1, raytrace.SceneError, "render.max_depth: must be >= 0"),
    "min_weight": (-1, raytrace.SceneError, "render.min_weight: must be >= 0, got -1"),
    "seed": (0.5, raytrace.SceneError, "render.seed: must be a whole number, got 0.5"),
    "threads": (0, raytrace.SceneError, "threads: must be >= 1"),
    "progress": (5, TypeError, "progress must be a callable progress(done, total) or None, "
                               "got int"),
    "pass_samples": (0, raytrace.SceneError, "pass_samples: must be >= 1, got 0"),
    "crop": ((0, 0, 0, 0), raytrace.SceneError, "crop: x bounds 0..0 must satisfy"),
    "aovs": ("colour", raytrace.SceneError, "aovs: unknown AOV 'colour'"),
    "texture_filter": ("nearest", raytrace.SceneError,
                       "render.texture_filter: must be one of 'bilinear', 'trilinear'"),
    "filter": ("gauss", raytrace.SceneError, "render.filter: unknown filter 'gauss'"),
    "aa": ("x", raytrace.SceneError, "render.aa: unknown anti-aliasing 'x'"),
    "aa_threshold": (-1, raytrace.SceneError, "render.aa_threshold: must be >= 0, got -1"),
    "aa_depth": (9, raytrace.SceneError, "render.aa_depth: must be <= 8"),
    "aa_min_depth": (3, raytrace.SceneError, "render.aa_min_depth: must be <= 2"),
    "noise_threshold": (-1, raytrace.SceneError, "render.noise_threshold: must be >= 0"),
    "min_spp": (3, raytrace.SceneError, "render.min_spp: must be even"),
    "max_spp": (1, raytrace.SceneError, "render.max_spp: must be >= 2"),
    "target_error": (0, raytrace.SceneError, "target_error: must be > 0"),
    "time_limit": (-1, raytrace.SceneError, "time_limit: must be > 0"),
    "client": (3, TypeError, "client must be a dask.distributed.Client or None, got int"),
    "tile": (16, raytrace.SceneError, "tile: tiles need a client"),
    "max_memory": ("lots", raytrace.SceneError, "max_memory: must be a size such as 4G"),
    "worker_timeout": (5, raytrace.SceneError, "worker_timeout: a worker timeout needs a "
                                               "client"),
}


@pytest.mark.parametrize("keyword", BAD_KEYWORDS)
def test_a_bad_value_of_any_keyword_is_one_error_naming_it_before_the_render(keyword):
    value, error, message = BAD_KEYWORDS[keyword]
    scene = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])
    with pytest.raises(error) as e:
        raytrace.render(scene, **{"width": 4, "height": 4, keyword: value})
    assert str(e.value).startswith(message)


def test_every_keyword_of_render_has_a_bad_value_here():
    keywords = set(inspect.signature(raytrace.render).parameters) - {"scene"}
    assert keywords == set(BAD_KEYWORDS)


def _one_sphere() -> raytrace.Scene:
    return raytrace.Scene(camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
                          objects=[raytrace.Sphere([0, 0, 0], 1.0, material="brass")],
                          lights=[raytrace.PointLight([5, 5, 5])])


def test_render_checks_edits_made_after_construction():
    # Scene.check at render entry (tests/test_scene.py has every kind of edit); on main these
    # rendered silently: an in-place radius, NaN in a mesh's vertices.
    scene = _one_sphere()
    scene.objects[0].radius = -1
    for call in (raytrace.render, lambda s, **kw: raytrace.explain(s, (0, 0), **kw)):
        with pytest.raises(raytrace.SceneError,
                           match=r"^objects\[0\]\.radius: must be > 0, got -1$"):
            call(scene, width=4, height=3)
    scene = _one_sphere()
    scene.objects.append(raytrace.Mesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                       faces=[[0, 1, 2]], material="brass"))
    scene.objects[1].vertices[0, 0] = np.nan
    with pytest.raises(raytrace.SceneError, match=r"^objects\[1\]\.vertices: vertex 0 is not "
                                                  r"finite"):
        raytrace.render(scene, width=4, height=3)


def test_render_frames_checks_each_frame_s_scene_as_render_does(tmp_path):
    def frame(i: int) -> raytrace.Scene:
        scene = _one_sphere()
        scene.objects[0].center[1] = float("nan")  # in place, after construction
        return scene

    with pytest.raises(raytrace.SceneError, match=r"^objects\[0\]\.center\[1\]: must be "
                                                  r"finite, got nan$"):
        raytrace.render_frames(frame, tmp_path / "f.####.exr", [0], width=4, height=3)
    assert list(tmp_path.iterdir()) == []


def test_a_material_name_set_after_construction_renders_as_one_given_at_construction():
    # was AttributeError: 'str' object has no attribute 'ambient', deep in the render
    edited = _one_sphere()
    edited.objects.append(raytrace.Sphere([1.5, 0, 0], 0.5, material="emerald"))
    built = _one_sphere()
    built.objects = [*built.objects, raytrace.Sphere([1.5, 0, 0], 0.5,
                                                     material=raytrace.materials["emerald"])]
    a = raytrace.render(edited, width=16, height=12).rgb
    np.testing.assert_array_equal(a, raytrace.render(built, width=16, height=12).rgb)
    assert a.max() > 0


def test_pixels_beyond_float32_warn_with_count_and_first_pixel(tmp_path, capsys):
    scene = tmp_path / "hot.toml"
    scene.write_text(HOT_FLOOR)
    rc = cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "-q"])
    err = capsys.readouterr().err
    assert rc == 0
    # One line, though stderr is not a terminal here.
    assert err == (f"raytrace: warning: {scene}: 24 pixels overflowed to inf or NaN (the first "
                   "at x=0, y=3), written as 0\n")
    rgb, header = read_exr(tmp_path / "o.exr")
    assert header["raytrace:nonfinite_pixels"] == 24
    assert (rgb[3:] == 0).all()


def test_a_finite_render_has_a_zero_count_in_the_header_and_no_warning(tmp_path, capsys):
    scene = tmp_path / "ok.toml"
    scene.write_text(HOT_FLOOR.replace("1e39", "1.0"))
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "o.exr"), "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert read_exr(tmp_path / "o.exr")[1]["raytrace:nonfinite_pixels"] == 0


def test_the_api_warns_too():
    scene = raytrace.scene_from_dict({
        "camera": {"position": [0, 1, 0], "look_at": [0, 1, -1]},
        "lights": [{"type": "directional", "direction": [0, -1, 0], "color": 1e39}],
        "objects": [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0],
                     "material": {"kd": 1.0, "ka": 0.0}}]})
    with pytest.warns(raytrace.RenderWarning, match=r"24 pixels .* x=0, y=3"):
        image = raytrace.render(scene, width=8, height=6)
    assert image.stats["nonfinite_first_pixel"] == [0, 3]


def test_a_scene_without_objects_warns_and_an_empty_file_is_an_error(tmp_path, capsys):
    lonely = tmp_path / "lonely.toml"
    lonely.write_text("[render]\nwidth = 4\nheight = 2\n")
    rc = cli.main(["render", str(lonely), "-o", str(tmp_path / "l.exr"), "-q"])
    assert rc == 0
    assert capsys.readouterr().err == (f"raytrace: warning: {lonely}: the scene has no "
                                       "objects: the image is the background\n")
    for name, text in (("zero.toml", ""), ("blank.json", " \n\t\n")):
        empty = tmp_path / name
        empty.write_text(text)
        rc = cli.main(["render", str(empty), "-o", str(tmp_path / "e.exr"), "-q"])
        assert rc == 2
        assert capsys.readouterr().err == f"raytrace: error: {empty}: the scene file is empty\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blank.json", "l.exr", "lonely.toml",
                                                          "zero.toml"]


def test_an_object_whose_every_surface_is_invisible_warns():
    """Opacity 0 on every material of an object (as an MTL ``Tr 1`` gives): nothing of it is
    drawn, and the render says which object; one partly visible material, or opacity above
    0, says nothing."""
    ghost = raytrace.Material(kd=0.5, opacity=0.0)
    scene = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1.0, material=raytrace.Material()),
                                    raytrace.Sphere([2, 0, -3], 1.0, material=ghost)])
    with pytest.warns(raytrace.RenderWarning, match=r"^objects\[1\]: every surface has "
                                                    r"opacity 0 .*so nothing of it is drawn$"):
        raytrace.render(scene, width=4, height=3)
    scene.objects[1].material = ghost.replace(opacity=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error", raytrace.RenderWarning)
        raytrace.render(scene, width=4, height=3)


# -- memory ------------------------------------------------------------------------------------
def test_peak_estimate_is_the_base_plus_the_largest_step():
    # The writers' figures are the registry's (film/writers.py); the render's is its own.
    base, render = RENDER.PEAK_BASE_BYTES, RENDER.PEAK_RENDER_BYTES_PER_PIXEL
    exr, png = (WRITERS[s].peak_bytes_per_pixel for s in (".exr", ".png"))
    assert RENDER.peak_bytes(100, 10) == base + render * 1000
    assert RENDER.peak_bytes(100, 10, ("exr",)) == base + max(render, exr) * 1000
    assert RENDER.peak_bytes(100, 10, ("exr", "png")) == base + max(render, exr, png) * 1000


def test_an_image_this_machine_cannot_hold_is_refused_up_front(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(RENDER, "available_bytes", lambda: 2 * 10**9)
    scene = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])
    # 300 MiB + 15 B × 1e8 pixels = 1.81e9 B fits in 2e9 B: not refused by the check (the
    # integrator is stopped before it allocates anything).
    RENDER.check_memory(10000, 10000)
    # 300 MiB + 25 B × 1e8 = 2.81e9 B = 2.62 GiB with the EXR, and with a PNG too (written band
    # by band), over 2e9 B = 1.86 GiB.
    with pytest.raises(raytrace.SceneError, match=r"10000x10000 needs about 2\.6 GiB of memory "
                       r"at its peak \(render \+ exr\), more than the 1\.9 GiB available"):
        RENDER.check_memory(10000, 10000, ("exr",))
    monkeypatch.setattr(RENDER, "available_bytes", lambda: 10**9)
    with pytest.raises(raytrace.SceneError, match=r"^render\.width: 10000x10000 needs about "
                                                  r"1\.7 GiB .*\(render\)"):
        raytrace.render(scene, width=10000, height=10000)
    toml = tmp_path / "s.toml"
    toml.write_text('[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\nradius = 1\n')
    rc = cli.main(["render", str(toml), "-o", str(tmp_path / "o.exr"), "--png",
                   str(tmp_path / "o.png"), "--width", "10000", "--height", "10000", "-q"])
    assert rc == 2
    assert capsys.readouterr().err == ("raytrace: error: --width: 10000x10000 needs about 2.6 "
                                       "GiB of memory at its peak (render + exr + png), more "
                                       "than the 953.7 MiB available on this machine\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


# -- the memory ceiling ------------------------------------------------------------------------
BALL = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)],
                      lights=[raytrace.PointLight([2, 2, 0])])


@pytest.mark.parametrize(("size", "bytes_"), [
    ("4G", 4 * 2**30), ("512M", 512 * 2**20), ("512m", 512 * 2**20), ("1.5GiB", 3 * 2**29),
    ("64KB", 64 * 1024), ("1T", 2**40), ("1000", 1000), (1000, 1000), (" 2 G ", 2 * 2**30)])
def test_a_memory_size_reads_binary_units_or_bytes(size, bytes_):
    assert RENDER.memory_size(size) == bytes_


@pytest.mark.parametrize("size", ["lots", "4 GB RAM", "-1G", "G", "0", 0, -5, True, 1.5, None,
                                  "0.5", "4.5"])
def test_a_bad_memory_size_is_one_line_naming_the_key(size):
    with pytest.raises(raytrace.SceneError, match=r"^max_memory: must be "):
        RENDER.memory_size(size)


def test_the_default_ceiling_is_the_memory_held_plus_the_memory_available(monkeypatch):
    monkeypatch.setattr(RENDER, "rss_bytes", lambda: 300 * 2**20)
    monkeypatch.setattr(RENDER, "available_bytes", lambda: 2 * 2**30)
    assert RENDER.memory_ceiling() == RENDER.Ceiling(2 * 2**30 + 300 * 2**20, False)
    assert RENDER.memory_ceiling("1G") == RENDER.Ceiling(2**30, True)
    monkeypatch.setattr(RENDER, "available_bytes", lambda: None)  # a platform that won't say
    assert RENDER.memory_ceiling() is None


def test_a_render_over_its_ceiling_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("the integrator was built")

    monkeypatch.setattr(RENDER, "WhittedIntegrator", never)
    need = RENDER.size_text(RENDER.peak_bytes(32, 24))
    with pytest.raises(RENDER.MemoryLimitError) as e:
        raytrace.render(BALL, width=32, height=24, max_memory="100M")
    assert str(e.value) == (f"max_memory: 32x24 needs about {need} of memory at its peak "
                            "(render), over the memory ceiling of 100.0 MiB; give a larger "
                            "size to raise it")
    toml = tmp_path / "s.toml"
    toml.write_text('[render]\nwidth = 32\nheight = 24\n[[objects]]\ntype = "sphere"\n'
                    'center = [0, 0, -3]\nradius = 1\n')
    out = tmp_path / "o.exr"
    assert cli.main(["render", str(toml), "-o", str(out), "--max-memory", "1M", "-q"]) == 2
    need = RENDER.size_text(RENDER.peak_bytes(32, 24, ("exr",)))
    assert capsys.readouterr().err == (
        f"raytrace: error: --max-memory: 32x24 needs about {need} of memory at its peak "
        "(render + exr), over the memory ceiling of 1.0 MiB; give a larger size to raise it\n")
    assert not out.exists()
    assert cli.main(["render", str(toml), "-o", str(out), "--max-memory", "lots"]) == 2
    assert "--max-memory: must be a size such as 4G" in capsys.readouterr().err


def test_a_render_that_reaches_its_ceiling_is_stopped(tmp_path, capsys, monkeypatch):
    # The estimate passes (1 GiB), then the process "grows" past the ceiling once the first
    # pass is done: the memory watch stops the render before its last pass.
    started, calls = [], []

    def rss() -> int:
        return 2**30 + 2**20 if started else 100 * 2**20

    def progress(done: int, total: int) -> None:
        calls.append(done)
        started.append(True)

    monkeypatch.setattr(RENDER, "rss_bytes", rss)
    with pytest.raises(RENDER.MemoryLimitError) as e:
        raytrace.render(BALL, width=400, height=300, spp=16, threads=1, max_memory="1G",
                        progress=progress, pass_samples=4096)
    assert str(e.value) == ("max_memory: the render reached 1.001 GiB and was stopped, over "
                            "the memory ceiling of 1.000 GiB; give a larger size to raise it")
    assert 1 <= len(calls) < 400 * 300 * 16 // 4096 / 2, calls  # stopped well before the end
    # The command line: one line, exit 2, nothing written.
    started.append(True)
    toml = tmp_path / "s.toml"
    toml.write_text('[[objects]]\ntype = "sphere"\ncenter = [0, 0, -3]\nradius = 1\n')
    out = tmp_path / "o.exr"
    assert cli.main(["render", str(toml), "-o", str(out), "--max-memory", "1G", "-q"]) == 2
    assert capsys.readouterr().err == (
        "raytrace: error: --max-memory: the render reached 1.001 GiB and was stopped, over "
        "the memory ceiling of 1.000 GiB; give a larger size to raise it\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
    # By default the ceiling is the memory held and available at the start, and says so.
    monkeypatch.setattr(RENDER, "available_bytes", lambda: 2**29)
    monkeypatch.setattr(RENDER, "rss_bytes", lambda: 2**29 if not calls else 2**31)
    calls.clear()
    with pytest.raises(RENDER.MemoryLimitError, match=r"reached 2\.0 GiB and was stopped, over "
                       r"the memory ceiling of 1\.0 GiB \(the default: the memory this "
                       r"process held and the memory available when the render started\)"):
        raytrace.render(BALL, width=400, height=300, spp=16, threads=1, progress=progress,
                        pass_samples=4096)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ru_maxrss in KiB on Linux")
@pytest.mark.parametrize("steps", [(), ("exr",), ("exr", "png")])
def test_the_peak_estimate_covers_a_measured_render(tmp_path, steps):
    # A real 3000×3000 render in a fresh process: the estimate is at least the measured peak
    # (ru_maxrss) and not more than 1.5 times it. Re-measure the bytes a pixel
    # (PEAK_RENDER_BYTES_PER_PIXEL, the writers' in film/writers.py) when this fails after a
    # change to the film or the preview.
    side = 3000

    def peak(side: int) -> int:
        code = f"""
import resource, sys, raytrace
from raytrace.film import write_exr, write_png
scene = raytrace.scene_from_dict({{"objects": [{{"type": "sphere", "center": [0, 0, -3],
                                            "radius": 1}}],
                                  "lights": [{{"type": "point", "position": [2, 2, 0]}}]}})
image = raytrace.render(scene, width={side}, height={side}, threads=2)
if "exr" in {steps!r}:
    write_exr({str(tmp_path / "o.exr")!r}, image.rgb, image.metadata, 2)
if "png" in {steps!r}:
    write_png({str(tmp_path / "o.png")!r}, image.rgb)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout
        return int(out.split()[-1])

    peak(16)  # the kernels compiled into the cache first: a compiler's memory is not the render's
    measured = peak(side)
    estimate = RENDER.peak_bytes(side, side, steps)
    assert measured <= estimate <= 1.5 * measured, (measured, estimate)


def glass_pair(depth: int, min_weight: float = 0.0) -> raytrace.Scene:
    glass = raytrace.Material(kd=0.0, kr=0.1, kt=0.9, ior=1.5, name="glass")
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0, 0, 5], look_at=[0, 0, 0]),
        objects=[raytrace.Sphere(center=[-1, 0, 0], radius=1.0, material=glass),
                 raytrace.Sphere(center=[1, 0, 0], radius=1.0, material=glass)],
        lights=[raytrace.PointLight(position=[3, 3, 3])],
        render=raytrace.RenderSettings(max_depth=depth, min_weight=min_weight))


def test_a_ray_tree_that_can_double_past_2_to_the_24_warns_before_the_render():
    # glass reflects and refracts: 2 rays a hit, (2^(D+1) − 1) rays a sample at most
    assert RENDER.ray_tree_warning(glass_pair(23), 23, 0.0) is None    # 2^24 − 1 rays
    assert RENDER.ray_tree_warning(glass_pair(24), 24, 0.0) == (
        "render.max_depth: 24 with min_weight 0 lets a ray tree grow to about 10^7 rays a "
        "camera sample, as material 'glass' spawns 2 rays a hit; where such surfaces face "
        "each other the render may not end: set render.min_weight (POV-Ray's adc_bailout, "
        "1/255 there) or a lower max_depth")                          # 2^25 − 1 rays
    assert "10^301 rays" in RENDER.ray_tree_warning(glass_pair(1000), 1000, 0.0)
    assert RENDER.ray_tree_warning(glass_pair(1000), 1000, 1 / 255) is None
    unnamed = glass_pair(30)
    unnamed.objects[1].material = dataclasses.replace(unnamed.objects[1].material, name="",
                                                      opacity=0.5)  # and seen through: 3
    assert "as material objects[1].material spawns 3" in RENDER.ray_tree_warning(unnamed, 30, 0)
    mirror = glass_pair(1000)
    for sphere in mirror.objects:
        sphere.material = raytrace.Material(kr=0.9, name="mirror")   # one ray a hit: a chain
    assert RENDER.ray_tree_warning(mirror, 1000, 0.0) is None
    with pytest.warns(raytrace.RenderWarning, match="max_depth: 40 with min_weight 0"):
        raytrace.render(glass_pair(40), width=2, height=2, threads=1)
