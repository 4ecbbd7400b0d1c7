"""Prototype (numpy + PyWavelets): noise-aware pixel estimates on the harness's sample sets.

What it asks: on real renders, what does a pixel estimate gain from (a) clamping a fit's pixel
to the range of its own samples (high dynamic range: least-squares ringing next to an
emitter), and (b) soft wavelet shrinkage of the box pixels with the noise level estimated
from the samples themselves, sigma_c = sqrt(median over pixels of s^2_c / n) (s^2 the
unbiased spread of a pixel's n samples in channel c: the variance of its mean), at the
universal threshold sigma sqrt(2 ln N) (Donoho-Johnstone), on an orthonormal Haar transform
averaged over the 16 shifts (dx, dy) in {0..3}^2 (cycle spinning). SURE's threshold is printed
beside it.

It reads what `harness.py` left in its work folders (`{scene}-{W}x{W}-{spp}-samples.npy`:
the uniform multijitter samples, x, y in pixel units, r, g, b) and the cached references; it
runs no renderer and no rkwave. Lab code, not part of any test.

    /work/venv-mitsuba/bin/pip install -r benches/mitsuba/requirements.txt
    /work/venv-mitsuba/bin/python benches/mitsuba/prototypes/noise_shrinkage.py \
        --workdir /tmp/rkwave-mitsuba-work /tmp/rkwave-mitsuba-work-thinlens
"""

import argparse
import glob
import os
import sys

import numpy as np
import pywt

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from metrics import psnr  # noqa: E402


def box_and_variance(samples, width):
    """Box pixels and the variance of each pixel's mean, `(H, W, C)` each."""
    ix = np.clip(np.floor(samples[:, 0]).astype(int), 0, width - 1)
    iy = np.clip(np.floor(samples[:, 1]).astype(int), 0, width - 1)
    v = samples[:, 2:]
    shape = (width, width, v.shape[1])
    s1, s2, n = np.zeros(shape), np.zeros(shape), np.zeros((width, width))
    np.add.at(s1, (iy, ix), v)
    np.add.at(s2, (iy, ix), v * v)
    np.add.at(n, (iy, ix), 1.0)
    n = n[..., None]
    mean = s1 / n
    spread = (s2 / n - mean**2) * n / (n - 1.0)
    return mean, spread / n


def sure_threshold(x, sigma):
    a = np.sort(np.abs(x.ravel()))
    k = np.arange(1, a.size + 1)
    risk = a.size * sigma**2 - 2 * sigma**2 * k + np.cumsum(a**2) + (a.size - k) * a**2
    return min(a[np.argmin(risk)], sigma * np.sqrt(2 * np.log(a.size)))


def shrink(image, mean_variance, rule, factor=1.0, shifts=4):
    out = np.zeros_like(image)
    for dy in range(shifts):
        for dx in range(shifts):
            im = np.roll(image, (dy, dx), (0, 1))
            for c in range(image.shape[2]):
                coeffs = pywt.wavedec2(im[..., c], "haar", mode="periodization")
                sigma = np.sqrt(np.median(mean_variance[..., c]))
                new = [coeffs[0]]
                for d in coeffs[1:]:
                    if rule == "universal":
                        t = factor * sigma * np.sqrt(2 * np.log(im[..., c].size))
                    else:
                        t = sure_threshold(np.concatenate([q.ravel() for q in d]), sigma)
                    new.append(tuple(np.sign(q) * np.maximum(np.abs(q) - t, 0.0) for q in d))
                rec = pywt.waverec2(new, "haar", mode="periodization")
                out[..., c] += np.roll(rec, (-dy, -dx), (0, 1))
    return out / shifts**2


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--workdir", nargs="+", default=["/tmp/rkwave-mitsuba-work"])
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/rkwave-mitsuba"))
    args = ap.parse_args()
    print("| scene | spp | box | universal | universal x0.7 | SURE | sigma (r, g, b) |")
    print("|---|---|---|---|---|---|---|")
    for folder in args.workdir:
        for path in sorted(glob.glob(os.path.join(folder, "*-samples.npy"))):
            scene, size, spp = os.path.basename(path).split("-")[:3]
            width = int(size.split("x")[0])
            refs = glob.glob(os.path.join(args.cache, f"ref-{scene}-{size}-1024spp-*.npy"))
            if not refs:
                continue
            ref = np.load(refs[0])
            box, var = box_and_variance(np.load(path), width)
            sig = np.sqrt(np.median(var, axis=(0, 1)))
            print(
                f"| {scene} | {spp} | {psnr(box, ref):.2f} "
                f"| {psnr(shrink(box, var, 'universal'), ref):.2f} "
                f"| {psnr(shrink(box, var, 'universal', 0.7), ref):.2f} "
                f"| {psnr(shrink(box, var, 'sure'), ref):.2f} "
                f"| {', '.join(f'{s:.2g}' for s in sig)} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
