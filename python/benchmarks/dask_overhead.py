"""The task graph's overhead of rkwave.dask.fit_chunks against rkwave.fit in one process.

    python python/benchmarks/dask_overhead.py [samples] [chunks]

Fits `samples` sorted 1D samples (default 4e6) once in memory (rkwave.fit) and once as
`chunks` .npy files (default 8) on a LocalCluster of two single-threaded worker processes,
and prints both wall-clock times (best of three) and the ratio. The in-memory fit uses the
engine's threads (two on this machine); the cluster uses one thread per worker, so the ratio
measures the graph, the file reads and the moves of the partials together.
"""

import sys
import tempfile
import time

import numpy as np

import rkwave
import rkwave.dask as rdask


def best(f, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return min(times)


def main():
    m = int(float(sys.argv[1])) if len(sys.argv) > 1 else 4_000_000
    k = int(sys.argv[2]) if len(sys.argv) > 2 else 8
    from distributed import Client, LocalCluster

    rng = np.random.default_rng(1)
    x = np.sort(rng.uniform(0, 1, m))
    y = np.sin(6 * x) + 1e-3 * rng.standard_normal(m)
    with tempfile.TemporaryDirectory() as d, LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster, Client(cluster) as client:
        paths = []
        for i, rows in enumerate(np.array_split(np.arange(m), k)):
            paths.append(f"{d}/c{i}.npy")
            np.save(paths[-1], np.column_stack([x[rows], y[rows]]))
        one = best(lambda: rkwave.fit(x, y, domain=(0, 1)))
        graph = best(lambda: rdask.fit_chunks(paths, domain=(0, 1), client=client))
    print(f"samples {m}, chunks {k}: rkwave.fit {one:.3f} s, fit_chunks {graph:.3f} s, "
          f"ratio {graph / one:.2f}")


if __name__ == "__main__":
    main()
