#!/usr/bin/env python3
"""Issue 38, helper "media": why the plan's final image falls below uniform `auto` on the
participating-media rows. For each (scene, spp) of a `suite.py plan` workdir (kept files
`{scene}-128x128-{spp}-all.npy`, `-adaptive.npy`), prints PSNR / relMSE against the
reference of:

- `plan`: the plan's final image (whatever --output-pixels its run used);
- `auto|shrunk|box on plan`: `reconstruct --dim 2 --pixels X` on the plan's own samples;
- `auto|shrunk|box on mitsuba`: the same on Mitsuba's cached samples at that spp;
- with `--renders` (Mitsuba renders, `render.Renderer`, fixed seeds 77-79): the plan's
  positions rendered again in one batch (each pixel's path dimensions stratified together, as
  a Mitsuba film's are; the loop renders each round apart), Mitsuba's own sampler at the
  plan's per-pixel counts (the allocation without the plan's positions) and Mitsuba's sampler
  at `spp` in every pixel (a second uniform render), each by `auto` and `box`;
and the per-pixel count histogram of the plan's samples, and `auto`'s squared error on the
plan's samples per count class against `auto` on Mitsuba's samples in the same pixels.

    media_diag.py --rkwave BIN --workdir W --scenes fog --spp 4 8 16 [--renders] [--cache /work/suite-cache]
"""
import argparse
import os
import subprocess
import sys
import json

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import metrics  # noqa: E402


def rec(binary, samples, pixels, tmp, w=128, h=128):
    inp, out = os.path.join(tmp, "in.npy"), os.path.join(tmp, "out.npy")
    np.save(inp, np.ascontiguousarray(samples, dtype=np.float64))
    p = subprocess.run([binary, "reconstruct", "--dim", "2", "--input", inp, "--resolution", f"{w}x{h}",
                        "--output", out, "--force", "--json", "--pixels", pixels], capture_output=True, text=True)
    if p.returncode:
        raise SystemExit(p.stderr)
    return np.load(out).astype(np.float64), json.loads(p.stdout)


def counts_of(s, w=128, h=128):
    px = np.clip(np.floor(s[:, 0]).astype(int), 0, w - 1)
    py = np.clip(np.floor(s[:, 1]).astype(int), 0, h - 1)
    return np.bincount(py * w + px, minlength=w * h), py * w + px


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rkwave", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--scenes", nargs="+", required=True)
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--cache", default="/work/suite-cache")
    ap.add_argument("--estimators", nargs="+", default=["auto", "shrunk", "box"])
    ap.add_argument("--renders", action="store_true", help="render the one-batch and Mitsuba-sampler splits")
    a = ap.parse_args()
    tmp = os.path.join(a.workdir, "diag")
    os.makedirs(tmp, exist_ok=True)
    for scene in a.scenes:
        ref = np.load(os.path.join(a.cache, scene, "ref.npy")).astype(np.float64)
        for spp in a.spp:
            tag = os.path.join(a.workdir, f"{scene}-128x128-{spp}")
            s = np.load(tag + "-all.npy")
            mits = np.load(os.path.join(a.cache, scene, f"samples-{spp}.npy"))
            rows = [("plan", np.load(tag + "-adaptive.npy").astype(np.float64))]
            for e in a.estimators:
                rows.append((f"{e} on plan", rec(a.rkwave, s, e, tmp)[0]))
                rows.append((f"{e} on mitsuba", rec(a.rkwave, mits, e, tmp)[0]))
            n, _ = counts_of(s)
            if a.renders:
                import suite  # noqa: F401  (sets Mitsuba's variant)
                import suite_scenes as ss
                from render import Renderer

                ren = Renderer(ss.load(scene, 128, 128, "box", spp))
                for name, smp in [("plan positions, one batch", ren.render_positions(s[:, :2], 77, spp)),
                                  ("mitsuba sampler @plan counts", ren.render_pixels(n.reshape(128, 128), 78)),
                                  ("mitsuba sampler @spp (seed 79)", ren.render_pixels(np.full((128, 128), spp), 79))]:
                    for e in ("auto", "box"):
                        rows.append((f"{e} on {name}", rec(a.rkwave, smp, e, tmp)[0]))
            hist = np.bincount(n)
            print(f"\n{scene} {spp} spp: plan counts per pixel: min {n.min()} median {np.median(n):.0f} "
                  f"max {n.max()}; pixels with n<=2: {int((n <= 2).sum())}, n>={2*spp}: {int((n >= 2*spp).sum())}; "
                  f"hist {dict((k, int(v)) for k, v in enumerate(hist) if v)}")
            for name, img in rows:
                print(f"  {name:40s} {metrics.psnr(img, ref):7.2f} dB  relMSE {metrics.relmse(img, ref):.4g}")
            rc = np.clip(ref, 0, 1)
            se = {k: (((np.clip(img, 0, 1) - rc) ** 2).sum(axis=2).ravel()) for k, img in rows
                  if k in ("auto on plan", "auto on mitsuba")}
            if len(se) == 2:
                for lo, hi in [(0, 2), (3, 4), (5, 8), (9, 16), (17, 1 << 30)]:
                    sel = (n >= lo) & (n <= hi)
                    if sel.any():
                        print(f"  pixels with {lo}-{hi} plan samples ({sel.sum()}): auto's squared error a pixel on "
                              f"the plan's samples {se['auto on plan'][sel].mean():.3g}, on Mitsuba's "
                              f"{se['auto on mitsuba'][sel].mean():.3g}")


if __name__ == "__main__":
    main()
