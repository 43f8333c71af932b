"""The pictures of docs/sampling.md: each filter, and uniform against adaptive sampling, on a
crop of the Whitted scene's checker floor at the horizon, enlarged 4× (nearest neighbour);
and a noise-driven render of the whole Whitted frame with its samples AOV.

    python3 docs/make_sampling.py            # all
    python3 docs/make_sampling.py noise      # the noise-driven pictures only

Prints each render's camera samples and seconds (one thread).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run from a checkout without installing
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_scenes import WHITTED  # noqa: E402  (plain checkers: what the pictures compare)

import raytrace  # noqa: E402
from raytrace.film import write_png  # noqa: E402

OUT = ROOT / "docs" / "sampling"
W, H = 640, 480
CROP = (40, 200, 200, 300)  # the floor's far edge and the mirror sphere's reflection
ZOOM = 4


def render(name: str, **kw) -> None:
    scene = raytrace.load_scene(WHITTED)
    t0 = time.perf_counter()
    image = raytrace.render(scene, width=W, height=H, crop=CROP, threads=1, **kw)
    seconds = time.perf_counter() - t0
    big = np.repeat(np.repeat(image.rgb, ZOOM, axis=0), ZOOM, axis=1)
    write_png(OUT / f"{name}.png", big)
    print(f"{name}: {image.stats['rays']['camera']} camera samples, {seconds:.2f} s")


def noise_pictures() -> None:
    """The Whitted scene at 160×120 by ``target_error = 0.01`` (2 threads), enlarged 2×, and
    its samples AOV as grey levels, log2(samples) from min_spp (black) to the most (white)."""
    scene = raytrace.load_scene(WHITTED)
    image = raytrace.render(scene, width=160, height=120, threads=2, target_error=0.01,
                            aovs="samples")
    counts = np.log2(image.aov("samples").astype(np.float64))
    grey = (counts - counts.min()) / max(counts.max() - counts.min(), 1e-9)
    for name, rgb in (("noise_target0.01", image.rgb),
                      ("noise_target0.01_samples", np.repeat(grey[..., None], 3, 2))):
        write_png(OUT / f"{name}.png", np.repeat(np.repeat(rgb, 2, axis=0), 2, axis=1))
    st = image.stats["aa"]
    print(f"noise: {st['samples']} samples ({st['samples_per_pixel']:.1f} a pixel, "
          f"{image.aov('samples').min()} to {image.aov('samples').max()}), estimate "
          f"{st['estimated_relative_rmse']:.4f}, {st['rounds']} rounds")


if __name__ == "__main__":
    OUT.mkdir(exist_ok=True)
    if sys.argv[1:] == ["noise"]:
        noise_pictures()
        sys.exit()
    render("filter_box_1spp", spp=1)
    for f in ("box", "tent", "gaussian", "mitchell"):
        render(f"filter_{f}_4spp", spp=4, filter=f)
    render("uniform_16spp", spp=16)
    render("adaptive_t0.05_d2", aa="adaptive", aa_threshold=0.05, aa_depth=2)
    noise_pictures()
