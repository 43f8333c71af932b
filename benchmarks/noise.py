"""Noise-driven sampling (``aa = "noise"``) against uniform stratified sampling, in one run.

    python3 benchmarks/noise.py                       # whitted, mesh_model, area_light 160×120
    python3 benchmarks/noise.py --json out.json       # the table's numbers as JSON too
    python3 benchmarks/noise.py --curves docs/sampling  # + error-against-time curves, PNG each
    python3 benchmarks/noise.py --min-spp 8            # noise-driven renders from 8 samples
    python3 benchmarks/noise.py --seeds 10             # + the two ratios, interleaved

For each scene (2 threads, a reference of ``--reference-spp`` uniform samples with another
seed, kept in ``--cache``): uniform 16 spp, timed (best of ``--repeats`` after a warm-up);
then noise-driven renders (best of ``--repeats`` each; by time limit, the median by samples
of at least 3, :func:`timed`)

* stopped by a time limit of uniform 16 spp's wall seconds: its RMSE over uniform's (target
  ≤ 0.7);
* stopped by a target error of uniform 16 spp's measured relative RMSE: its wall seconds over
  uniform's (target ≤ 0.5), and the RMSE it reached over uniform's;
* ``--target-error 0.01``: the relative RMSE measured (target within [0.0067, 0.015]) and the
  renderer's estimate;
* the default threshold (0.01, 8 to 1024 samples).

``--seeds K`` adds, per scene, the two ratios of the targets measured so that the machine's
drift cancels (:func:`interleaved`): seed by seed, uniform 16 spp and then a render by its
error, each timed once; then, seed by seed, a render by a time limit of the median uniform
time; the medians over the seeds of the time ratio, and of each render's RMSE over uniform's
(of the same seed).

``--curves FOLDER`` adds, per scene, the error-against-time curves of four ways to spend
time: uniform stratified spp (:data:`CURVE_SPP`), the corner-adaptive mode at its defaults
and at ``aa_min_depth`` 1, noise-driven sampling stopped by ``--target-error``
(:data:`CURVE_TARGETS`) and by ``--time-limit`` (:data:`CURVE_TIMES` times uniform 16 spp's
wall seconds): a table, and ``noise_curves_<scene>.png`` (relative RMSE against CPU seconds,
log-log; matplotlib, the ``dev`` extra, imported there).

RMSE over linear RGB; relative RMSE is the RMSE over the reference's mean. Wall seconds of
``raytrace.render`` (build included), as ``--stats`` reports them, and CPU seconds (every
thread's), which a loaded machine moves less. The allocator is set up as the ``raytrace``
command sets it (:func:`raytrace.malloc.tune`): with glibc's default thresholds the Whitted
scene's main thread took 16 ms between its two rounds, tuned 9 ms (the allocation's arrays
of a few hundred KiB each mapped afresh).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from functools import partial
from pathlib import Path

import numpy as np
from bench_scenes import scene_path

import raytrace
from raytrace import malloc

ROOT = Path(__file__).resolve().parent.parent


def timed(scene, repeats: int, **kw) -> tuple[raytrace.Image, float, float]:
    """The image of the fastest of ``repeats`` renders (wall), its wall seconds and the
    fewest CPU seconds of any (every thread's, ``time.process_time``). A render by
    ``time_limit`` takes about the limit whatever it reaches, so the fastest would be the one
    that traced least: of at least 3 such renders, the one of median samples instead, with
    its own seconds."""
    runs = []
    for _ in range(max(repeats, 3) if "time_limit" in kw else repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = raytrace.render(scene, **kw)
        runs.append((time.perf_counter() - t0, time.process_time() - c0, out))
    if "time_limit" in kw:
        runs.sort(key=lambda run: run[2].stats["aa"]["samples"])
        seconds, cpu, image = runs[len(runs) // 2]
        return image, seconds, cpu
    seconds, _, image = min(runs, key=lambda run: run[0])
    return image, seconds, min(run[1] for run in runs)


def reference(scene, name: str, spp: int, cache: Path, **common) -> np.ndarray:
    """The scene's reference image: ``spp`` uniform samples, seed 12345, kept in ``cache``."""
    w, h = common["width"], common["height"]
    path = cache / f"{name}_{w}x{h}_{spp}spp.npy"
    if path.exists():
        return np.load(path)
    cache.mkdir(parents=True, exist_ok=True)
    rgb = raytrace.render(scene, spp=spp, seed=12345, **common).rgb.astype(np.float64)
    np.save(path, rgb)
    return rgb


def rms_error(image: raytrace.Image, ref: np.ndarray) -> float:
    """The RMSE of ``image``'s linear RGB against ``ref`` (a :func:`reference`), in float64."""
    return float(np.sqrt(np.mean((image.rgb.astype(np.float64) - ref) ** 2)))


#: Uniform stratified sample counts of the curves (perfect squares: a k×k jittered grid).
CURVE_SPP = (1, 4, 16, 64, 256)
#: ``--target-error`` values of the curves (relative RMSE).
CURVE_TARGETS = (0.1, 0.05, 0.02, 0.01, 0.005)
#: ``--time-limit`` values of the curves, in multiples of uniform 16 spp's wall seconds.
CURVE_TIMES = (0.25, 0.5, 1.0, 2.0, 4.0)


def curves(scene, common: dict, rmse, level: float, t_u: float, repeats: int) -> dict:
    """The four series of the curves (module docstring), each a list of rows (label, wall
    seconds, CPU seconds, samples a pixel, relative RMSE, the renderer's estimate or None)."""
    def row(label: str, **kw) -> dict:
        image, seconds, cpu = timed(scene, repeats, **common, **kw)
        st = image.stats.get("aa", {})
        return {"label": label, "seconds": seconds, "cpu": cpu,
                "spp": st.get("samples_per_pixel", kw.get("spp", 1)),
                "relative_rmse": rmse(image) / level,
                "estimate": st.get("estimated_relative_rmse")}
    return {
        "uniform": [row(f"{n}", spp=n) for n in CURVE_SPP],
        "adaptive": [row("defaults", aa="adaptive"),
                     row("min depth 1", aa="adaptive", aa_min_depth=1)],
        "noise, by target error": [row(f"{e:g}", target_error=e) for e in CURVE_TARGETS],
        "noise, by time limit": [row(f"{f:g}x", time_limit=f * t_u) for f in CURVE_TIMES]}


def interleaved(scene, common: dict, rmse, level: float, seeds: int, **first) -> dict:
    """The targets' two ratios over ``seeds`` seeds, interleaved (module docstring): the
    medians of the time of a render by uniform 16 spp's error over uniform's, of its RMSE
    over uniform's, and of the RMSE of a render by uniform's median time over uniform's;
    ``first``: the noise-driven renders' ``min_spp``, where given."""
    uniform, by_error = [], []
    for seed in range(seeds):
        t0 = time.perf_counter()
        image = raytrace.render(scene, spp=16, seed=seed, **common)
        t1 = time.perf_counter()
        e = rmse(image)
        noisy = raytrace.render(scene, target_error=e / level, seed=seed, **common, **first)
        by_error.append(((time.perf_counter() - t1) / (t1 - t0), rmse(noisy) / e))
        uniform.append((t1 - t0, e))
    limit = float(np.median([t for t, _ in uniform]))
    by_time = [rmse(raytrace.render(scene, time_limit=limit, seed=seed, **common, **first)) / e
               for seed, (_, e) in enumerate(uniform)]
    return {"seeds": seeds, "uniform_seconds": limit,
            "time_to_error": float(np.median([r for r, _ in by_error])),
            "rmse_reached": float(np.median([r for _, r in by_error])),
            "rmse_at_time": float(np.median(by_time))}


def plot_curves(name: str, size: tuple[int, int], threads: int, series: dict,
                folder: Path) -> Path:
    """``noise_curves_<name>.png``: relative RMSE against CPU seconds, log-log, a series each
    way of spending time, each point labelled (spp, target, or time multiple; the renders of
    a series that stopped at the same image under one label)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    # (the series by target labelled below left, so that their labels and the others' part)
    styles = (("o-", (4, 4), "left"), ("s", (4, 4), "left"), ("^-", (-4, -10), "right"),
              ("v-", (4, 4), "left"))
    for (label, rows), (fmt, offset, align) in zip(series.items(), styles, strict=True):
        ax.plot([r["cpu"] for r in rows], [r["relative_rmse"] for r in rows], fmt, label=label)
        labels: dict[float, list] = {}  # renders that stopped at the same image: one label
        for r in rows:
            labels.setdefault(r["relative_rmse"], [r, []])[1].append(r["label"])
        for r, names in labels.values():
            ax.annotate(", ".join(names), (r["cpu"], r["relative_rmse"]), ha=align,
                        textcoords="offset points", xytext=offset, fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"render CPU seconds ({threads} threads, all threads' time)")
    ax.set_ylabel("relative RMSE against the reference")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"{name} {size[0]}×{size[1]}", fontsize=10)
    fig.tight_layout()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"noise_curves_{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--size", type=int, nargs=2, default=(160, 120))
    p.add_argument("--reference-spp", type=int, default=1024)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--scenes", nargs="*", default=["whitted", "mesh_model", "area_light"])
    p.add_argument("--cache", type=Path, default=Path("/tmp/raytrace-noise-references"))
    p.add_argument("--min-spp", type=int, help="the noise-driven renders' first round "
                   "(default: the renderer's, 4 by target or time, 8 by threshold)")
    p.add_argument("--seeds", type=int, default=0,
                   help="also measure the targets' two ratios over this many seeds, "
                   "interleaved (medians)")
    p.add_argument("--json", type=Path)
    p.add_argument("--curves", type=Path, metavar="FOLDER",
                   help="also measure the error-against-time curves; their PNGs go here")
    a = p.parse_args()
    malloc.tune()  # as the command line does, whose --stats wall seconds issue #30 reads
    w, h = a.size
    out = {}
    for name in a.scenes:
        scene = raytrace.load_scene(scene_path(name))
        common = dict(width=w, height=h, threads=a.threads)
        raytrace.render(scene, width=32, height=24, threads=1)  # warm-up
        raytrace.render(scene, width=32, height=24, threads=1, aa="noise")
        ref = reference(scene, name, a.reference_spp, a.cache, **common)
        level = float(ref.mean())

        rmse = partial(rms_error, ref=ref)

        uniform, t_u, c_u = timed(scene, a.repeats, spp=16, **common)
        e_u = rmse(uniform)
        rows = {"uniform 16 spp": (t_u, c_u, 16.0, e_u, None)}
        runs = {"noise, time limit = uniform's": dict(time_limit=t_u),
                "noise, target = uniform's error": dict(target_error=e_u / level),
                "noise, --target-error 0.01": dict(target_error=0.01),
                "noise, threshold 0.01 (default)": dict(aa="noise")}
        first = {} if a.min_spp is None else {"min_spp": a.min_spp}
        for label, kw in runs.items():
            image, seconds, cpu = timed(scene, a.repeats, **common, **kw, **first)
            st = image.stats["aa"]
            rows[label] = (seconds, cpu, st["samples_per_pixel"], rmse(image),
                           st["estimated_relative_rmse"])
        print(f"\n{name} {w}x{h}, {a.threads} threads, reference {a.reference_spp} spp "
              f"(seed 12345, mean {level:.4f})")
        print(f"{'render':<34}{'wall s':>8}{'CPU s':>8}{'spp':>7}{'rmse':>11}{'rel rmse':>10}"
              f"{'estimate':>10}")
        for label, (seconds, cpu, spp, e, est) in rows.items():
            print(f"{label:<34}{seconds:>8.3f}{cpu:>8.3f}{spp:>7.1f}{e:>11.3e}"
                  f"{e / level:>10.4f}{'' if est is None else f'{est:10.4f}'}")
        at_time = rows["noise, time limit = uniform's"]
        to_error = rows["noise, target = uniform's error"]
        print(f"RMSE at uniform 16 spp's wall time: {at_time[3] / e_u:.2f}x uniform's (target "
              f"<= 0.7); time to uniform's error: {to_error[0] / t_u:.2f}x wall, "
              f"{to_error[1] / c_u:.2f}x CPU (target <= 0.5, reaching {to_error[3] / e_u:.2f}x "
              f"its RMSE); --target-error 0.01 measured "
              f"{rows['noise, --target-error 0.01'][3] / level:.4f} (target 0.0067-0.015)")
        out[name] = {"mean": level, "rows": {k: dict(zip(
            ("seconds", "cpu", "spp", "rmse", "estimate"), v, strict=True))
            for k, v in rows.items()}}
        if a.seeds:
            medians = interleaved(scene, common, rmse, level, a.seeds, **first)
            print(f"interleaved over {a.seeds} seeds (medians): RMSE at uniform 16 spp's wall "
                  f"time {medians['rmse_at_time']:.2f}x uniform's; time to uniform's error "
                  f"{medians['time_to_error']:.2f}x wall (reaching "
                  f"{medians['rmse_reached']:.2f}x its RMSE); uniform "
                  f"{medians['uniform_seconds']:.3f} s")
            out[name]["interleaved"] = medians
        if a.curves:
            series = curves(scene, common, rmse, level, t_u, a.repeats)
            print(f"\n{name}: error against time ({'wall s':>6}, CPU s, spp, relative RMSE, "
                  "estimate)")
            for label, series_rows in series.items():
                for r in series_rows:
                    est = "" if r["estimate"] is None else f"{r['estimate']:10.4f}"
                    print(f"{label + ' ' + r['label']:<34}{r['seconds']:>8.3f}{r['cpu']:>8.3f}"
                          f"{r['spp']:>7.1f}{r['relative_rmse']:>10.4f}{est}")
            out[name]["curves"] = series
            print("wrote", plot_curves(name, (w, h), a.threads, series, a.curves))
    out["load_average_end"] = list(os.getloadavg())
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
