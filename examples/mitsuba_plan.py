#!/usr/bin/env python3
"""Mitsuba 3 renders a scene through rkwave.Plan, in process: the plan hands out each round's
film positions, Mitsuba answers with radiance, until the plan stops; the image is written
beside Mitsuba's own film at the same samples per pixel, with the PSNR of both against a
high-spp reference.

    pip install mitsuba ./python            # from the repository root
    python examples/mitsuba_plan.py --scene direct --resolution 128 --spp 8 --out mitsuba-out
    python examples/mitsuba_plan.py --resolution 16 --spp 4 --ref-spp 16   # small (CI)

The scenes, the per-sample renderer (`Renderer.render_positions`: Mitsuba's
`SamplingIntegrator::render_sample` steps at given positions), the cached reference and the
metrics are those of the Mitsuba benchmark harness (benches/mitsuba), imported from there.
Times: the renderer's seconds (Mitsuba called from Python one sample at a time), rkwave's
seconds inside the library (fits, positions, the image), and the rest of the loop outside
both (conversion, copies, Python glue), as a share of the whole loop.
"""

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "benches", "mitsuba"))

import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)

import numpy as np  # noqa: E402

import rkwave  # noqa: E402
import metrics  # noqa: E402  (benches/mitsuba)
import scenes  # noqa: E402
from harness import reference  # noqa: E402
from render import Renderer  # noqa: E402


def plan_loop(renderer, width, height, spp, seed):
    """The renderer in rkwave.Plan's loop; returns the image, the plan and the seconds of the
    whole loop."""
    t0 = time.perf_counter()
    plan = rkwave.Plan(resolution=(width, height), spp=spp, seed=seed)
    k = 0
    while not plan.done:
        xy = plan.positions()
        rendered = renderer.render_positions(xy, seed * 7919 + k, spp)
        plan.add(xy, rendered[:, 2:])
        k += 1
    image = plan.image()
    return image, plan, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="direct", choices=["direct", "cornell", "thinlens"])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--film", default="gaussian", choices=scenes.FILTERS,
                    help="Mitsuba's film filter for the side-by-side render (its default: gaussian)")
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/rkwave-mitsuba"))
    ap.add_argument("--out", default="mitsuba-plan-out")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    w = h = args.resolution
    ref, _ = reference(args.scene, w, h, args.ref_spp, args.cache)

    renderer = Renderer(scenes.load(args.scene, w, h, "box", args.spp))
    image, plan, loop_s = plan_loop(renderer, w, h, args.spp, args.seed)
    report = plan.report
    library_s = report["time_s"]["library"]
    outside_s = loop_s - renderer.seconds - library_s

    film_scene = scenes.load(args.scene, w, h, args.film, args.spp)
    t0 = time.perf_counter()
    film = np.array(mi.render(film_scene, spp=args.spp, seed=args.seed), dtype=np.float64)
    film_s = time.perf_counter() - t0

    os.makedirs(args.out, exist_ok=True)
    # Written synchronously: `write_bitmap`'s default (`write_async=True`) hands the EXR to
    # Mitsuba's thread pool, and on a 2-core machine the interpreter then never exits (every
    # thread parked at exit, OpenEXR's pool waiting on a semaphore); a plain write returns.
    for name, pixels in [("rkwave_plan", image), (f"mitsuba_{args.film}", film)]:
        mi.util.write_bitmap(os.path.join(args.out, f"{name}.exr"), pixels.astype(np.float32),
                             write_async=False)
    np.save(os.path.join(args.out, "rkwave_plan.npy"), image)
    np.save(os.path.join(args.out, f"mitsuba_{args.film}.npy"), film)

    summary = {
        "scene": args.scene, "resolution": [w, h], "spp": args.spp, "ref_spp": args.ref_spp,
        "samples": report["samples"], "rounds": report["round"] + 1,
        "psnr_rkwave_plan": metrics.psnr(image, ref),
        f"psnr_mitsuba_{args.film}": metrics.psnr(film, ref),
        "loop_s": loop_s, "renderer_s": renderer.seconds, "rkwave_library_s": library_s,
        "outside_s": outside_s, "outside_share": outside_s / loop_s,
        "rkwave_glue_s": report["time_s"]["glue"], f"mitsuba_{args.film}_render_s": film_s,
    }
    if args.json:
        print(json.dumps(summary, indent=2))
        return
    print(f"{args.scene} {w}x{h}, {args.spp} spp (reference {args.ref_spp} spp):")
    print(f"  rkwave.Plan      PSNR {summary['psnr_rkwave_plan']:.2f} dB  "
          f"({report['samples']} samples in {summary['rounds']} rounds)")
    print(f"  mitsuba {args.film:<8} PSNR {summary[f'psnr_mitsuba_{args.film}']:.2f} dB  "
          f"(mi.render, {film_s:.2f} s)")
    print(f"  plan loop {loop_s:.2f} s: renderer {renderer.seconds:.2f} s, rkwave {library_s:.2f} s, "
          f"outside both {outside_s:.3f} s ({100 * summary['outside_share']:.1f}%)")
    print(f"  wrote {args.out}/rkwave_plan.exr and mitsuba_{args.film}.exr (and .npy)")


if __name__ == "__main__":
    main()
