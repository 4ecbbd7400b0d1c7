#!/usr/bin/env python3
"""The plan's output pixels compared on a finished harness run: for each scene's plan state
and samples left in the harness's work folder, `rkwave reconstruct --dim 2 --state` with the
state's output pixels set to each estimate (the rounds do not depend on it), PSNR against the
cached reference. Nothing is rendered.

    python benches/mitsuba/plan_pixels.py --workdir /tmp/rkwave-mitsuba-work --spp 8 \
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

ESTIMATES = ["residual_clamped", "shrunk", "box_shrunk", "auto"]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--rkwave", required=True)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--scenes", nargs="+", default=["direct", "cornell", "thinlens"])
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/rkwave-mitsuba"))
    ap.add_argument("--mitsuba", default="3.9.1", help="version in the reference's file name")
    ap.add_argument("--estimates", nargs="+", default=ESTIMATES, help="the output estimates")
    args = ap.parse_args()
    n = args.resolution
    print("| scene | spp | " + " | ".join(args.estimates) + " |")
    print("|---|---:|" + "---:|" * len(args.estimates))
    for scene in args.scenes:
        tag = f"{scene}-{n}x{n}-{args.spp}"
        state = os.path.join(args.workdir, f"{tag}-plan")
        samples = os.path.join(args.workdir, f"{tag}-all.npy")
        if not os.path.exists(samples):
            continue
        ref = np.load(os.path.join(args.cache, f"ref-{scene}-{n}x{n}-1024spp-mitsuba{args.mitsuba}.npy"))
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
                cells.append(f"{metrics.psnr(np.load(out), ref):.2f}")
        print(f"| {scene} | {args.spp} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
