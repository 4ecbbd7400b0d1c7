"""1D fits of samples too many for one process, on Dask (``dask.distributed``).

``fit_chunks(chunks, domain=..., ...)`` maps each chunk of samples (a list of ``.npy`` files
``m_i x (1 + channels)``, a list of ``(x, y)`` array pairs, or a dask array ``m x (1 +
channels)`` chunked by rows) to a *partial fit* on a worker -- the banded QR triangle of its
rows, ``rkwave.partial_fit``, as bytes -- and merges the partials pairwise in a tree
(``rkwave.merge_partials``, neighbours only: the chunks must hold samples sorted by ``x``, in
order) before ``rkwave.finish_partial`` solves. The result is the ``rkwave.Fit`` of
``rkwave.fit`` on all samples: the same basis and levels; coefficients within the rounding
of the QR (a different merge tree rounds differently, ``O(eps cond(K))`` relative). Only the
partials travel (``8 P (3p - 2 + channels + 1)`` bytes for ``P`` functions at most), never the
samples. A worker lost mid-run costs its tasks' retry: every task is a pure function of its
inputs.

Dask is imported when a function here is called, not when ``rkwave.dask`` is imported:
``pip install "dask[distributed]"`` to use it.
"""

import os

import numpy as np

from rkwave import RkwaveError, finish_partial, merge_partials, partial_fit

__all__ = ["fit_chunks"]


def _dask():
    try:
        import dask
        import dask.delayed  # noqa: F401
    except ImportError as e:  # pragma: no cover - exercised without dask installed
        raise ImportError(
            'rkwave.dask needs Dask: pip install "dask[distributed]"'
        ) from e
    return dask


def _npy_rows(path):
    """Rows and columns of a .npy file from its header (no data read)."""
    if not os.path.exists(path):
        raise RkwaveError(f"cannot read `{path}`: no such file; check the list of chunks")
    try:
        a = np.load(path, mmap_mode="r")
    except Exception as e:  # numpy's own message says what is wrong
        raise RkwaveError(f"`{path}` is not a readable .npy sample file: {e}") from e
    if a.ndim != 2 or a.shape[1] < 2:
        raise RkwaveError(
            f"`{path}` has shape {a.shape}: give m x (1 + channels) samples, x in column 0"
        )
    return a.shape


def _load(chunk):
    if isinstance(chunk, (str, os.PathLike)):
        a = np.load(chunk)
        return a[:, 0], a[:, 1:]
    if isinstance(chunk, tuple):
        return chunk
    a = np.asarray(chunk)
    return a[:, 0], a[:, 1:]


def _partial(chunk, start, problem):
    x, y = _load(chunk)
    return partial_fit(x, y, start=start, **problem)


def _describe(chunks):
    """(rows, channels) of every chunk, checked before any task runs."""
    shapes = []
    for i, c in enumerate(chunks):
        if isinstance(c, (str, os.PathLike)):
            m, k = _npy_rows(c)
            shapes.append((m, k - 1))
        elif isinstance(c, tuple):
            x, y = np.asarray(c[0]), np.asarray(c[1])
            ch = 1 if y.ndim == 1 else y.shape[1]
            if y.shape[0] != x.shape[0]:
                raise RkwaveError(
                    f"chunk {i}: x has {x.shape[0]} samples, y {y.shape[0]}: give one value row per x"
                )
            shapes.append((x.shape[0], ch))
        else:
            raise RkwaveError(
                f"chunk {i} is a {type(c).__name__}: give .npy paths or (x, y) pairs"
            )
    for i, (m, _) in enumerate(shapes):
        if m == 0:
            raise RkwaveError(f"chunk {i} is empty: leave it out of the list")
    channels = {ch for _, ch in shapes}
    if len(channels) > 1:
        raise RkwaveError(
            f"the chunks have different numbers of channels {sorted(channels)}: give every "
            "chunk the same value columns"
        )
    return shapes


def fit_chunks(chunks, *, domain, p=3, levels=None, family=None, rho=2.0,
               coarse_samples=256.0, ridge=0.0, client=None, fan_in=2):
    """The ``rkwave.Fit`` of the samples of all ``chunks`` (in order, sorted by ``x``).

    ``chunks``: a list of ``.npy`` paths (each ``m_i x (1 + channels)``, read by the worker
    that fits it, so they must lie on storage every worker sees), a list of ``(x, y)`` pairs,
    or a dask array ``m x (1 + channels)`` (its row blocks are the chunks). ``domain=(a, b)``
    is required (the whole set's bounds are not known before the tasks run). The other
    parameters are ``rkwave.fit``'s (single-scale QR). ``client``: a
    ``dask.distributed.Client`` (default: the current one, else Dask's local scheduler);
    ``fan_in``: partials merged per reduction step.

    Raises ``RkwaveError`` before any task runs for a missing or malformed file, an empty
    chunk, or chunks with different channels; a chunk whose samples are out of order raises
    it from its task.
    """
    dask = _dask()
    if hasattr(chunks, "to_delayed") and hasattr(chunks, "chunks"):
        if chunks.ndim != 2 or chunks.shape[1] < 2:
            raise RkwaveError(
                f"the dask array has shape {chunks.shape}: give m x (1 + channels) samples"
            )
        blocks = chunks.rechunk({1: chunks.shape[1]}).to_delayed().ravel().tolist()
        rows = list(chunks.chunks[0])
        if any(r == 0 for r in rows):
            raise RkwaveError("the dask array has an empty row block: rechunk it")
        parts_in = blocks
    else:
        chunks = list(chunks)
        if not chunks:
            raise RkwaveError("no chunks: give at least one chunk of samples")
        rows = [m for m, _ in _describe(chunks)]
        parts_in = chunks
    total = int(sum(rows))
    problem = dict(samples=total, domain=tuple(domain), p=p, levels=levels, family=family,
                   rho=rho, coarse_samples=coarse_samples)
    starts = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(int).tolist()
    layer = [dask.delayed(_partial, pure=True)(c, s, problem)
             for c, s in zip(parts_in, starts)]
    fan_in = max(2, int(fan_in))
    while len(layer) > 1:
        layer = [_merged(dask, layer[i:i + fan_in], problem)
                 for i in range(0, len(layer), fan_in)]
    top = layer[0]
    if client is not None:
        partial = client.compute(top).result()
    else:
        partial = top.compute()
    return finish_partial(partial, ridge=ridge, **problem)


def _merge_all(problem, *parts):
    acc = parts[0]
    for later in parts[1:]:
        acc = merge_partials(acc, later, **problem)
    return acc


def _merged(dask, group, problem):
    if len(group) == 1:
        return group[0]
    return dask.delayed(_merge_all, pure=True)(problem, *group)
