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
        --rkwave target/release/rkwave
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


if __name__ == "__main__":
    main()
