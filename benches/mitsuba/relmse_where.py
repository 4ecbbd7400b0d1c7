#!/usr/bin/env python3
"""Where the squared relative error of the plan's final image sits, against Mitsuba's best film.

For each (scene, spp) of a finished `suite.py plan --workdir WD` run: the final image
(`WD/SCENE-128x128-SPP-adaptive.npy`, or `--images DIR/SCENE-128x128-SPP.npy`), the suite's
reference and the best of Mitsuba's films by PSNR (as `suite.py`). Per row: relMSE (HDR, eps
0.01, `metrics.relmse`) over the best film's, PSNR (clipped) over the film's, the share of the image's summed squared relative
error in four classes of pixels -- dark (reference luminance, the mean of the channels,
below 0.1), mid (0.1 to 1), bright (1 and above, where the clipped and HDR views differ), edges
(the top 10 % of `|grad ref| / (ref + 0.1)`) -- and the excess over the film's in each class
(summed over the class, divided by all pixels: the classes' excesses add up to the difference of
the two relMSEs, edges overlapping the others); at the end the geometric mean of the ratios
and the mean PSNR gain. Nothing is rendered.

    python benches/mitsuba/relmse_where.py --workdir WD --scenes fog stripes --spp 4 8 16
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

import metrics  # noqa: E402

FILMS = ["box", "tent", "gaussian", "mitchell", "lanczos"]
DEFAULT_CACHE = os.environ.get("RKWAVE_SUITE_CACHE", "/work/suite-cache")


def relative_error(image, ref):
    """The squared relative error per pixel, the mean over channels (metrics.relmse's terms)."""
    return ((image - ref) ** 2 / (ref**2 + metrics.RELMSE_EPS)).mean(axis=2)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--images", help="final images DIR/SCENE-NxN-SPP.npy instead of the run's own")
    ap.add_argument("--cache", default=DEFAULT_CACHE)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--scenes", nargs="+", required=True)
    args = ap.parse_args()
    n = args.resolution
    print("| row | relMSE / best film | PSNR − best film (dB) | share in dark / mid / bright / edges "
          "| excess over the film in dark / mid / bright / edges (x 1e-3) |")
    print("|---|---|---|---|---|")
    ratios = []
    for scene in args.scenes:
        ref = np.load(os.path.join(args.cache, scene, "ref.npy"))
        lum = ref.mean(axis=2)
        gy, gx = np.gradient(lum)
        grad = np.hypot(gx, gy) / (lum + 0.1)
        classes = [lum < 0.1, (lum >= 0.1) & (lum < 1.0), lum >= 1.0, grad > np.quantile(grad, 0.9)]
        for spp in args.spp:
            tag = f"{scene}-{n}x{n}-{spp}"
            path = (os.path.join(args.images, f"{tag}.npy") if args.images
                    else os.path.join(args.workdir, f"{tag}-adaptive.npy"))
            if not os.path.exists(path):
                continue
            image = np.load(path).astype(np.float64)
            films = {f: np.load(os.path.join(args.cache, scene, f"film-{f}-{spp}.npy")).astype(np.float64)
                     for f in FILMS}
            best = max(FILMS, key=lambda f: metrics.psnr(films[f], ref))
            ri, rf = relative_error(image, ref), relative_error(films[best], ref)
            share = " / ".join(f"{ri[m].sum() / ri.sum():.0%}" for m in classes)
            excess = " / ".join(f"{(ri[m].sum() - rf[m].sum()) / ri.size * 1e3:+.2f}" for m in classes)
            gain = metrics.psnr(image, ref) - metrics.psnr(films[best], ref)
            ratios.append((ri.mean() / rf.mean(), gain))
            print(f"| {scene} {spp} | {ri.mean() / rf.mean():.3f} ({best}) | {gain:+.2f} | {share} | {excess} |",
                  flush=True)
    if ratios:
        r = np.array(ratios)
        print(f"\n{len(r)} rows: geometric mean relMSE / best film {np.exp(np.mean(np.log(r[:, 0]))):.4f}, "
              f"mean PSNR − best film {np.mean(r[:, 1]):+.3f} dB, relMSE above the film's on {int(np.sum(r[:, 0] > 1))}")


if __name__ == "__main__":
    main()
