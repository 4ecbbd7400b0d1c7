#!/usr/bin/env python3
"""The Dask paths (rkwave.dask) against the one-process paths on the same samples, as ratios
in one run.

    python python/benchmarks/dask_overhead.py [--rkwave target/release/rkwave] [--size 2048 ...]
        [--spp 1] [--tile 256] [--halo 12] [--m1 10000000] [--chunks 8] [--rounds 3]

Image: a ``size x size`` image from ``spp`` samples per pixel (uniform positions, seed 7, one
channel: a disc on a ramp times a sine product), p = 2, tiles of ``tile`` with ``halo``. The
samples are written as one ``.npy`` file per band of tile rows (``rkwave.dask``'s layout) and
as their concatenation (the command line's input; the same order, so the same image bit for
bit, checked). Per round, alternating: ``rkwave reconstruct --dim 2 --tile T --halo H
--workers 2`` (one process, two threads; wall clock of the subprocess, reading and writing
included) and ``rkwave.dask.reconstruct_image_tiles`` on a ``LocalCluster(n_workers=2,
processes=True, threads_per_worker=1)`` started before the rounds (wall clock of the call:
client-side checks, graph, tasks, assembly, the atomic write). The overhead is the median of
the per-round ratios dask / CLI minus one; the spread is their min and max. Several sizes
(``--size 512 4096``) run one after the other on the same cluster, each with its Dask seconds
per megapixel; after each size, every worker's peak resident memory so far (``ru_maxrss``:
a worker's peak over the sizes run until then, so give the sizes in increasing order).

1D: ``m1`` sorted samples of ``sin 6x + 0.3 |x - 0.4|`` with noise, ``rkwave.fit`` in this
process against ``rkwave.dask.fit_chunks`` on ``chunks`` files on the same cluster, at the
levels ``rkwave.fit`` chose (``--rho1``): the largest coefficient difference and the time
ratio.
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import rkwave
import rkwave.dask as rd

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def image_samples(size, spp, seed=7):
    rng = np.random.default_rng(seed)
    m = size * size * spp
    xy = rng.uniform(0, size, (m, 2))
    x, y = xy[:, 0] / size, xy[:, 1] / size
    disc = np.where((x - 0.35) ** 2 + (y - 0.5) ** 2 < 0.06, 1.0, 0.2 + 0.5 * x)
    v = disc * (0.6 + 0.4 * np.sin(40 * x) * np.cos(25 * y))
    return np.c_[xy, v]


def spread(values):
    return {
        "median": statistics.median(values),
        "min": min(values),
        "max": max(values),
        "all": values,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rkwave", default=os.path.join(ROOT, "target", "release", "rkwave"))
    ap.add_argument("--size", type=int, nargs="+", default=[2048],
                    help="image sizes, each its own case in this run (time per pixel compared)")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--tile", type=int, default=256)
    ap.add_argument("--halo", type=int, default=12)
    ap.add_argument("--m1", type=int, default=10_000_000)
    ap.add_argument("--chunks", type=int, default=8)
    ap.add_argument("--rho1", type=float, default=2.0, help="rkwave.fit's rho (1D levels)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--skip-image", action="store_true")
    ap.add_argument("--skip-1d", action="store_true")
    args = ap.parse_args()
    from distributed import Client, LocalCluster

    tmp = tempfile.mkdtemp(prefix="rkwave-dask-bench-")
    cluster = LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    client = Client(cluster)
    out = {"load_before": os.getloadavg()}

    for size in [] if args.skip_image else args.size:
        tile = args.tile
        a = image_samples(size, args.spp)
        band = np.minimum((a[:, 1] // tile).astype(int), size // tile - 1)
        order = np.argsort(band, kind="stable")
        a = a[order]
        band = band[order]
        whole = os.path.join(tmp, "all.npy")
        np.save(whole, a)
        paths = []
        for b in range(band.max() + 1):
            paths.append(os.path.join(tmp, f"band{b:03d}.npy"))
            np.save(paths[-1], a[band == b])
        del a, band
        cli_s, dask_s, ratio = [], [], []
        same = True
        for r in range(args.rounds):
            cli_out = os.path.join(tmp, f"cli{r}.npy")
            t = time.perf_counter()
            subprocess.run(
                [args.rkwave, "reconstruct", "--dim", "2", "--input", whole, "--output",
                 cli_out, "--resolution", f"{size}x{size}", "--tile", str(tile), "--halo",
                 str(args.halo), "--workers", "2"],
                check=True, capture_output=True,
            )
            cli_s.append(time.perf_counter() - t)
            dask_out = os.path.join(tmp, f"dask{r}.npy")
            t = time.perf_counter()
            rd.reconstruct_image_tiles(
                paths, (size, size), tile, args.halo, dask_out, client=client
            )
            dask_s.append(time.perf_counter() - t)
            ratio.append(dask_s[-1] / cli_s[-1])
            same &= bool(np.array_equal(np.load(cli_out), np.load(dask_out)))
            os.unlink(cli_out)
            os.unlink(dask_out)
        # each worker process's peak resident memory so far (Linux: ru_maxrss in KiB)
        peaks = client.run(
            lambda: __import__("resource").getrusage(
                __import__("resource").RUSAGE_SELF).ru_maxrss * 1024)
        out.setdefault("image", []).append({
            "size": size, "spp": args.spp, "tile": tile, "halo": args.halo,
            "files": len(paths), "tiles": (size // tile) ** 2,
            "cli_s": spread(cli_s), "dask_s": spread(dask_s),
            "overhead": spread([q - 1 for q in ratio]), "identical": same,
            "dask_s_per_megapixel": spread([d / (size * size / 1e6) for d in dask_s]),
            "worker_peak_bytes": sorted(peaks.values()),
        })

    if not args.skip_1d:
        m = args.m1
        rng = np.random.default_rng(11)
        x = (np.arange(m) + rng.uniform(0, 1, m)) / m
        y = np.sin(6 * x) + 0.3 * np.abs(x - 0.4) + 0.01 * rng.standard_normal(m)
        bounds = np.linspace(0, m, args.chunks + 1).astype(int)
        paths = []
        for i, (s, e) in enumerate(zip(bounds[:-1], bounds[1:])):
            paths.append(os.path.join(tmp, f"c{i:03d}.npy"))
            np.save(paths[-1], np.c_[x[s:e], y[s:e]])
        mem_s, dask_s, diff = [], [], []
        for _ in range(args.rounds):
            t = time.perf_counter()
            f = rkwave.fit(x, y, domain=(0, 1), p=3, rho=args.rho1)
            mem_s.append(time.perf_counter() - t)
            t = time.perf_counter()
            g = rd.fit_chunks(paths, (0, 1), 3, f.levels, client=client)
            dask_s.append(time.perf_counter() - t)
            diff.append(float(np.abs(f.coefficients - g.coefficients).max()))
        out["1d"] = {
            "samples": m, "chunks": args.chunks, "rho": args.rho1, "levels": f.levels,
            "functions": len(f.coefficients),
            "max_abs_coefficient": float(np.abs(f.coefficients).max()),
            "max_abs_difference": max(diff),
            "fit_s": spread(mem_s), "dask_s": spread(dask_s),
            "ratio": spread([d / s for d, s in zip(dask_s, mem_s)]),
        }

    out["load_after"] = os.getloadavg()
    client.close()
    cluster.close()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
