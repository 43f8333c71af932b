"""Fast Phong shading against exact Phong (``smooth``) and Gouraud: error and time per
triangle size (seed 000's question: error against run time).

    python3 benchmarks/fast_phong.py --json benchmarks/fast_phong.json \\
        --plot docs/shading/fast_phong.png
    python3 benchmarks/fast_phong.py --quick     # checks the harness

An icosphere of radius 1 subdivided 1 … 6 times (80 … 81 920 triangles) 4 units in front of
the camera, lit by one directional light (the case fast Phong is made for), Phong highlight
n = 30 (kd 0.6, 0.5, 0.4; ks 0.5), ambient 0.05, ``max_depth`` 0 (camera rays only, so every
lit hit is shaded by the polynomials), 320×240, spp 1, one thread. Per subdivision and
shading: the image's error against ``smooth`` (exact Phong interpolation: the normal blended
and normalised per hit) as RMSE and largest |difference| over every pixel and channel,
diffuse only (ks = 0: the Taylor polynomial's own error) and with the highlight (adds the
distant viewer's: V taken at the centroid); and the CPU seconds of the shading stage
(``stats["seconds"]["shade"]``) and of the whole render (``time.process_time``), each the
best of ``--repeat`` renders, shadings alternated in each round so that load from other
processes falls on all of them alike. Then the light pass alone, per hit, and the table's
build, per triangle (:func:`kernel_times`).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

SHADINGS = ("smooth", "fast_phong", "gouraud")


def scene(subdivisions: int, shading: str, ks: float):
    import trimesh

    import raytrace

    material = raytrace.Material(kd=[0.6, 0.5, 0.4], ks=ks, shininess=30.0)
    return raytrace.Scene(
        camera=raytrace.Camera(position=[0, 0, 4], look_at=[0, 0, 0]),
        objects=[raytrace.Mesh(mesh=trimesh.creation.icosphere(subdivisions), shading=shading,
                               material=material)],
        lights=[raytrace.DirectionalLight(direction=[-1.0, -1.0, -1.0])], ambient=0.05)


def measure(subdivisions: list[int], size: tuple[int, int], repeat: int) -> list[dict]:
    import raytrace

    width, height = size
    settings = dict(width=width, height=height, spp=1, max_depth=0, threads=1)
    rows = []
    for k in subdivisions:
        for ks in (0.0, 0.5):
            scenes = {s: scene(k, s, ks) for s in SHADINGS}
            images, shade, cpu = {}, {s: [] for s in SHADINGS}, {s: [] for s in SHADINGS}
            for _ in range(repeat):
                for s in SHADINGS:
                    t0 = time.process_time()
                    image = raytrace.render(scenes[s], **settings)
                    cpu[s].append(time.process_time() - t0)
                    shade[s].append(image.stats["seconds"]["shade"])
                    images[s] = image.rgb.astype(np.float64)
            for s in SHADINGS:
                diff = images[s] - images["smooth"]
                rows.append(dict(subdivisions=k, triangles=20 * 4**k, ks=ks, shading=s,
                                 rmse=float(np.sqrt(np.mean(diff**2))),
                                 max=float(np.abs(diff).max()),
                                 shade_seconds=min(shade[s]), cpu_seconds=min(cpu[s])))
                print(f"{k} {20 * 4**k:6d} ks={ks} {s:10s} rmse {rows[-1]['rmse']:.2e} "
                      f"max {rows[-1]['max']:.2e} shade {rows[-1]['shade_seconds']:.4f} s "
                      f"cpu {rows[-1]['cpu_seconds']:.4f} s", flush=True)
    return rows


def kernel_times(subdivisions: list[int], size: tuple[int, int], repeat: int) -> list[dict]:
    """Nanoseconds per hit of the light pass alone (``shading_kernels.light_pass`` on the
    camera rays' hits, shadow rays written, not traced) with exact Phong (``smooth``) and
    with the polynomials (``fast_phong``), best of ``repeat`` alternated calls; and the
    table's build (:func:`raytrace.fast_phong.tables`) in nanoseconds per triangle."""
    from raytrace import fast_phong
    from raytrace.camera import camera_rays
    from raytrace.integrator import WhittedIntegrator
    from raytrace.kernels import shading as sk
    from raytrace.kernels.records import Hits, Shadows
    from raytrace.rendering import render_options
    from raytrace.shading import NO_KEY

    width, height = size
    out = []
    for k in subdivisions:
        sc = scene(k, "fast_phong", 0.5)
        integ = WhittedIntegrator(sc, render_options(sc, width=width, height=height,
                                                     threads=1, max_depth=0))
        rays = camera_rays(sc.camera, integ.opt, 0, width * height)
        hits = integ.accel.intersect(rays.origin, rays.direction, rays.origin_shape)
        found = np.isfinite(hits.t)
        rays = rays.take(found)
        hits = Hits(*(np.ascontiguousarray(a[found]) for a in hits))
        surf = integ.accel.surface(hits, rays.origin, rays.direction)
        n = len(rays)
        term = np.empty((n, 3))
        shadow = Shadows(np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)),
                         np.empty(n), np.empty(n, np.int64))
        em = integ.emitters[0].record
        tables = {"smooth": integ.tables, "fast_phong": integ.tables._replace(fast=integ.fast[0])}
        best = {s: np.inf for s in tables}
        for _ in range(repeat):
            for s, t in tables.items():
                t0 = time.perf_counter()
                sk.light_pass(rays.record, surf, t, em, NO_KEY, 0, term, shadow)
                best[s] = min(best[s], time.perf_counter() - t0)
        build = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            fast_phong.tables(integ.accel.triangles, integ.table.highlight, integ.emitters)
            build = min(build, time.perf_counter() - t0)
        triangles = len(integ.accel.tri_material)
        out.append(dict(subdivisions=k, triangles=triangles, hits=n,
                        smooth_ns_per_hit=best["smooth"] / n * 1e9,
                        fast_phong_ns_per_hit=best["fast_phong"] / n * 1e9,
                        table_ns_per_triangle=build / triangles * 1e9))
        print(f"{k} {triangles:6d} light pass: smooth {out[-1]['smooth_ns_per_hit']:.1f} ns/hit, "
              f"fast_phong {out[-1]['fast_phong_ns_per_hit']:.1f} ns/hit; table "
              f"{out[-1]['table_ns_per_triangle']:.0f} ns/triangle", flush=True)
    return out


def plot(rows: list[dict], kernels: list[dict], path: Path) -> None:
    """Left: the largest image error against ``smooth`` per triangle count; right: the light
    pass's nanoseconds per hit, exact and fast, per triangle count."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    for s, ks, style in (("fast_phong", 0.0, "o--"), ("fast_phong", 0.5, "o-"),
                         ("gouraud", 0.5, "s-")):
        r = [x for x in rows if x["shading"] == s and x["ks"] == ks]
        label = f"{s}, {'diffuse only' if ks == 0 else 'with highlight'}"
        left.loglog([x["triangles"] for x in r], [x["max"] for x in r], style, label=label)
    triangles = [k["triangles"] for k in kernels]
    right.semilogx(triangles, [k["smooth_ns_per_hit"] for k in kernels], "o-",
                   label="smooth (exact Phong)")
    right.semilogx(triangles, [k["fast_phong_ns_per_hit"] for k in kernels], "s-",
                   label="fast_phong")
    left.set_xlabel("triangles (icosphere)")
    left.set_ylabel("largest |image − smooth|")
    left.set_title("error against triangle count")
    right.set_xlabel("triangles (icosphere)")
    right.set_ylabel("ns per hit")
    right.set_ylim(bottom=0)
    right.set_title("light pass, one directional light (best of 20)")
    left.legend(fontsize=7)
    right.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--json", type=Path)
    p.add_argument("--plot", type=Path)
    p.add_argument("--from-json", type=Path, help="measure nothing: plot an earlier run")
    a = p.parse_args()
    if a.from_json:
        out = json.loads(a.from_json.read_text())
        plot(out["rows"], out["kernels"], a.plot)
        return
    subdivisions, size = ([1, 2], (64, 48)) if a.quick else (list(range(1, 7)), (320, 240))
    import raytrace

    raytrace.render(scene(1, "fast_phong", 0.5), width=8, height=6)  # compile / load kernels
    load = os.getloadavg()
    rows = measure(subdivisions, size, 1 if a.quick else a.repeat)
    kernels = kernel_times(subdivisions, size, 3 if a.quick else 20)
    out = dict(load_before=load, load_after=os.getloadavg(), size=size, rows=rows,
               kernels=kernels)
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")
    if a.plot:
        plot(rows, kernels, a.plot)


if __name__ == "__main__":
    main()
