#!/usr/bin/env python3
"""The plan's output pixels compared on a finished harness run: for each scene's plan state
and samples left in the harness's work folder (`suite.py plan --workdir WD`), `rkwave
reconstruct --dim 2 --state` with the state's output pixels set to each estimate (the rounds
do not depend on it), scored against the suite's reference (PSNR of images clipped to [0, 1],
relMSE of the HDR values, as the suite's harness), beside the per-pixel mean of the plan's
own samples and Mitsuba's box film of uniform samples at the same spp (the same sample count:
the split of a loss between where the plan puts its samples and how its final image
estimates the pixels from them). Nothing is rendered.

    python benches/mitsuba/plan_pixels.py --workdir WD --spp 16 --scenes stripes grid \
        --rkwave target/release/rkwave [--placement]

`--placement` adds, per row, where the plan put its samples: the per-pixel counts, and the
pixels in quarters by texture (the variance of the uniform samples inside each pixel, summed
over channels) with their mean count and the clipped MSE of the plan's final image, of the
mean of the plan's samples and of the mean of the uniform samples at the same spp.

`--by-count` adds, per row, the pixels binned by how many samples the plan gave them: the
clipped MSE of the mean of the plan's samples in each bin beside the MSE of Mitsuba's box
films at 4 / 8 / 16 / 32 (35) spp on the same pixels (what uniform stratified samples at
those counts would give there) and the bin's share of the plan's error.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

import metrics  # noqa: E402
import oidn  # noqa: E402

ESTIMATES = ["fit_only", "residual_clamped", "shrunk", "auto", "blend"]
DEFAULT_CACHE = os.environ.get("RKWAVE_SUITE_CACHE", "/work/suite-cache")


def cell(img, ref):
    return f"{metrics.psnr(img, ref):.2f} ({metrics.relmse(img, ref):.3g})"


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--rkwave", required=True)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, nargs="+", default=[16])
    ap.add_argument("--scenes", nargs="+", default=["stripes", "grid", "thinlens"])
    ap.add_argument("--cache", default=DEFAULT_CACHE, help="the suite's cache (SCENE/ref.npy)")
    ap.add_argument("--estimates", nargs="+", default=ESTIMATES, help="the output estimates")
    ap.add_argument("--placement", action="store_true", help="counts and texture quarters")
    ap.add_argument("--by-count", action="store_true", help="error by the pixels' sample counts")
    args = ap.parse_args()
    n = args.resolution
    cols = args.estimates + ["mean of the plan's samples", "box film (uniform samples)"]
    print("PSNR dB (relMSE)\n")
    print("| scene | spp | " + " | ".join(cols) + " |")
    print("|---|---:|" + "---:|" * len(cols))
    for scene in args.scenes:
        for spp in args.spp:
            tag = f"{scene}-{n}x{n}-{spp}"
            state = os.path.join(args.workdir, f"{tag}-plan")
            samples = os.path.join(args.workdir, f"{tag}-all.npy")
            if not os.path.exists(samples):
                continue
            ref = np.load(os.path.join(args.cache, scene, "ref.npy"))
            cells = []
            with tempfile.TemporaryDirectory() as tmp:
                for est in args.estimates:
                    copy = os.path.join(tmp, est)
                    shutil.copytree(state, copy)
                    path = os.path.join(copy, "state.json")
                    with open(path) as fh:
                        st = json.load(fh)
                    st["params"]["pixels"] = est
                    with open(path, "w") as fh:
                        json.dump(st, fh)
                    out = os.path.join(tmp, f"{est}.npy")
                    subprocess.run(["nice", args.rkwave, "reconstruct", "--dim", "2", "--state", copy,
                                    "--input", samples, "--output", out, "--force"],
                                   check=True, capture_output=True)
                    cells.append(cell(np.load(out).astype(np.float64), ref))
            mean, _, _, _ = oidn.pixel_mean(np.load(samples), n, n)
            cells.append(cell(mean, ref))
            box = os.path.join(args.cache, scene, f"film-box-{spp}.npy")
            cells.append(cell(np.load(box).astype(np.float64), ref) if os.path.exists(box) else "-")
            print(f"| {scene} | {spp} | " + " | ".join(cells) + " |", flush=True)
            if args.placement:
                placement(args, scene, spp, samples, ref)
            if args.by_count:
                by_count(args, scene, spp, samples, ref)


def placement(args, scene, spp, samples, ref):
    """Where the plan put its samples against the texture of each pixel (module docs)."""
    n = args.resolution
    s = np.load(samples)
    plan = np.load(os.path.join(args.workdir, f"{scene}-{n}x{n}-{spp}-adaptive.npy")).astype(np.float64)
    pm, counts, _, _ = oidn.pixel_mean(s, n, n)
    u = np.load(os.path.join(args.cache, scene, f"samples-{spp}.npy"))
    um, uc, _, _ = oidn.pixel_mean(u, n, n)
    idx = (np.clip(np.floor(u[:, 1]).astype(int), 0, n - 1) * n
           + np.clip(np.floor(u[:, 0]).astype(int), 0, n - 1))
    k = np.maximum(uc.ravel(), 1)
    texture = sum(np.bincount(idx, weights=u[:, 2 + c] ** 2, minlength=n * n) / k
                  - (np.bincount(idx, weights=u[:, 2 + c], minlength=n * n) / k) ** 2 for c in range(3))
    c = counts.ravel()
    print(f"  {scene} {spp}: plan's samples a pixel min {c.min():.0f}, median {np.median(c):.0f}, "
          f"max {c.max():.0f}; {np.mean(c < spp):.0%} of pixels below {spp}, {np.mean(c > 2 * spp):.0%} above {2 * spp}")
    clip = np.clip(ref, 0, 1)
    order = np.argsort(texture)
    q = len(order) // 4

    def mse(img, sel):
        return ((np.clip(img, 0, 1) - clip) ** 2).reshape(-1, 3)[sel].mean()

    for i, name in enumerate(["least textured quarter", "2nd quarter", "3rd quarter", "most textured quarter"]):
        sel = order[i * q:(i + 1) * q]
        print(f"    {name:22s} mean count {c[sel].mean():5.1f}; MSE final {mse(plan, sel):.2e}, "
              f"plan's mean {mse(pm, sel):.2e}, uniform mean {mse(um, sel):.2e}")


COUNT_BINS = [0, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 1 << 30]


def by_count(args, scene, spp, samples, ref):
    """The mean of the plan's samples against uniform films, pixels binned by the plan's count."""
    n = args.resolution
    pm, counts, _, _ = oidn.pixel_mean(np.load(samples), n, n)
    c = counts.ravel()
    clip = np.clip(ref, 0, 1)

    def err(img):
        return ((np.clip(img, 0, 1) - clip) ** 2).reshape(-1, 3).mean(1)

    ep = err(pm)
    films = {}
    for k in (4, 8, 16, 32):
        path = os.path.join(args.cache, scene, f"film-box-{k}.npy")
        if os.path.exists(path):
            films[k] = err(np.load(path).astype(np.float64))
    print(f"  {scene} {spp}: MSE of the plan's mean {ep.mean():.3e}; by the plan's samples a pixel "
          f"(pixels; plan's mean; box film at {' / '.join(map(str, films))} spp on the same pixels; share of the error):")
    for a, b in zip(COUNT_BINS[:-1], COUNT_BINS[1:]):
        sel = (c > a) & (c <= b)
        if sel.any():
            films_cell = " / ".join(f"{films[k][sel].mean():.2e}" for k in films)
            print(f"    ({a}, {min(b, int(c.max()))}]: {sel.sum()}; {ep[sel].mean():.2e}; "
                  f"{films_cell}; {ep[sel].sum() / ep.sum():.2f}")


if __name__ == "__main__":
    main()
