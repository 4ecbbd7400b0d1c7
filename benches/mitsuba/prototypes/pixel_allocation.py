#!/usr/bin/env python3
"""Prototype (issue 38, texture rows): a floor, then the rest of the budget over the pixels by
their own samples' spread, measured with Mitsuba (no rkwave refiner involved).

Why: per pixel, the clipped squared error of the box mean of stratified samples falls faster
than 1/n on texture past Nyquist (e ~ c_P n^-a, a = 1.1-1.8 on the suite's texture scenes,
fitted from Mitsuba's box films at 4/8/16/35 spp). Minimising sum_P c_P n_P^-a at a fixed
total gives n_P ~ c_P^(1/(1+a)) (Lagrange: a c_P n_P^-(a+1) = lambda), flatter than Neyman's
n_P ~ s_P (the a = 1 case). The plan's tree allocates by its wavelet indicator instead.

What it does, per scene and spp N (W x H pixels):
1. the floor: every pixel gets `N/2` points of its own digitally shifted Sobol (0, 2)-sequence
   (the first two Sobol dimensions, a per-pixel random XOR shift: a (0, m, 2)-net at powers
   of two, as the plan's pixel sequences);
2. per pixel the unbiased spread s_P^2 of those samples (each channel clipped to [0, 1], summed
   over channels), pooled over the 3 x 3 neighbourhood when `--pool` (a 2-sample spread is
   noisy);
3. n_P = max(N/2, lambda s_P^(2/(1+a0))) with the total exactly N W H (largest remainders),
   the next n_P - N/2 points of each pixel's sequence rendered;
4. scored: the box mean of all samples and `rkwave reconstruct --dim 2` (the uniform path's
   default pixels) on them, against the suite's reference; beside them the same with
   n_P = N everywhere (the control: should be Mitsuba's box film within noise).

    PY=/work/venv-mitsuba/bin/python
    nice $PY benches/mitsuba/prototypes/pixel_allocation.py --rkwave target/release/rkwave \
        --scenes stripes grid --spp 4 8 16 --a0 2 --pool
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

mi.set_variant("scalar_rgb")

import metrics  # noqa: E402
import oidn  # noqa: E402
import suite_scenes as ss  # noqa: E402
from render import Renderer  # noqa: E402
from rkwave_cli import Rkwave  # noqa: E402


def sobol02(count):
    """The first `count` points of the 2D Sobol (0, 2)-sequence as 32-bit integers: dimension 1
    the van der Corput sequence (bit reversal), dimension 2 the Pascal matrix mod 2."""
    bits = 32
    v1 = [1 << (bits - 1 - k) for k in range(bits)]
    v2 = []
    # direction numbers of Sobol's second dimension: v_k = v_{k-1} ^ (v_{k-1} >> 1), v_0 = 2^31
    v = 1 << (bits - 1)
    for _ in range(bits):
        v2.append(v)
        v = v ^ (v >> 1)
    out = np.zeros((count, 2), dtype=np.uint64)
    for i in range(count):
        a = b = 0
        k, j = i, 0
        while k:
            if k & 1:
                a ^= v1[j]
                b ^= v2[j]
            k >>= 1
            j += 1
        out[i] = (a, b)
    return out


def pixel_points(counts_from, counts_to, shifts, base, w):
    """Points `counts_from[p] .. counts_to[p]` of pixel p's shifted sequence, pixel units."""
    rows = []
    for p in np.flatnonzero(counts_to > counts_from):
        pts = base[counts_from[p]:counts_to[p]] ^ shifts[p]
        u = pts.astype(np.float64) / 2.0 ** 32
        rows.append(np.column_stack([u[:, 0] + p % w, u[:, 1] + p // w]))
    return np.vstack(rows)


def spread(samples, w, h, pool):
    """Per pixel the unbiased spread of the samples (channels clipped to [0, 1], summed)."""
    px = np.clip(np.floor(samples[:, 0]).astype(int), 0, w - 1)
    py = np.clip(np.floor(samples[:, 1]).astype(int), 0, h - 1)
    pix = py * w + px
    cnt = np.bincount(pix, minlength=w * h).astype(np.float64)
    var = np.zeros(w * h)
    for c in range(3):
        v = np.clip(samples[:, 2 + c], 0, 1)
        m1 = np.bincount(pix, weights=v, minlength=w * h) / np.maximum(cnt, 1)
        m2 = np.bincount(pix, weights=v * v, minlength=w * h) / np.maximum(cnt, 1)
        var += np.maximum(m2 - m1 * m1, 0) * cnt / np.maximum(cnt - 1, 1)
    if pool:
        img = np.pad(var.reshape(h, w), 1, mode="edge")
        var = sum(img[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)).ravel() / 9
    return var


def allocate(weights, total, floor):
    """Integers n_P >= floor, summing to `total`, n_P ~ max(floor, lambda w_P) (bisection on
    lambda, then the largest remainders)."""
    lo, hi = 0.0, 1.0
    while np.maximum(floor, hi * weights).sum() < total:
        hi *= 2
    for _ in range(100):
        lam = (lo + hi) / 2
        lo, hi = (lam, hi) if np.maximum(floor, lam * weights).sum() < total else (lo, lam)
    x = np.maximum(floor, lo * weights)
    n = np.floor(x).astype(np.int64)
    rest = int(total - n.sum())
    if rest > 0:
        n[np.argsort(-(x - n))[:rest]] += 1
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rkwave", required=True)
    ap.add_argument("--scenes", nargs="+", default=["stripes", "grid"])
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--a0", type=float, nargs="+", default=[2.0], help="the exponent a of e ~ n^-a")
    ap.add_argument("--pool", action="store_true", help="pool the spread over 3 x 3 pixels")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--cache", default=os.environ.get("RKWAVE_SUITE_CACHE", "/work/suite-cache"))
    ap.add_argument("--workdir", default="pixel-allocation-work")
    ap.add_argument("--json", help="write every row here")
    args = ap.parse_args()
    w = h = args.size
    rk = Rkwave(args.rkwave, args.workdir, nice=False)
    rng = np.random.default_rng(args.seed)
    base = sobol02(4096)
    rows = []
    print("PSNR dB (relMSE); box = the per-pixel mean of the samples, rkwave = reconstruct --dim 2\n")
    print("| scene | spp | allocation | samples a pixel (min / median / max) | box | rkwave | Mitsuba box film |")
    print("|---|---:|---|---|---:|---:|---:|")
    for name in args.scenes:
        ref = np.load(os.path.join(args.cache, name, "ref.npy"))
        for n in args.spp:
            film = np.load(os.path.join(args.cache, name, f"film-box-{n}.npy")).astype(np.float64)
            ren = Renderer(ss.load(name, w, h, "box", n))
            shifts = rng.integers(0, 2 ** 32, size=(w * h, 2), dtype=np.uint64)
            floor = n // 2
            zero = np.zeros(w * h, dtype=np.int64)
            pilot_n = np.full(w * h, floor, dtype=np.int64)
            pilot = ren.render_positions(pixel_points(zero, pilot_n, shifts, base, w),
                                         args.seed * 7919 + 1001, n)
            var = spread(pilot, w, h, args.pool)
            runs = [("uniform (control)", None, np.full(w * h, n, dtype=np.int64))]
            for a0 in args.a0:
                wts = np.maximum(var, 0) ** (1.0 / (1.0 + a0))
                runs.append((f"floor {floor}, rest by s^(2/(1+{a0:g}))", a0, allocate(wts, n * w * h, floor)))
            for label, a0, counts in runs:
                extra = ren.render_positions(pixel_points(pilot_n, counts, shifts, base, w),
                                             args.seed * 7919 + 1002, n)
                s = np.vstack([pilot, extra])
                box = oidn.pixel_mean(s, w, h)[0]
                img, _, used = rk.uniform(s, w, h, f"{name}-{n}")
                cell = lambda im: f"{metrics.psnr(im, ref):.2f} ({metrics.relmse(im, ref):.3g})"  # noqa: E731
                print(f"| {name} | {n} | {label} | {counts.min()} / {int(np.median(counts))} / {counts.max()} "
                      f"| {cell(box)} | {cell(img)} ({used}) | {cell(film)} |", flush=True)
                rows.append({"scene": name, "spp": n, "seed": args.seed, "allocation": label, "a0": a0,
                             "pool": args.pool, "counts_min": int(counts.min()),
                             "counts_median": float(np.median(counts)), "counts_max": int(counts.max()),
                             "box_psnr": metrics.psnr(box, ref), "box_relmse": metrics.relmse(box, ref),
                             "psnr": metrics.psnr(img, ref), "relmse": metrics.relmse(img, ref),
                             "estimate": used, "film_box_psnr": metrics.psnr(film, ref)})
                if args.json:
                    with open(args.json, "w") as f:
                        json.dump({"command": " ".join(sys.argv), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
