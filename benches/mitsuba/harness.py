#!/usr/bin/env python3
"""Mitsuba 3 as rkwave's real renderer: Mitsuba's five films, rkwave uniform, rkwave
adaptive (`plan`) and a Cycles-style adaptive sampler at equal total samples, against a
box film at >= 1024 spp. See README.md in this folder.

    python benches/mitsuba/harness.py --resolution 128 --spp 4 8 16 --json out.json
    python benches/mitsuba/harness.py --quick
    python benches/mitsuba/harness.py --fixtures data/renders --resolution 64 --spp 4
"""

import argparse
import json
import os
import platform
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)  # multijitter warns when it rounds a count up

import numpy as np  # noqa: E402

import cycles  # noqa: E402
import metrics  # noqa: E402
import scenes  # noqa: E402
from render import Renderer  # noqa: E402
from rkwave_cli import Rkwave  # noqa: E402

REF_SEED = 999_999


def reference(name, w, h, spp, cache):
    """Mitsuba's box film at `spp` (multijitter), cached as .npy in `cache`."""
    os.makedirs(cache, exist_ok=True)
    path = os.path.join(cache, f"ref-{name}-{w}x{h}-{spp}spp-mitsuba{mi.__version__}.npy")
    if os.path.exists(path):
        return np.load(path), None
    scene = scenes.load(name, w, h, "box", spp)
    t0 = time.perf_counter()
    img = np.array(mi.render(scene, spp=spp, seed=REF_SEED), dtype=np.float64)
    dt = time.perf_counter() - t0
    np.save(path, img)
    return img, dt


def row(scene, spp, method, image, ref, render_s, rkwave_s, samples, extra=None):
    r = {"scene": scene, "spp": spp, "method": method, **metrics.all_metrics(image, ref),
         "render_s": render_s, "rkwave_s": rkwave_s, "samples": int(samples)}
    if extra:
        r.update(extra)
    return r


def run_scene(name, w, h, spp, args, rk, ref):
    rows = []
    pixels = w * h
    # Mitsuba's five films, each rendered by Mitsuba itself (sampling included).
    for f in scenes.FILTERS:
        scene = scenes.load(name, w, h, f, spp)
        t0 = time.perf_counter()
        img = np.array(mi.render(scene, spp=spp, seed=args.seed), dtype=np.float64)
        rows.append(row(name, spp, f"mitsuba {f}", img, ref, time.perf_counter() - t0, 0.0, spp * pixels))
    scene = scenes.load(name, w, h, "box", spp)
    # rkwave uniform on Mitsuba's own (multijitter) positions.
    ren = Renderer(scene)
    samples = ren.render_pixels(np.full((h, w), spp), args.seed)
    tag = f"{name}-{w}x{h}-{spp}"
    img, dt, used = rk.uniform(samples, w, h, tag)
    rows.append(row(name, spp, "rkwave uniform", img, ref, ren.seconds, dt, len(samples),
                    {"estimate": used}))
    img, dt, used = rk.uniform(samples, w, h, tag, pixels="fit")
    rows.append(row(name, spp, "rkwave fit (old uniform)", img, ref, ren.seconds, dt, len(samples),
                    {"estimate": used}))
    box = metrics.box_film(samples[:, 0], samples[:, 1], samples[:, 2:], w, h)
    rows.append(row(name, spp, "box of the same samples", box, ref, ren.seconds, 0.0, len(samples)))
    # rkwave adaptive: the plan loop, the renderer answering each round.
    if not args.no_adaptive:
        ren = Renderer(scene)
        img, s_all, dt, rounds = rk.adaptive(
            lambda p, seed: ren.render_positions(p, args.seed * 7919 + seed, spp), w, h, spp, tag,
            seed=args.seed, extra=args.plan_args.split())
        rows.append(row(name, spp, "rkwave adaptive (plan)", img, ref, ren.seconds, dt, len(s_all),
                        {"rounds": rounds}))
    if args.no_cycles:
        return rows
    # Cycles-style adaptive sampler at the same total samples, box film.
    ren = Renderer(scene)
    t0 = time.perf_counter()
    img, s_all, _ = cycles.cycles_adaptive(ren, w, h, spp, args.seed + 101)
    total = time.perf_counter() - t0
    rows.append(row(name, spp, "cycles-style adaptive", img, ref, ren.seconds,
                    total - ren.seconds, len(s_all)))
    return rows


def table(rows):
    lines = ["| scene | spp | method | PSNR (dB) | relMSE | SSIM | render (s) | rkwave (s) | samples |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['spp']} | {r['method']} | {r['psnr']:.2f} | {r['relmse']:.3g} | "
            f"{r['ssim']:.4f} | {r['render_s']:.2f} | {r['rkwave_s']:.2f} | {r['samples']} |")
    return "\n".join(lines)


def write_fixtures(args, w, h):
    """Small rendered sample sets with their references, for `cargo test`."""
    os.makedirs(args.fixtures, exist_ok=True)
    meta = {"mitsuba": mi.__version__, "variant": mi.variant(), "seed": args.seed,
            "resolution": [w, h], "ref_spp": args.ref_spp, "command": " ".join(sys.argv),
            "sets": []}
    for name in args.scenes:
        for spp in args.spp:
            ref, _ = reference(name, w, h, args.ref_spp, args.cache)
            ren = Renderer(scenes.load(name, w, h, "box", spp))
            s = ren.render_pixels(np.full((h, w), spp), args.seed)
            s32 = s.astype(np.float32)
            # Keep each float32 position inside its pixel's open interior: rounding to
            # float32 may land on an integer (the next pixel's edge) or on W or H.
            for c, size in ((0, w), (1, h)):
                cell = np.floor(s[:, c])
                lo = cell.astype(np.float32)
                hi = np.nextafter((cell + 1).astype(np.float32), np.float32(0))
                s32[:, c] = np.clip(s32[:, c], np.nextafter(lo, np.float32(size)), hi)
            base = f"{name}-{w}x{h}-{spp}spp"
            np.save(os.path.join(args.fixtures, f"{base}-samples.npy"), s32)
            # The reference as a table of pixel centres: (x + 1/2, y + 1/2, r, g, b), row-major,
            # float64, so that it loads through rkwave's sample reader.
            ys, xs = np.mgrid[0:h, 0:w]
            table_ = np.column_stack([xs.ravel() + 0.5, ys.ravel() + 0.5, ref.reshape(-1, 3)])
            np.save(os.path.join(args.fixtures, f"{name}-{w}x{h}-reference.npy"), table_)
            s64 = s32.astype(np.float64)
            box = metrics.box_film(s64[:, 0], s64[:, 1], s64[:, 2:], w, h)
            meta["sets"].append({"samples": f"{base}-samples.npy",
                                 "reference": f"{name}-{w}x{h}-reference.npy",
                                 "scene": name, "spp": spp,
                                 "box_psnr_numpy": metrics.psnr(box, ref),
                                 "box_relmse_numpy": metrics.relmse(box, ref),
                                 "box_ssim_numpy": metrics.ssim(box, ref)})
            print(f"fixture {base}: box PSNR {meta['sets'][-1]['box_psnr_numpy']:.3f} dB")
    with open(os.path.join(args.fixtures, "fixtures.json"), "w") as fh:
        json.dump(meta, fh, indent=2)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resolution", type=int, default=128, help="width = height (default 128)")
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--scenes", nargs="+", default=list(scenes.SCENES), choices=scenes.SCENES)
    ap.add_argument("--ref-spp", type=int, default=1024, help="reference box film spp (>= 1024)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rkwave", default="/work/main/target/release/rkwave")
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/rkwave-mitsuba"),
                    help="folder for the references (outside the repository)")
    ap.add_argument("--workdir", default="/tmp/rkwave-mitsuba-work")
    ap.add_argument("--json", help="write every row to this JSON file")
    ap.add_argument("--quick", action="store_true", help="32x32, 4 spp, 256-spp references")
    ap.add_argument("--no-adaptive", action="store_true", help="skip the plan loop")
    ap.add_argument("--no-cycles", action="store_true", help="skip the Cycles-style sampler")
    ap.add_argument("--plan-args", default="",
                    help="extra flags for the plan's first call, e.g. '--spread indicator'")
    ap.add_argument("--fixtures", help="write the fixtures (samples + references) into this folder")
    args = ap.parse_args()
    if args.quick:
        args.resolution, args.spp, args.ref_spp = 32, [4], 256
    w = h = args.resolution
    if args.fixtures:
        write_fixtures(args, w, h)
        return
    rk = Rkwave(args.rkwave, args.workdir)
    rows = []
    meta = {"mitsuba": mi.__version__, "variant": mi.variant(), "resolution": [w, h],
            "ref_spp": args.ref_spp, "seed": args.seed, "command": " ".join(sys.argv),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores", "references": {}}
    for name in args.scenes:
        ref, dt = reference(name, w, h, args.ref_spp, args.cache)
        meta["references"][name] = dt
        for spp in args.spp:
            new = run_scene(name, w, h, spp, args, rk, ref)
            for r in new:
                used = f" (--pixels {r['estimate']})" if "estimate" in r else ""
                print(f"{r['scene']:9s} {r['spp']:3d} {r['method']:26s} {r['psnr']:7.2f} dB "
                      f"relMSE {r['relmse']:.3g} SSIM {r['ssim']:.4f} render {r['render_s']:.2f} s "
                      f"rkwave {r['rkwave_s']:.2f} s{used}", flush=True)
            rows.extend(new)
            if args.json:
                with open(args.json, "w") as fh:
                    json.dump({"meta": meta, "rows": rows}, fh, indent=2)
    print()
    print(table(rows))


if __name__ == "__main__":
    main()
