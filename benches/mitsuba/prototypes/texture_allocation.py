#!/usr/bin/env python3
"""Split a plan row's gap to the best film into allocation and estimator (issue 38, texture rows).

For each (scene, spp) of a `suite.py plan` run kept in WORKDIR (its `{scene}-128x128-{spp}-all.npy`):

* box: the per-pixel mean of the plan's own samples against Mitsuba's box film at the same spp
  (a worse box at equal count is the plan's allocation/pattern losing), clipped PSNR;
* estimator: the plan's final image against that mean (`d_psnr_mean` of the row);
* the allocation in the model `E = mean_P s_P^2 / n_P` (the box's error with iid samples),
  `s_P^2` the variance of one sample in pixel P (channels clipped to [0, 1], averaged) taken
  from Mitsuba's cached 16 spp samples (independent of the plan): the plan's counts `n_P`
  against uniform `N` and Neyman `n_P = max(f, lambda s_P)` (floor f = N/2, mean N), in dB
  over uniform; and the Spearman correlation of `n_P` with `s_P`.

    PY=/work/venv-mitsuba/bin/python
    $PY benches/mitsuba/prototypes/texture_allocation.py --rows ROWS.json --workdir WORKDIR [--scenes ...]
"""
import argparse
import json
import os

import numpy as np

CACHE = "/work/suite-cache"


def psnr(a, b):
    return 10 * np.log10(1.0 / np.mean((np.clip(a, 0, 1) - np.clip(b, 0, 1)) ** 2))


def pixel_stats(s, w, h):
    px = np.clip(np.floor(s[:, 0]).astype(int), 0, w - 1)
    py = np.clip(np.floor(s[:, 1]).astype(int), 0, h - 1)
    idx = py * w + px
    n = np.bincount(idx, minlength=w * h).astype(float)
    raw = np.stack([np.bincount(idx, weights=s[:, 2 + c], minlength=w * h) for c in range(3)], 1)
    mean = raw / np.maximum(n, 1)[:, None]
    # the spread of clipped values (what a display shows; as `refiner/pixel_spread.rs`)
    v = np.clip(s[:, 2:5], 0, 1)
    sums = np.stack([np.bincount(idx, weights=v[:, c], minlength=w * h) for c in range(3)], 1)
    sq = np.stack([np.bincount(idx, weights=v[:, c] ** 2, minlength=w * h) for c in range(3)], 1)
    cm = sums / np.maximum(n, 1)[:, None]
    var = (sq - n[:, None] * cm**2) / np.maximum(n - 1, 1)[:, None]
    return n, mean.reshape(h, w, 3), np.maximum(var, 0).mean(1)


def neyman(s, N, floor):
    lo, hi = 0.0, 1e9
    for _ in range(200):
        lam = 0.5 * (lo + hi)
        if np.maximum(floor, lam * s).mean() < N:
            lo = lam
        else:
            hi = lam
    return np.maximum(floor, lo * s)


def rank(x):
    r = np.empty(len(x))
    r[np.argsort(x, kind="stable")] = np.arange(len(x))
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--scenes", nargs="+")
    a = ap.parse_args()
    rows = json.load(open(a.rows))["rows"]
    print("| scene | spp | plan − best | = box: plan's − Mitsuba's box | + estimator (d_psnr_mean) | + Mitsuba box − best film | model E: plan counts / Neyman floor N/2 / Neyman no floor, dB over uniform | Spearman(n_P, s_P) | pixels at the floor | max n_P |")
    print("|---|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    for r in rows:
        sc, N = r["scene"], r["spp"]
        if a.scenes and sc not in a.scenes:
            continue
        path = os.path.join(a.workdir, f"{sc}-128x128-{N}-all.npy")
        if not os.path.exists(path):
            continue
        ref = np.load(f"{CACHE}/{sc}/ref.npy").astype(float)
        h, w, _ = ref.shape
        n, mean, _ = pixel_stats(np.load(path), w, h)
        _, _, v16 = pixel_stats(np.load(f"{CACHE}/{sc}/samples-16.npy"), w, h)
        box = np.load(f"{CACHE}/{sc}/film-box-{N}.npy").astype(float)
        p_box, m_box = psnr(mean, ref), psnr(box, ref)
        E = lambda cnt: np.mean(v16 / cnt)
        uni = E(np.full(w * h, float(N)))
        ney_f = E(neyman(np.sqrt(v16), N, N / 2))
        ney_0 = E(neyman(np.sqrt(v16), N, 1.0))
        rho = np.corrcoef(rank(n), rank(np.sqrt(v16)))[0, 1]
        db = lambda e: 10 * np.log10(uni / e)
        print(f"| {sc} | {N} | {r['d_psnr_best']:+.2f} | {p_box - m_box:+.2f} | {r['d_psnr_mean']:+.2f} | "
              f"{m_box - r['best_psnr']:+.2f} | {db(E(n)):+.2f} / {db(ney_f):+.2f} / {db(ney_0):+.2f} | "
              f"{rho:.2f} | {np.mean(n <= n.min()):.0%} | {int(n.max())} |")


if __name__ == "__main__":
    main()
