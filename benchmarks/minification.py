"""Texture minification: bilinear against trilinear (mip-mapped, ray-cone footprint) lookups,
error against render time.

    python3 benchmarks/minification.py      # 320×240, reference 1024 spp (checked against 256)

The scene is made here (nothing large is committed): a 1024² checker of 4-texel cells
(linear 0 and 1, an 8-bit sRGB PNG), repeated every 10 world units on a 400 × 400 floor
that recedes to the horizon, lit from straight above (a directional light of 1, no ambient),
so a pixel is the texture's value. The reference is the bilinear lookup at ``--reference-spp``
uniform samples (seed 12345): the box-filtered image, whatever the filter at 1 spp. Its
convergence is checked by comparing it with ``--check-spp`` samples (another seed) on the far
floor's rows: the two differ by √(1/256 + 1/1024)·σ, the reference alone by √(1/1024)·σ,
0.45 of that difference. The pyramid's build (once a texture) is timed apart. Each run is
timed (best of ``--repeats``, after a warm-up); the table gives the RMSE over linear RGB
against the reference, the seconds, the ratio of RMSE to bilinear's at the same spp, and the
spp bilinear needs to reach trilinear's error (interpolated in log-log between the rows).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from aa import timed
from PIL import Image as PILImage

import raytrace
from raytrace import mipmap
from raytrace.film.metrics import METRICS

SCENE = """
[render]
width = 320
height = 240
max_depth = 0

[camera]
position = [0.0, 1.0, 0.0]
look_at = [0.0, 0.75, -10.0]
fov = 40.0

[ambient]
color = 0.0

[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
color = 1.0

[[objects]]
type = "mesh"
file = "floor.obj"
material = "from_file"
"""


def write_scene(folder: Path, size: int = 1024, cell: int = 4, half: float = 200.0,
                period: float = 10.0) -> Path:
    """The floor scene in ``folder``: a ``size``² checker of ``cell``-texel cells, repeated
    every ``period`` world units on the square |x|, |z| ≤ ``half`` at y = 0."""
    i = np.arange(size) // cell
    codes = np.where((i[:, None] + i[None, :]) % 2 == 1, 255, 0).astype(np.uint8)
    PILImage.fromarray(codes, "L").convert("RGB").save(folder / "checker.png")
    (folder / "floor.mtl").write_text("newmtl floor\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nillum 1\n"
                                      "map_Kd checker.png\n")
    r, s = half, half / period
    (folder / "floor.obj").write_text(
        "mtllib floor.mtl\nusemtl floor\n"
        f"v {-r} 0 {r}\nv {r} 0 {r}\nv {r} 0 {-r}\nv {-r} 0 {-r}\n"
        f"vt {-s} {-s}\nvt {s} {-s}\nvt {s} {s}\nvt {-s} {s}\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (folder / "floor.toml").write_text(SCENE)
    return folder / "floor.toml"


def spp_to_match(rows: list[tuple[int, float]], target: float) -> float:
    """The spp at which bilinear's RMSE (``rows`` of (spp, rmse), spp rising) falls to
    ``target``: log-log interpolation between the two rows around it; inf beyond the last."""
    for (s0, e0), (s1, e1) in zip(rows, rows[1:], strict=False):
        if e0 >= target >= e1:
            f = math.log(e0 / target) / math.log(e0 / e1)
            return s0 * (s1 / s0) ** f
    return rows[0][0] if target >= rows[0][1] else math.inf


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--reference-spp", type=int, default=1024)
    p.add_argument("--check-spp", type=int, default=256)
    p.add_argument("--spp", type=int, nargs="*", default=[1, 4, 16, 64])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--filters", nargs="*", default=["bilinear", "trilinear"])
    a = p.parse_args()
    rmse = METRICS["rmse"].function
    with tempfile.TemporaryDirectory() as tmp:
        scene = raytrace.load_scene(write_scene(Path(tmp)))
        w, h = scene.render.width, scene.render.height
        common = dict(threads=a.threads)
        raytrace.render(scene, width=32, height=24, threads=1)  # warm-up (compiles)
        t0 = time.perf_counter()
        ref = raytrace.render(scene, spp=a.reference_spp, seed=12345, **common).rgb
        ref_seconds = time.perf_counter() - t0
        crop = (0, h // 3, w, h // 2)  # the far floor, up to the horizon
        check = raytrace.render(scene, spp=a.check_spp, seed=777, crop=crop, **common).rgb
        x0, y0, x1, y1 = crop
        converged = rmse(ref[y0:y1, x0:x1], check)
        print(f"floor {w}x{h}, 1024² checker of 4-texel cells; reference {a.reference_spp} spp "
              f"bilinear (seed 12345, {ref_seconds:.1f} s)")
        print(f"reference vs {a.check_spp} spp on rows {y0}..{y1}: RMSE {converged:.5f}")
        texture = scene.objects[0].file_materials[0].kd
        t0 = time.perf_counter()
        mipmap.pyramid(texture.texels, (0, 0))
        print(f"pyramid of the {texture.texels.shape[1]}x{texture.texels.shape[0]} texture: "
              f"{time.perf_counter() - t0:.3f} s (once a texture)")
        print(f"{'filter':<11}{'spp':>5}{'rmse':>10}{'seconds':>9}{'vs bilinear':>13}"
              f"{'bilinear spp to match':>23}")
        results: dict[str, list[tuple[int, float, float]]] = {}
        for name in a.filters:
            extra = {} if name == "bilinear" else {"texture_filter": name}
            raytrace.render(scene, width=32, height=24, threads=1, **extra)  # warm-up
            results[name] = []
            for spp in a.spp:
                img, seconds = timed(scene, a.repeats, spp=spp, **common, **extra)
                results[name].append((spp, rmse(img.rgb, ref), seconds))
        bilinear = [(s, e) for s, e, _ in results.get("bilinear", [])]
        for name, rows in results.items():
            for spp, err, seconds in rows:
                base = dict(bilinear).get(spp)
                ratio = f"{err / base:.3f}" if base else "-"
                match = f"{spp_to_match(bilinear, err):.1f}" if bilinear else "-"
                print(f"{name:<11}{spp:>5}{err:>10.5f}{seconds:>9.3f}{ratio:>13}{match:>23}")


if __name__ == "__main__":
    main()
