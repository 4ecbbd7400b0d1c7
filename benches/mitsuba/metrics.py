"""Image metrics against a reference, numpy only.

* PSNR of images clipped to [0, 1]: `10 log10(1 / MSE)`, MSE over pixels and channels.
* relMSE: `mean((x - r)^2 / (r^2 + eps))`, eps = 0.01 (the usual guard for dark pixels,
  as in Rousselle et al. 2011), unclipped.
* SSIM (Wang et al. 2004) of the clipped images: 11 x 11 Gaussian window, sigma 1.5,
  L = 1, C1 = (0.01 L)^2, C2 = (0.03 L)^2, statistics over the 'valid' windows only
  (no padding), mean over the SSIM map and the channels.
"""

import numpy as np

RELMSE_EPS = 0.01


def psnr(image, reference):
    a = np.clip(image, 0.0, 1.0)
    b = np.clip(reference, 0.0, 1.0)
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0.0 else 10.0 * np.log10(1.0 / mse)


def relmse(image, reference):
    return float(np.mean((image - reference) ** 2 / (reference**2 + RELMSE_EPS)))


def _gauss_window(size=11, sigma=1.5):
    t = np.arange(size) - (size - 1) / 2.0
    g = np.exp(-(t**2) / (2.0 * sigma**2))
    return g / g.sum()


def _filter_valid(x, g):
    """Separable 'valid' correlation of a 2D array with the 1D window g on both axes."""
    n = len(g)
    rows = sum(g[k] * x[:, k : x.shape[1] - n + 1 + k] for k in range(n))
    return sum(g[k] * rows[k : rows.shape[0] - n + 1 + k, :] for k in range(n))


def ssim_channel(a, b, size=11, sigma=1.5):
    g = _gauss_window(size, sigma)
    c1, c2 = (0.01) ** 2, (0.03) ** 2
    mu_a, mu_b = _filter_valid(a, g), _filter_valid(b, g)
    saa = _filter_valid(a * a, g) - mu_a**2
    sbb = _filter_valid(b * b, g) - mu_b**2
    sab = _filter_valid(a * b, g) - mu_a * mu_b
    num = (2 * mu_a * mu_b + c1) * (2 * sab + c2)
    den = (mu_a**2 + mu_b**2 + c1) * (saa + sbb + c2)
    return float(np.mean(num / den))


def ssim(image, reference):
    a = np.clip(image, 0.0, 1.0)
    b = np.clip(reference, 0.0, 1.0)
    return float(np.mean([ssim_channel(a[..., c], b[..., c]) for c in range(a.shape[2])]))


def all_metrics(image, reference):
    return {"psnr": psnr(image, reference), "relmse": relmse(image, reference), "ssim": ssim(image, reference)}


def box_film(xs, ys, values, width, height):
    """The box film of scattered samples: the mean of the samples in each pixel (H, W, C);
    a pixel without samples is 0."""
    px = np.clip(np.floor(xs).astype(np.int64), 0, width - 1)
    py = np.clip(np.floor(ys).astype(np.int64), 0, height - 1)
    idx = py * width + px
    counts = np.bincount(idx, minlength=width * height).astype(np.float64)
    out = np.zeros((width * height, values.shape[1]))
    for c in range(values.shape[1]):
        out[:, c] = np.bincount(idx, weights=values[:, c], minlength=width * height)
    out /= np.maximum(counts, 1.0)[:, None]
    return out.reshape(height, width, values.shape[1])
