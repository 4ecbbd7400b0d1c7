"""Intel Open Image Denoise (`pyoidn`, CPU) on a film, the bar a Mitsuba or Cycles user would
reach for, and the per-pixel mean of scattered samples (the input a denoiser takes).

* `denoise(color, albedo=None, normal=None)`: OIDN's `RT` filter, `hdr=True` (radiance is
  unbounded), quality `high`; with auxiliary images `clean_aux=True` (they are rendered at
  256 spp by Mitsuba's `aov` integrator, box film: noise-free enough not to need OIDN's
  prefiltering). Negative or non-finite colour values are an error (OIDN's HDR input must be
  nonnegative): raised, never clipped silently. Returns (image float64, seconds).
* `pixel_mean(samples, w, h)`: the per-pixel mean of `m x 5` samples and the sample count of
  every pixel; a pixel without samples takes the mean of the samples in the smallest square
  window (radius 1, 2, ...) around it that holds any, and the number of such pixels and the
  largest radius used are returned, so the filling is never silent.
"""

import time

import numpy as np

_DEVICE = None


def denoise(color, albedo=None, normal=None):
    import pyoidn

    c = np.ascontiguousarray(color, dtype=np.float32)
    if not np.all(np.isfinite(c)):
        raise ValueError("OIDN input has non-finite values; fix the renderer's output first")
    if c.min() < 0:
        raise ValueError(f"OIDN's HDR input must be nonnegative; minimum {c.min():.3g}")
    kw = {}
    if albedo is not None:
        kw["albedo"] = np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), dtype=np.float32)
    if normal is not None:
        kw["normal"] = np.ascontiguousarray(np.clip(normal, -1.0, 1.0), dtype=np.float32)
    t0 = time.perf_counter()
    out = pyoidn.denoise(c, hdr=True, clean_aux=bool(kw), quality="high", **kw)
    return np.asarray(out, dtype=np.float64), time.perf_counter() - t0


def pixel_mean(samples, w, h):
    """(image (h, w, 3), counts (h, w), filled pixels, largest fill radius)."""
    s = np.asarray(samples, dtype=np.float64)
    px = np.clip(np.floor(s[:, 0]).astype(np.int64), 0, w - 1)
    py = np.clip(np.floor(s[:, 1]).astype(np.int64), 0, h - 1)
    idx = py * w + px
    counts = np.bincount(idx, minlength=w * h).astype(np.float64).reshape(h, w)
    sums = np.stack([np.bincount(idx, weights=s[:, 2 + c], minlength=w * h) for c in range(3)],
                    axis=1).reshape(h, w, 3)
    img = sums / np.maximum(counts, 1.0)[..., None]
    empty = np.argwhere(counts == 0)
    radius_max = 0
    for j, i in empty:
        r = 1
        while True:
            j0, j1, i0, i1 = max(j - r, 0), min(j + r + 1, h), max(i - r, 0), min(i + r + 1, w)
            n = counts[j0:j1, i0:i1].sum()
            if n > 0 or r > max(w, h):
                break
            r += 1
        if n > 0:
            img[j, i] = sums[j0:j1, i0:i1].sum(axis=(0, 1)) / n
        radius_max = max(radius_max, r)
    return img, counts, int(len(empty)), radius_max
