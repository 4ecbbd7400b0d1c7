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


if __name__ == "__main__":
    main()
