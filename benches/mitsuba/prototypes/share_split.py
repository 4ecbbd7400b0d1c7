#!/usr/bin/env python3
"""Which part of the plan's final image loses on the pixel share's uneven counts (issue 38,
helper "shareuneven"): the final image re-run on kept plan states with each output pixel
estimate, scored against the reference, and the squared error split by the pixels' sample
counts.

    PY=/work/venv-mitsuba/bin/python
    $PY benches/mitsuba/prototypes/share_split.py --rkwave BIN --workdir W [W2 ...] --scenes cornell rough --spp 4 \
        [--pixels box auto shrunk blend] [--json F]

Each W is a `suite.py plan --workdir W` folder (the kept states `NAME-128x128-SPP-plan` and
samples `...-all.npy`); the states are copied to a temporary folder, so W is only read.
`box` is the plain per-pixel mean of the plan's samples (no rkwave call). Per estimate the
row gives PSNR (clipped to [0, 1]) and relMSE against the cached reference, and per class of
per-pixel count `n_P` (2, 3-4, 5-8, 9+; fewer than 2: the floor keeps none) the share of the
pixels and the class's mean clipped squared error `(1 / |C|) sum_{P in C} |x_P - r_P|^2 / 3`
in dB (`-10 log10`), so a class that loses shows at once. Beside it the box's noise per class:
the mean of the unbiased `s^2_P / n_P` (channels averaged) against the box's measured squared
error, both unclipped: their ratio is what a per-pixel noise estimate from the pixel's own spread
would see (1: the spread is the box's error; above 1: the samples' spread overstates it, as
stratification makes it).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import metrics  # noqa: E402

CLASSES = [(2, 2), (3, 4), (5, 8), (9, 10**9)]


def per_pixel(s, w, h):
    px = np.clip(np.floor(s[:, 0]).astype(np.int64), 0, w - 1)
    py = np.clip(np.floor(s[:, 1]).astype(np.int64), 0, h - 1)
    idx = py * w + px
    n = np.bincount(idx, minlength=w * h).astype(np.float64)
    mean = np.stack([np.bincount(idx, weights=s[:, 2 + c], minlength=w * h) for c in range(3)], 1)
    mean /= np.maximum(n, 1)[:, None]
    sq = np.stack([np.bincount(idx, weights=s[:, 2 + c] ** 2, minlength=w * h) for c in range(3)], 1)
    var = (sq - n[:, None] * mean**2) / np.maximum(n - 1, 1)[:, None]
    return n.reshape(h, w), mean.reshape(h, w, 3), var.reshape(h, w, 3)


def final(binary, state, allp, pixels, tmp):
    copy = os.path.join(tmp, "plan")
    shutil.rmtree(copy, ignore_errors=True)
    shutil.copytree(state, copy)
    path = os.path.join(copy, "state.json")
    st = json.load(open(path))
    st["params"]["pixels"] = pixels
    json.dump(st, open(path, "w"))
    out = os.path.join(tmp, "out.npy")
    cmd = [binary, "reconstruct", "--dim", "2", "--state", copy, "--input", allp, "--output", out, "--force", "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{p.stderr}")
    return np.load(out).astype(np.float64), json.loads(p.stdout)


def db(x):
    return float("inf") if x <= 0 else -10 * np.log10(x)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rkwave", required=True)
    ap.add_argument("--workdir", nargs="+", required=True)
    ap.add_argument("--scenes", nargs="+", default=["cornell"])
    ap.add_argument("--spp", type=int, nargs="+", default=[4])
    ap.add_argument("--pixels", nargs="+", default=["box", "auto", "shrunk", "blend"])
    ap.add_argument("--cache", default="/work/suite-cache")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--json")
    a = ap.parse_args()
    w = h = a.res
    rows = []
    for name in a.scenes:
        ref = np.load(os.path.join(a.cache, name, "ref.npy")).astype(np.float64)
        refc = np.clip(ref, 0, 1)
        for spp in a.spp:
            for wd in a.workdir:
                tag = f"{name}-{w}x{h}-{spp}"
                allp = os.path.join(wd, f"{tag}-all.npy")
                s = np.load(allp).astype(np.float64)
                n, box, var = per_pixel(s, w, h)
                cls = [(lo, hi, (n >= lo) & (n <= hi)) for lo, hi in CLASSES]
                err2 = ((box - ref) ** 2).mean(-1)
                noise = (var / np.maximum(n, 1)[..., None]).mean(-1)
                head = f"{name} {spp} {wd}: counts " + ", ".join(
                    f"{lo}-{hi if hi < 10**9 else '+'} {m.mean():.0%} (box err/spread "
                    f"{err2[m].mean() / max(noise[m].mean(), 1e-30):.2f})" for lo, hi, m in cls if m.any())
                print(head)
                with tempfile.TemporaryDirectory() as tmp:
                    for pix in a.pixels:
                        if pix == "box":
                            img, rep = box, None
                        else:
                            img, rep = final(a.rkwave, os.path.join(wd, f"{tag}-plan"), allp, pix, tmp)
                        e = ((np.clip(img, 0, 1) - refc) ** 2).mean(-1)
                        r = {"scene": name, "spp": spp, "workdir": wd, "pixels": pix,
                             "psnr": metrics.psnr(img, ref), "relmse": metrics.relmse(img, ref),
                             "classes": [{"counts": [lo, hi], "share": float(m.mean()),
                                          "psnr": db(e[m].mean()),
                                          "mse_share": float(e[m].sum() / max(e.sum(), 1e-300))}
                                         for lo, hi, m in cls if m.any()]}
                        if rep is not None:
                            px = rep.get("pixels", {})
                            r["blend_weight_shrunk"] = px.get("blend_weight")
                            r["shrink_sigma"] = px.get("shrink_sigma")
                        rows.append(r)
                        print(f"  {pix:12s} {r['psnr']:6.2f} dB relMSE {r['relmse']:.4g}  " + "  ".join(
                            f"[{c['counts'][0]}-{c['counts'][1] if c['counts'][1] < 10**9 else '+'}] "
                            f"{c['psnr']:5.2f} dB ({c['mse_share']:.0%} of the error)" for c in r["classes"]))
    if a.json:
        json.dump({"command": " ".join(sys.argv), "rows": rows}, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
