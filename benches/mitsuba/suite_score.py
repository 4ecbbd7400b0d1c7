"""`suite.py score | plan | table`: rows on the cached suite (see suite_cache.py for the layout).

Every row carries both measures: `psnr` of the images clipped to [0, 1] and `relmse` of the
unclipped HDR values (metrics.py), against the reference (the mean of the two 1024-spp halves).
A row is marked `near_floor` when its clipped MSE or its relMSE is below twice the
reference's own floor (the mean's floor, suite_cache.floor_stats): its error is then of the
order of the reference's and the row cannot be resolved from a better one.

Per-half means: the mean of the PSNRs and of the dB differences, and the geometric mean of
the relMSEs and of the relMSE ratios (relMSE spans orders of magnitude between scenes; an
arithmetic mean would be one scene's figure).

The range check of an output image against its samples: the global minimum and maximum of
the image and of the samples (per channel, reported as the extreme over channels), and, per
pixel and channel, the range [lo, hi] of the samples whose pixel lies within `RANGE_RADIUS`
pixels (a 5 x 5 block: the support of the widest film filter rkwave or Mitsuba uses here);
`outside_local` counts the values outside it (beyond 1e-6 relative), `outside_local_1pct` those
beyond 1 % of max(|lo|, |hi|, 0.01), `worst_below` / `worst_above` are the largest excursions
below lo / above hi.
"""

import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

import metrics
import oidn
import suite_scenes as ss
from render import Renderer
from rkwave_cli import Rkwave

RANGE_RADIUS = 2


def load(cache, name, spp):
    d = os.path.join(cache, name)
    if not os.path.exists(os.path.join(d, f"samples-{spp}.npy")):
        raise SystemExit(f"{d}/samples-{spp}.npy missing: run `suite.py cache --scenes {name} --spp {spp}` first")
    meta = json.load(open(os.path.join(d, "meta.json")))
    return {"meta": meta, "ref": np.load(os.path.join(d, "ref.npy")),
            "samples": np.load(os.path.join(d, f"samples-{spp}.npy")),
            "films": {f: np.load(os.path.join(d, f"film-{f}-{spp}.npy")).astype(np.float64) for f in ss.FILTERS},
            "albedo": np.load(os.path.join(d, "aov-albedo.npy")),
            "normal": np.load(os.path.join(d, "aov-normal.npy")),
            "rendered_spp": meta["spp"][str(spp)]["rendered_spp"]}


def range_check(img, samples, w, h, radius=RANGE_RADIUS):
    s = np.asarray(samples, dtype=np.float64)
    px = np.clip(np.floor(s[:, 0]).astype(np.int64), 0, w - 1)
    py = np.clip(np.floor(s[:, 1]).astype(np.int64), 0, h - 1)
    lo = np.full((h, w, 3), np.inf)
    hi = np.full((h, w, 3), -np.inf)
    for c in range(3):
        np.minimum.at(lo[..., c], (py, px), s[:, 2 + c])
        np.maximum.at(hi[..., c], (py, px), s[:, 2 + c])
    # Extend over the (2r+1)^2 block by repeated 3 x 3 min / max (edges replicate).
    for _ in range(radius):
        lp = np.pad(lo, ((1, 1), (1, 1), (0, 0)), mode="edge")
        hp = np.pad(hi, ((1, 1), (1, 1), (0, 0)), mode="edge")
        lo = np.min([lp[a:a + h, b:b + w] for a in range(3) for b in range(3)], axis=0)
        hi = np.max([hp[a:a + h, b:b + w] for a in range(3) for b in range(3)], axis=0)
    below = np.where(np.isfinite(lo), lo - img, 0.0)
    above = np.where(np.isfinite(hi), img - hi, 0.0)
    # "Significant": beyond 1 % of the local magnitude max(|lo|, |hi|, 0.01) (a constant sky
    # has lo = hi, where any rounding-level difference is outside).
    mag = 0.01 * np.maximum(np.maximum(np.abs(np.where(np.isfinite(lo), lo, 0)),
                                       np.abs(np.where(np.isfinite(hi), hi, 0))), 0.01)
    return {"image_min": float(img.min()), "image_max": float(img.max()),
            "samples_min": float(s[:, 2:].min()), "samples_max": float(s[:, 2:].max()),
            "outside_local": int((below > 1e-6 * np.maximum(1, np.abs(lo))).sum()
                                 + (above > 1e-6 * np.maximum(1, np.abs(hi))).sum()),
            "outside_local_1pct": int((below > mag).sum() + (above > mag).sum()),
            "worst_below": float(max(below.max(), 0.0)), "worst_above": float(max(above.max(), 0.0)),
            "radius": radius}


def _floor_mark(r, floor):
    mse = 10 ** (-r["psnr"] / 10)
    fmse = 10 ** (-floor["psnr_floor_of_mean"] / 10)
    return bool(mse < 2 * fmse or r["relmse"] < 2 * floor["relmse_floor_of_mean"])


def row(name, spp, data, method, img, render_s=0.0, tool_s=0.0, samples=None, **extra):
    r = {"scene": name, "half": "tuning" if name in ss.TUNING else "validation", "spp": spp,
         "rendered_spp": data["rendered_spp"], "method": method,
         "psnr": metrics.psnr(img, data["ref"]), "relmse": metrics.relmse(img, data["ref"]),
         "render_s": render_s, "tool_s": tool_s,
         "samples": int(samples if samples is not None else len(data["samples"]))}
    r["near_floor"] = _floor_mark(r, data["meta"]["floor"])
    r.update(extra)
    return r


def films(name, spp, data):
    t = data["meta"]["spp"][str(spp)]
    out = [row(name, spp, data, f"mitsuba {f}", data["films"][f], render_s=t.get(f"film_{f}_s", float("nan")))
           for f in ss.FILTERS]
    best = max(out, key=lambda r: r["psnr"])
    return out, best


def reconstruct(binary, samples_path, w, h, out, extra):
    """`binary reconstruct --dim 2` (inheriting this process's niceness); (image, seconds, report)."""
    cmd = [binary, "reconstruct", "--dim", "2", "--input", samples_path,
           "--resolution", f"{w}x{h}", "--output", out, "--force", "--json"] + shlex.split(extra)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    rep = json.loads(p.stdout)
    return np.load(out).astype(np.float64), dt, rep


def compare(r, mean, best):
    """The result's differences to the per-pixel mean and to the best film (dB, relMSE ratio)."""
    r["d_psnr_mean"] = r["psnr"] - mean["psnr"]
    r["relmse_ratio_mean"] = r["relmse"] / mean["relmse"]
    r["d_psnr_best"] = r["psnr"] - best["psnr"]
    r["relmse_ratio_best"] = r["relmse"] / best["relmse"]
    r["best_film"] = best["method"]
    r["mean_psnr"], r["mean_relmse"] = mean["psnr"], mean["relmse"]
    r["best_psnr"], r["best_relmse"] = best["psnr"], best["relmse"]
    return r


def _gmean(v):
    v = [x for x in v if x > 0 and np.isfinite(x)]
    return float(np.exp(np.mean(np.log(v)))) if v else float("nan")


HEAD = ("| scene | spp | result dB | relMSE | mean dB | relMSE | best film dB | relMSE | "
        "Δ mean dB | relMSE / mean | Δ best dB | relMSE / best | image min / max | samples min / max | outside local range (n, worst below, above) |")


def print_results(results, title):
    """The score/plan table, one block per half, with its means."""
    for half in ("tuning", "validation"):
        rows = [r for r in results if r["half"] == half]
        if not rows:
            continue
        print(f"\n{title}, {half} half\n")
        print(HEAD)
        print("|" + "---|" * (HEAD.count("|") - 1))
        for r in rows:
            g = r["range"]
            spp = f"{r['spp']}" + ("" if r["rendered_spp"] == r["spp"] else f" ({r['rendered_spp']})")
            mark = "†" if r.get("near_floor") else ""
            print(f"| {r['scene']} | {spp} | {r['psnr']:.2f}{mark} | {r['relmse']:.3g} | {r['mean_psnr']:.2f} | "
                  f"{r['mean_relmse']:.3g} | {r['best_psnr']:.2f} ({r['best_film'].split()[-1]}) | {r['best_relmse']:.3g} | "
                  f"{r['d_psnr_mean']:+.2f} | {r['relmse_ratio_mean']:.3g} | {r['d_psnr_best']:+.2f} | "
                  f"{r['relmse_ratio_best']:.3g} | {g['image_min']:.3g} / {g['image_max']:.3g} | "
                  f"{g['samples_min']:.3g} / {g['samples_max']:.3g} | {g['outside_local']} ({g['outside_local_1pct']} > 1 %), "
                  f"{g['worst_below']:.3g}, {g['worst_above']:.3g} |")
        for spp in sorted({r["spp"] for r in rows}) + [None]:
            sel = [r for r in rows if spp is None or r["spp"] == spp]
            lab = "all spp" if spp is None else f"{spp} spp"
            print(f"| **mean {half}, {lab}** ({len(sel)}) | | {np.mean([r['psnr'] for r in sel]):.2f} | "
                  f"{_gmean([r['relmse'] for r in sel]):.3g} | {np.mean([r['mean_psnr'] for r in sel]):.2f} | "
                  f"{_gmean([r['mean_relmse'] for r in sel]):.3g} | {np.mean([r['best_psnr'] for r in sel]):.2f} | "
                  f"{_gmean([r['best_relmse'] for r in sel]):.3g} | {np.mean([r['d_psnr_mean'] for r in sel]):+.2f} | "
                  f"{_gmean([r['relmse_ratio_mean'] for r in sel]):.3g} | {np.mean([r['d_psnr_best'] for r in sel]):+.2f} | "
                  f"{_gmean([r['relmse_ratio_best'] for r in sel]):.3g} | | | "
                  f"{sum(r['range']['outside_local'] for r in sel)} |")
    print("\n† within twice the reference's noise floor (clipped MSE or relMSE): not resolvable from a better image.")


def _dump(args, results, extra=None):
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"command": " ".join(sys.argv), "rows": results, **(extra or {})}, fh, indent=1)


def score(args, scenes, w, h):
    os.makedirs(args.workdir, exist_ok=True)
    results = []
    for name in scenes:
        for spp in args.spp:
            data = load(args.cache, name, spp)
            _, best = films(name, spp, data)
            s = data["samples"]
            box = metrics.box_film(s[:, 0], s[:, 1], s[:, 2:], w, h)
            mean = row(name, spp, data, "per-pixel mean", box)
            path = os.path.join(args.cache, name, f"samples-{spp}.npy")
            img, dt, rep = reconstruct(args.rkwave, path, w, h, os.path.join(args.workdir, f"{name}-{spp}.npy"), args.extra)
            r = row(name, spp, data, f"rkwave reconstruct {args.extra}".strip(), img, tool_s=dt,
                    pixels=rep.get("pixels"), notes=rep.get("notes"))
            r["range"] = range_check(img, s, w, h)
            results.append(compare(r, mean, best))
            print(f"{name:8s} {spp:3d} {r['psnr']:7.2f} dB (mean {mean['psnr']:.2f}, best film {best['psnr']:.2f}) "
                  f"relMSE {r['relmse']:.3g} (mean {mean['relmse']:.3g}) {dt:.2f} s", file=sys.stderr, flush=True)
            _dump(args, results)
    print_results(results, f"`{args.rkwave} reconstruct --dim 2 {args.extra}` on the cached samples")
    _dump(args, results)
    return results


def run_plan(args, name, spp, data, w, h, rk):
    """The plan loop on one scene: (final image, all samples, render seconds, rkwave seconds, rounds)."""
    n = data["rendered_spp"]
    ren = Renderer(ss.load(name, w, h, "box", n))
    tag = f"{name}-{w}x{h}-{spp}"
    img, s_all, dt, rounds = rk.adaptive(
        lambda p, seed: ren.render_positions(p, args.seed * 7919 + seed, n), w, h, n, tag,
        seed=args.seed, extra=shlex.split(args.extra))
    return img.astype(np.float64), s_all, ren.seconds, dt, rounds


def rerun_final(args, name, spp, w, h):
    """`--reuse`: the final image again from the plan state and samples a previous `plan` run
    left in `--workdir` (`BIN reconstruct --dim 2 --state`, the state's own output pixels and
    carried final fit, or `--pixels`; nothing is rendered, the positions are the kept run's). (image, all
    samples, 0 render seconds, rkwave seconds, rounds: None)."""
    tag = f"{name}-{w}x{h}-{spp}"
    state = os.path.join(args.workdir, f"{tag}-plan")
    allp = os.path.join(args.workdir, f"{tag}-all.npy")
    if not (os.path.isdir(state) and os.path.exists(allp)):
        raise SystemExit(f"--reuse: {state} or {allp} missing: run `suite.py plan` with this --workdir first")
    out = os.path.join(args.workdir, f"{tag}-reused.npy")
    with tempfile.TemporaryDirectory() as tmp:
        if getattr(args, "pixels", None):
            # the state's output pixels set to `--pixels` on a copy (the rounds do not depend on them)
            copy = os.path.join(tmp, "plan")
            shutil.copytree(state, copy)
            path = os.path.join(copy, "state.json")
            with open(path) as fh:
                st = json.load(fh)
            st["params"]["pixels"] = args.pixels
            with open(path, "w") as fh:
                json.dump(st, fh)
            state = copy
        cmd = [args.rkwave, "reconstruct", "--dim", "2", "--state", state, "--input", allp,
               "--output", out, "--force"] + shlex.split(args.extra)
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        dt = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return np.load(out).astype(np.float64), np.load(allp), 0.0, dt, None


def plan(args, scenes, w, h):
    rk = Rkwave(args.rkwave, args.workdir, nice=False)  # inherits this process's niceness
    results = []
    for name in scenes:
        for spp in args.spp:
            data = load(args.cache, name, spp)
            _, best = films(name, spp, data)
            if getattr(args, "reuse", False):
                img, s_all, rs, dt, rounds = rerun_final(args, name, spp, w, h)
            else:
                img, s_all, rs, dt, rounds = run_plan(args, name, spp, data, w, h, rk)
            pm, counts, filled, rad = oidn.pixel_mean(s_all, w, h)
            mean = row(name, spp, data, "mean of the plan's samples", pm, samples=len(s_all))
            r = row(name, spp, data, f"rkwave plan {args.extra}".strip(), img, render_s=rs, tool_s=dt,
                    samples=len(s_all), rounds=rounds, empty_pixels=filled, fill_radius=rad)
            r["range"] = range_check(img, s_all, w, h)
            results.append(compare(r, mean, best))
            print(f"{name:8s} {spp:3d} plan {r['psnr']:7.2f} dB (its samples' mean {mean['psnr']:.2f}, "
                  f"best film {best['psnr']:.2f}) relMSE {r['relmse']:.3g}, {rounds} rounds, "
                  f"{len(s_all)} samples, {filled} pixels without samples", file=sys.stderr, flush=True)
            _dump(args, results)
    print_results(results, f"`{args.rkwave} plan {args.extra}` loop (mean = the per-pixel mean of the plan's own samples)")
    _dump(args, results)
    return results


def table(args, scenes, w, h):
    """The full table: films, box of the same samples, rkwave uniform, the plan, OIDN."""
    import suite_table

    return suite_table.table(args, scenes, w, h)

