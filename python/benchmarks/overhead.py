#!/usr/bin/env python3
"""The Python module's overhead against the library on the same work, as ratios in one run.

    python python/benchmarks/overhead.py [--rkwave target/release/rkwave] [--repeats 5]

Two workloads (issue 25's targets): a 1D fit of 1e6 scattered samples (`rkwave.fit`, the
default single-scale method) and a 512 x 512 image from 4 samples per pixel, 3 channels
(`rkwave.reconstruct_image`, the wavelet method, p = 2). The reference is the library's own
time for the same call, reported by the command line on the same input file (`rkwave
reconstruct --json`: `time_s.kernel + time_s.solve` in 1D; `time_s.fit + time_s.pixels` on
the image plane), so reading files and writing outputs are not counted against either side
(the CLI's 1D figure leaves out the library's checks before the solve, so the ratio is
conservative). The Python side is the wall time of the whole call (conversion, checks,
report, warnings); its own report also gives the time of the whole library call in the same
process (`time_s.total`), against which the in-process overhead is shown. Runs alternate (CLI, Python, CLI, ...); medians are shown.
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

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def cli(binary, *args):
    out = subprocess.run([binary, *map(str, args), "--json"], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rkwave", default=os.path.join(ROOT, "target", "release", "rkwave"))
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    tmp = tempfile.mkdtemp()
    rng = np.random.default_rng(2026)

    x = rng.uniform(0.0, 1.0, 1_000_000)
    y = np.sin(20 * x) + (x > 0.37)
    np.save(os.path.join(tmp, "s1.npy"), np.c_[x, y])
    res = {"1d_cli_library": [], "1d_py_wall": [], "1d_py_library": []}
    for r in range(args.repeats):
        rep = cli(args.rkwave, "reconstruct", "--input", os.path.join(tmp, "s1.npy"),
                  "--output", os.path.join(tmp, f"g{r}.npy"), "--grid", 2)
        res["1d_cli_library"].append(rep["time_s"]["kernel"] + rep["time_s"]["solve"])
        t = time.perf_counter()
        f = rkwave.fit(x, y)
        res["1d_py_wall"].append(time.perf_counter() - t)
        res["1d_py_library"].append(f.report["time_s"]["total"])

    w = h = 512
    xy = rng.uniform(0.0, 1.0, (4 * w * h, 2)) * [w, h]
    values = np.c_[np.sin(xy[:, 0] / 9.0), (xy[:, 1] > 200).astype(float), xy[:, 0] / w]
    np.save(os.path.join(tmp, "s2.npy"), np.c_[xy, values])
    res.update({"2d_cli_library": [], "2d_py_wall": [], "2d_py_library": []})
    for r in range(args.repeats):
        rep = cli(args.rkwave, "reconstruct", "--dim", 2, "--input", os.path.join(tmp, "s2.npy"),
                  "--resolution", f"{w}x{h}", "--output", os.path.join(tmp, f"i{r}.npy"))
        res["2d_cli_library"].append(rep["time_s"]["fit"] + rep["time_s"]["pixels"])
        t = time.perf_counter()
        _, report = rkwave.reconstruct_image(xy, values, (w, h))
        res["2d_py_wall"].append(time.perf_counter() - t)
        res["2d_py_library"].append(report["time_s"]["total"])

    med = {k: statistics.median(v) for k, v in res.items()}
    for dim, label in [("1d", "1e6-sample 1D fit"), ("2d", "512x512, 4 spp, 3 channels")]:
        cli_s, wall, lib = med[f"{dim}_cli_library"], med[f"{dim}_py_wall"], med[f"{dim}_py_library"]
        print(f"{label}: CLI library {cli_s:.3f} s, Python call {wall:.3f} s "
              f"(inside the library {lib:.3f} s): Python / CLI = {wall / cli_s:.3f}, "
              f"overhead in process {100 * (wall - lib) / lib:.1f}%")
    print(json.dumps({"median_s": med, "repeats": args.repeats}))


if __name__ == "__main__":
    main()
