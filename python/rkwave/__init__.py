"""rkwave: reconstruction of functions from scattered samples by least squares in sparse,
adaptive CDV interval wavelet bases (numpy in, numpy out).

1D::

    >>> import numpy as np, rkwave
    >>> x = np.random.default_rng(1).uniform(-1, 1, 5000)
    >>> f = rkwave.fit(x, np.sin(3 * x), domain=(-1, 1), p=4)
    >>> bool(abs(f(np.array([0.5]))[0] - np.sin(1.5)) < 1e-6)
    True

The image plane (positions in pixel units, ``(H, W, C)`` out; the pixel estimate is
``pixels="auto"`` by default, as ``rkwave reconstruct --dim 2``'s, ``pixels="fit"`` the
wavelet fit)::

    >>> xy = np.random.default_rng(2).uniform(0, 32, (4 * 32 * 32, 2))
    >>> image, report = rkwave.reconstruct_image(xy, xy[:, 0] / 32, resolution=(32, 32))
    >>> image.shape
    (32, 32, 1)

Adaptive sampling driven by a renderer: ``rkwave.Plan``; in 1D with a Python oracle:
``rkwave.adapt``. Samples too many for one process: ``rkwave.partial`` (1D, chunk by chunk)
and ``rkwave.fit_tile`` (one image tile), which ``rkwave.dask`` runs on a Dask cluster
(``pip install dask[distributed]``). Errors are ``rkwave.RkwaveError`` (a ``ValueError``) with the command
line's message, ``rkwave.ResourceLimitError`` (a ``MemoryError``) for refused allocations;
fallbacks are ``rkwave.RkwaveWarning`` warnings.

Arrays of any stride, float64 or float32, are accepted; float32 (or anything else numpy turns
into float64) is converted to float64 once; contiguous float64 data is read in place.
"""

from rkwave._rkwave import (
    Fit,
    PartialFits,
    Plan,
    ResourceLimitError,
    RkwaveError,
    RkwaveWarning,
    TileGeometry,
    __version__,
    adapt,
    auto_levels,
    fit,
    fit_tile,
    local_vs_global,
    partial,
    reconstruct_image,
    set_memory_limit,
)

__all__ = [
    "Fit",
    "PartialFits",
    "Plan",
    "ResourceLimitError",
    "RkwaveError",
    "RkwaveWarning",
    "TileGeometry",
    "__version__",
    "adapt",
    "auto_levels",
    "fit",
    "fit_tile",
    "local_vs_global",
    "partial",
    "reconstruct_image",
    "set_memory_limit",
]
