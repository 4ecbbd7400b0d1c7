"""A Cycles-style adaptive sampler at a fixed total budget, box film.

Blender Cycles (`kernel/film/adaptive_sampling.h`) keeps two buffers per pixel: I, every
sample, and A, every other sample. Its per-pixel error is

    error = (|I_r - 2A_r| + |I_g - 2A_g| + |I_b - 2A_b|) / n  /  (1e-4 + sqrt((I_r+I_g+I_b) / n)),

the difference of the two half buffers relative to the square root of the pixel's
brightness; pixels under a threshold stop. Here, for equal total samples instead of a
threshold: every pixel first gets n0 = spp/2 samples (at least 2, one per half); the rest,
(spp - n0) x pixels, is spent in four equal rounds, each giving `n0` more samples to the
quarter of the pixels with the largest error. Differences from Cycles, stated: a ranking
instead of a threshold (so that the budget is exact) and no dilation of unconverged pixels
to their neighbours. The image is the box film (the mean of each pixel's samples).
"""

import numpy as np

from metrics import box_film

ROUNDS = 4


def cycles_adaptive(renderer, width, height, spp, seed):
    """Returns (image (H, W, 3), samples m x 5, counts (H, W))."""
    n0 = max(2, spp // 2)
    counts = np.full((height, width), n0, dtype=np.int64)
    batches = [renderer.render_pixels(counts, seed)]
    budget_left = (spp - n0) * width * height
    per_round = budget_left // ROUNDS
    for r in range(ROUNDS):
        if budget_left <= 0:
            break
        err = _error(np.vstack(batches), width, height)
        k = min(width * height, min(per_round, budget_left) // n0)
        if k == 0:
            break
        chosen = np.argsort(-err.ravel(), kind="stable")[:k]
        extra = np.zeros(width * height, dtype=np.int64)
        extra[chosen] = n0
        extra = extra.reshape(height, width)
        batches.append(renderer.render_pixels(extra, seed + 17 * (r + 1)))
        counts += extra
        budget_left -= k * n0
    samples = np.vstack(batches)
    return box_film(samples[:, 0], samples[:, 1], samples[:, 2:], width, height), samples, counts


def _error(samples, width, height):
    """Cycles' error per pixel; the half buffer A takes every other sample of each pixel
    (in the order rendered)."""
    px = np.floor(samples[:, 0]).astype(np.int64).clip(0, width - 1)
    py = np.floor(samples[:, 1]).astype(np.int64).clip(0, height - 1)
    pix = py * width + px
    order = np.argsort(pix, kind="stable")
    sp = pix[order]
    first = np.r_[0, np.flatnonzero(sp[1:] != sp[:-1]) + 1]
    rank = np.arange(len(sp)) - np.repeat(first, np.diff(np.r_[first, len(sp)]))
    in_a = np.zeros(len(sp), dtype=bool)
    in_a[order] = rank % 2 == 0
    n = np.bincount(pix, minlength=width * height).astype(np.float64)
    diff = np.zeros(width * height)
    total = np.zeros(width * height)
    for c in range(3):
        v = samples[:, 2 + c]
        i_sum = np.bincount(pix, weights=v, minlength=width * height)
        a_sum = np.bincount(pix[in_a], weights=v[in_a], minlength=width * height)
        diff += np.abs(i_sum - 2.0 * a_sum)
        total += i_sum
    n = np.maximum(n, 1.0)
    err = (diff / n) / (1e-4 + np.sqrt(np.maximum(total, 0.0) / n))
    return err.reshape(height, width)
