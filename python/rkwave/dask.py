"""rkwave on a Dask cluster: the 1D single-scale fit of chunked samples and the tiled image.

``fit_chunks(paths, domain, p, levels, client=None)``
    One task per chunk reads its own ``.npy`` file (``m_i x (1 + channels)``, sorted by x,
    consecutive chunks in order) and returns its partial fit (``rkwave.partial``: the banded
    QR triangle of its rows); the partials merge pairwise in a fixed tree, order kept
    (``PartialFits.merge``), and the client finishes the root (``PartialFits.finish``): the
    ``rkwave.Fit`` of ``rkwave.fit`` on all the samples, the coefficients within the QR's
    rounding (another merge tree rounds differently; the tree is fixed by the chunk count,
    so a rerun gives the same bits).

``reconstruct_image_tiles(sample_paths, resolution, tile, halo, output, client=None)``
    One task per band of tile rows (as the one-process tiled fit takes its samples: band
    ``ty`` is the tile row ``ty`` with its halo, the rows ``[ty T - H_a, (ty + 1) T + H_a]``)
    reads the samples of the band from the ``.npy`` files once (``x, y, c1..`` in pixel
    units, memory-mapped; files whose rows lie outside the band are skipped), gives each
    tile of the row the samples of its window in file order and fits it
    (``rkwave.fit_tile``); the client assembles the bands' interiors and writes the
    ``(H, W, C)`` image through a temporary file and a rename. The image is that of
    ``rkwave reconstruct --dim 2 --tile T --halo H`` on the concatenated files, bit for bit.

``TiledPlan(resolution, spp=, tile=, halo=None, client=None, rows_per_task=1, ...)``
    The adaptive plan on tiles (``rkwave.Plan(tile=)``) with each round's steps as Dask tasks,
    one per band of ``rows_per_task`` tile rows: ``positions()``, ``add(xy, values)``,
    ``image()`` as ``rkwave.Plan``. The client keeps every sample, the plan's state with each
    tile's record (index, parameters, last indicator, stop) and what it needs to replay a
    band; a round's ``add`` checks the samples and computes the tiles' shares (nothing changed
    yet), sends each band its tiles' records and shares and the samples of its windows that
    the band's worker does not hold yet, and commits the bands' new positions and records as
    one step, or none of them. On a ``distributed`` client each band's tiles' whole states
    (refinement history, PCG's start) and samples stay on a worker between rounds, as
    futures; a band whose worker was lost is sent whole again and its states replayed from
    the client's records. The positions and the image are those of
    ``rkwave.Plan(tile=, halo=)`` bit for bit.

Every task is a pure function of its inputs, so a lost worker costs a re-run of its tasks
(``retries``) and the same result. The inputs are checked on the client before any task is
submitted: missing or malformed files, the tile grid, samples outside the image or the
domain, non-finite values.

Dask is an optional dependency: ``pip install dask[distributed]``.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

try:
    import dask
    import distributed
except ImportError as _missing:  # pragma: no cover - exercised by the test without dask
    raise ImportError(
        "rkwave.dask needs Dask and its distributed scheduler, which are not installed: "
        "pip install dask[distributed]"
    ) from _missing

import rkwave
from rkwave import _rkwave

__all__ = ["fit_chunks", "reconstruct_image_tiles", "merge_tree", "TiledPlan"]

#: Rows read at once by the client's checks of a sample file.
CHECK_ROWS = 1 << 20


def _refuse(message, kind="InvalidInput"):
    err = rkwave.RkwaveError(message)
    err.kind = kind
    return err


def _client(client):
    """The client given, else the current default one, else None (dask's local scheduler)."""
    if client is not None:
        return client
    try:
        return distributed.get_client()
    except ValueError:
        return None


def _compute(graph, client, retries):
    if client is None:
        return dask.compute(graph, scheduler="threads")[0]
    return client.gather(client.compute(graph, retries=retries))


def _open(path):
    """The sample file at ``path`` memory-mapped, checked for shape and dtype."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise _refuse(
            f"{path}: no such sample file: give the path of an existing .npy file every worker "
            "can read (shared storage)",
            kind="Unreadable",
        )
    try:
        a = np.load(path, mmap_mode="r")
    except (ValueError, OSError) as e:
        raise _refuse(
            f"{path}: not a readable .npy file ({e}): save the samples with numpy.save",
            kind="Unreadable",
        ) from e
    if a.ndim != 2 or a.dtype not in (np.float64, np.float32):
        raise _refuse(
            f"{path}: the samples have shape {a.shape} and dtype {a.dtype}: give a 2-D float64 "
            "or float32 array, one sample per row"
        )
    return a


def _same_columns(counts, what):
    """The one column count of all the inputs, else refused."""
    if len(set(counts)) != 1:
        raise _refuse(
            f"the {what} have {sorted(set(counts))} columns: give every one the same columns "
            "(the positions, then one column per channel)"
        )
    return counts[0]


def _scan(path, a, each):
    """Calls ``each(first_row, block)`` on consecutive blocks of rows of ``a`` (float64)."""
    for s in range(0, a.shape[0], CHECK_ROWS):
        each(s, np.asarray(a[s : s + CHECK_ROWS], dtype=np.float64))


# ----------------------------------------------------------------------------------------
# 1D: fit_chunks


def merge_tree(parts, merge):
    """The pairwise reduction of ``parts`` in order: ``[a, b, c, d, e]`` becomes
    ``merge(merge(merge(a, b), merge(c, d)), e)``; each level merges neighbours left to right
    and carries an odd last part up unchanged. ``merge`` may build graph nodes (dask.delayed)
    or compute directly."""
    parts = list(parts)
    if not parts:
        raise ValueError("merge_tree of no parts")
    while len(parts) > 1:
        nxt = [merge(parts[i], parts[i + 1]) for i in range(0, len(parts) - 1, 2)]
        if len(parts) % 2:
            nxt.append(parts[-1])
        parts = nxt
    return parts[0]


def _chunk_partial(path, start, domain, p, levels, family, flat):
    """Task: the partial fit of the chunk file ``path`` (rows ``start..`` of the whole set)."""
    a = np.load(path, mmap_mode="r")
    a = np.asarray(a, dtype=np.float64)
    y = a[:, 1] if flat else a[:, 1:]
    return _rkwave.partial(a[:, 0], y, domain, p, levels, start, family=family)


def _block_partial(block, start, domain, p, levels, family, flat):
    """Task: the partial fit of one row block of a dask array."""
    a = np.asarray(block, dtype=np.float64)
    y = a[:, 1] if flat else a[:, 1:]
    return _rkwave.partial(a[:, 0], y, domain, p, levels, start, family=family)


def _merge(a, b):
    return a.merge(b)


def fit_chunks(
    paths_or_dask_array,
    domain,
    p=3,
    levels=None,
    client=None,
    *,
    family=None,
    ridge=0.0,
    rho=2.0,
    coarse_samples=256.0,
    retries=3,
):
    """The single-scale least-squares fit of samples held as chunks, one Dask task per chunk.

    ``paths_or_dask_array`` is a list of ``.npy`` files (each ``m_i x (1 + channels)``: x then
    the values; rows sorted by x; consecutive files hold consecutive ranges of x) or a dask
    array ``m x (1 + channels)`` chunked by rows. ``domain=(a, b)`` holds every x. ``levels``
    is ``(n, N)``, or None for the automatic levels of the total sample count
    (``rkwave.auto_levels(m, p, rho=rho, coarse_samples=coarse_samples)``, without the level
    drops ``rkwave.fit`` makes on a layout it inspects). With a single value column the fit
    evaluates to ``(m,)``, else ``(m, channels)``.

    The partials merge in the fixed tree of :func:`merge_tree` and ``client`` (default: the
    current Dask client, else dask's local threaded scheduler) finishes the root: returns the
    ``rkwave.Fit``. Failed tasks are retried up to
    ``retries`` times.
    """
    client = _client(client)
    chunks = _chunks_of(paths_or_dask_array)
    m = sum(c[2] for c in chunks)
    width = _same_columns([c[3] for c in chunks], "chunks")
    if width < 2:
        raise _refuse(
            f"the chunks have {width} column: give x and at least one value column"
        )
    if m == 0:
        raise _refuse("the chunks hold no samples: give at least one sample")
    flat = width == 2
    if levels is None:
        levels = rkwave.auto_levels(m, p, rho=rho, coarse_samples=coarse_samples)
    levels = tuple(int(v) for v in levels)
    domain = (float(domain[0]), float(domain[1]))
    # The basis is checked here, on the client, before any task: an empty partial builds it.
    _rkwave.partial(
        np.empty(0), np.empty((0, width - 1)), domain, p, levels, family=family
    )
    parts = []
    for source, start, rows, _ in chunks:
        if isinstance(source, str):
            task = dask.delayed(_chunk_partial, pure=True)
        else:
            task = dask.delayed(_block_partial, pure=True)
        parts.append(task(source, start, domain, p, levels, family, flat))
    root = merge_tree(parts, dask.delayed(_merge, pure=True))
    partial = _compute(root, client, retries)
    return partial.finish(ridge)


def _chunks_of(source):
    """``(source, start row, rows, columns)`` per chunk: a path checked on the client, or a
    delayed row block of a dask array."""
    if hasattr(source, "to_delayed") and hasattr(source, "chunks"):
        if source.ndim != 2:
            raise _refuse(
                f"the dask array has shape {source.shape}: give m x (1 + channels), x first"
            )
        if len(source.chunks[1]) != 1:
            source = source.rechunk({1: source.shape[1]})
        blocks = source.to_delayed()[:, 0]
        out, start = [], 0
        for block, rows in zip(blocks, source.chunks[0]):
            out.append((block, start, rows, source.shape[1]))
            start += rows
        return out
    if isinstance(source, (str, os.PathLike)):
        raise _refuse(
            "fit_chunks takes a list of .npy files (or a dask array), got one path: give "
            "[path]"
        )
    out, start = [], 0
    for path in source:
        path = os.fspath(path)
        a = _open(path)
        out.append((path, start, a.shape[0], a.shape[1]))
        start += a.shape[0]
    if not out:
        raise _refuse("no chunks given: give a list of .npy files or a dask array")
    return out


# ----------------------------------------------------------------------------------------
# 2D: reconstruct_image_tiles


def _window_rows(paths, bands, window):
    """The samples of the closed window ``(x0, x1, y0, y1)`` from every file whose rows'
    y-range ``bands[i]`` meets it, in file order (the order the one-process tiled fit gives
    each tile)."""
    x0, x1, y0, y1 = window
    parts = []
    for path, (lo, hi) in zip(paths, bands):
        if hi < y0 or lo > y1:
            continue
        a = np.load(path, mmap_mode="r")
        for s in range(0, a.shape[0], CHECK_ROWS):
            block = a[s : s + CHECK_ROWS]
            y = block[:, 1]
            # Rows in the window's band first (few in a neighbouring band's file), then
            # their x: the same rows, in the same order, as the closed-rectangle test.
            rows = np.flatnonzero((y >= y0) & (y <= y1))
            x = block[rows, 0]
            rows = rows[(x >= x0) & (x <= x1)]
            if len(rows):
                parts.append(np.asarray(block[rows], dtype=np.float64))
    if not parts:
        return None
    return np.concatenate(parts)


#: glibc's ``mallopt`` parameters (malloc.h): ``M_TRIM_THRESHOLD``, ``M_MMAP_THRESHOLD``.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3

#: Whether this process's heap keeps freed memory (:func:`_keep_heap`): None until tried.
_HEAP_KEPT = None


def _keep_heap():
    """Makes glibc's allocator in this (worker) process keep freed memory, as the command line
    does (``mallopt`` in src/main.rs): blocks up to 32 MiB come from the heap, not a fresh
    ``mmap``, and the heap is never trimmed. Each tile's fit allocates and frees its normal
    matrix and factor (megabytes); with glibc's defaults every one of them is a new mapping
    whose pages fault in again, which made the tiles' fits 15 to 30 % slower in a Dask worker
    than in the command line (docs/measurements/scale-out.md). Once per process; returns
    whether it took (False off glibc: nothing is changed). The worker then keeps the memory
    of its largest tile fit until it exits."""
    global _HEAP_KEPT
    if _HEAP_KEPT is None:
        _HEAP_KEPT = False
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6")
            # mallopt returns 1 on success; both must take.
            _HEAP_KEPT = bool(
                libc.mallopt(_M_MMAP_THRESHOLD, 32 << 20)
                and libc.mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)
            )
        except (OSError, AttributeError):
            _HEAP_KEPT = False
    return _HEAP_KEPT


def _band_task(
    paths, bands, columns, geometry, band, total, p, rho, ridge, before_tile, keep_heap
):
    """Task: the interior pixels of band ``band`` (tile row ``ty``), ``(band, strip (h, W, C),
    reports)``. The band's window rows (``[ty T - H_a, (ty + 1) T + H_a]``, clipped) are read
    once from the files they meet; each tile of the band takes the rows of its window
    (``x0 <= x <= x1``) from them, in file order, and is fitted (``rkwave.fit_tile``) in turn."""
    heap_kept = _keep_heap() if keep_heap else False
    nx, _ = geometry.grid
    w, _ = geometry.resolution
    first = band * nx
    _, _, wy0, wy1 = geometry.window(first)
    _, _, iy0, iy1 = geometry.interior(first)
    rows = _window_rows(paths, bands, (0, w, wy0, wy1))
    if rows is None:
        rows = np.empty((0, columns))
    x = rows[:, 0]
    strip = np.empty((iy1 - iy0, w, columns - 2))
    reports = []
    for tile in range(first, first + nx):
        if before_tile is not None:
            before_tile(tile)
        x0, x1, _, _ = geometry.window(tile)
        mine = rows[(x >= x0) & (x <= x1)]
        pixels, report = _rkwave.fit_tile(
            mine[:, :2], mine[:, 2:], geometry, tile, total, p, rho=rho, ridge=ridge
        )
        ix0, ix1, _, _ = geometry.interior(tile)
        strip[:, ix0:ix1, :] = pixels
        reports.append(report)
    return band, strip, reports, heap_kept


def _check_image_file(path, resolution):
    """Client check of one image sample file: shape, finite values, positions in the image.
    Returns (rows, columns, (min y, max y))."""
    a = _open(path)
    w, h = resolution
    if not 3 <= a.shape[1] <= 6:
        raise _refuse(
            f"{path}: the samples have {a.shape[1]} columns: an image-plane sample file has "
            "x, y and 1 to 4 channels (3 to 6 columns)"
        )
    lo, hi = np.inf, -np.inf

    def check(first, block):
        nonlocal lo, hi
        finite = np.isfinite(block).all(axis=1)
        x, y = block[:, 0], block[:, 1]
        inside = finite & (x >= 0) & (x <= w) & (y >= 0) & (y <= h)
        if not inside.all():
            i = int(np.argmin(inside))
            if not np.isfinite(block[i]).all():
                raise _refuse(
                    f"{path}: row {first + i} (0-based) has a non-finite value "
                    f"{block[i].tolist()}: remove or fix that sample"
                )
            raise _refuse(
                f"{path}: sample {first + i} (0-based row) at ({x[i]}, {y[i]}) is outside "
                f"the {w} x {h} image: give positions in pixel units within [0, W] x [0, H] "
                "(or the right resolution)"
            )
        if len(y):
            lo, hi = min(lo, float(y.min())), max(hi, float(y.max()))

    _scan(path, a, check)
    return a.shape[0], a.shape[1], (lo, hi)


def reconstruct_image_tiles(
    sample_paths,
    resolution,
    tile,
    halo=12,
    output=None,
    client=None,
    *,
    p=2,
    rho=None,
    ridge=None,
    force=False,
    retries=3,
    before_tile=None,
    keep_heap=True,
):
    """The tiled image-plane fit with one Dask task per band of tile rows; returns
    ``(image, report)``.

    ``sample_paths`` lists ``.npy`` files of samples ``x, y, c1..`` (3 to 6 columns, pixel
    units, float64 or float32) on storage every worker reads: one file per chunk, or per
    band of tile rows (a band's task then opens only the files its rows meet: its own and
    its neighbours'). ``resolution=(W, H)``,
    ``tile`` and ``halo`` (at most ``tile``) set the grid (``rkwave.TileGeometry``); ``p``,
    ``rho`` and ``ridge`` the fit (as ``rkwave reconstruct --dim 2``). The image ``(H, W, C)``
    is returned and, with ``output`` (a ``.npy`` path), written through a temporary file in
    the same folder and a rename: a failed run leaves no partial output. An existing output
    is refused unless ``force=True``.

    Checked on the client before any task: the files (present, 2-D float arrays of 3 to 6
    columns), the grid, every position inside the image and every value finite. ``client``:
    as :func:`fit_chunks`. ``before_tile(tile)``, if given, runs at the start of each tile's
    fit in its band's task (a hook for progress or fault injection); it must be picklable. A
    failed band's task is rerun whole (``retries``), with the same result.

    ``keep_heap`` (default True): each worker process's glibc allocator is set to keep freed
    memory, as the command line's is (blocks up to 32 MiB from the heap, never trimmed): the
    tiles' fits are then as fast as the command line's; the worker keeps the memory of its
    largest tile fit until it exits. The report's ``notes`` say whether it took on every band
    (``heap_kept`` per band); ``keep_heap=False`` leaves the workers' allocators alone.
    """
    client = _client(client)
    geometry = rkwave.TileGeometry(tuple(resolution), tile, halo)
    if output is not None:
        output = os.fspath(output)
        if not output.endswith(".npy"):
            raise _refuse(
                f"output {output!r}: the Dask path writes .npy images: give a path ending in "
                ".npy (convert with rkwave afterwards)"
            )
        folder = os.path.dirname(os.path.abspath(output))
        if not os.path.isdir(folder):
            raise _refuse(
                f"output {output!r}: the folder {folder} does not exist: create it first",
                kind="OutputRefused",
            )
        if os.path.exists(output) and not force:
            raise _refuse(
                f"output {output!r} exists: give force=True to replace it, or another path",
                kind="OutputRefused",
            )
    if isinstance(sample_paths, (str, os.PathLike)):
        sample_paths = [sample_paths]
    paths = [os.fspath(q) for q in sample_paths]
    if not paths:
        raise _refuse("no sample files given: give a list of .npy files")
    checked = [_check_image_file(q, geometry.resolution) for q in paths]
    total = sum(c[0] for c in checked)
    columns = _same_columns([c[1] for c in checked], "sample files")
    if total == 0:
        raise _refuse("the input holds no samples: give at least one sample inside the image")
    bands = [c[2] for c in checked]
    # The fit's parameters are checked once here (an empty window of tile 0).
    _rkwave.fit_tile(
        np.empty((0, 2)), np.empty((0, columns - 2)), geometry, 0, total, p, rho=rho,
        ridge=ridge,
    )
    task = dask.delayed(_band_task, pure=True)
    nx, ny = geometry.grid
    tasks = [
        task(paths, bands, columns, geometry, band, total, p, rho, ridge, before_tile, keep_heap)
        for band in range(ny)
    ]
    results = _compute(tasks, client, retries)
    w, h = geometry.resolution
    image = np.zeros((h, w, columns - 2))
    reports = []
    heap_kept = []
    for band, strip, band_reports, kept in results:
        _, _, y0, y1 = geometry.interior(band * nx)
        image[y0:y1, :, :] = strip
        reports.extend(band_reports)
        heap_kept.append(kept)
    if output is not None:
        _write_atomic(output, image)
    report = {
        "resolution": [w, h],
        "tile": tile,
        "halo": halo,
        "grid": list(geometry.grid),
        "samples": total,
        "channels": columns - 2,
        "files": len(paths),
        "tasks": ny,
        "tiles": reports,
        "heap_kept": heap_kept,
        "notes": [
            f"tile {r['tile']} (pixels {r['interior']}): {r['unsampled']} functions without "
            f"samples pinned to 0, {r['replaced_pivots']} Cholesky pivots replaced"
            for r in reports
            if r["unsampled"] > 0 or r["replaced_pivots"] > 0
        ],
    }
    if keep_heap:
        kept = sum(heap_kept)
        report["notes"].append(
            f"worker heap: freed memory kept by the allocator (as the command line does) in the "
            f"tasks of {kept} of {ny} bands"
            + ("" if kept == ny else " (the others' workers are not on glibc: left alone)")
        )
    else:
        report["notes"].append(
            "worker heap: left alone (keep_heap=False): each tile's factor is a fresh mapping, "
            "which made the fits 15 to 30 % slower than the command line's"
        )
    return image, report


def _write_atomic(output, image):
    """``numpy.save`` to a temporary file beside ``output``, then a rename over it."""
    folder = os.path.dirname(os.path.abspath(output))
    fd, tmp = tempfile.mkstemp(prefix=".rkwave-", suffix=".npy", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            np.save(f, image)
        os.replace(tmp, output)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


# ----------------------------------------------------------------------------------------
# 2D: the tiled plan's rounds (in rkwave/_dask_plan.py, which uses the helpers above)


def __getattr__(name):
    """``TiledPlan`` from ``rkwave._dask_plan``, imported on first use: that module imports
    this one (a worker unpickling one of its tasks imports it first)."""
    if name == "TiledPlan":
        from rkwave._dask_plan import TiledPlan

        return TiledPlan
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
