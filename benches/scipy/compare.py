#!/usr/bin/env python3
"""Compare `rkwave reconstruct` with scipy's FITPACK least-squares cubic spline.

Both fit the same scattered samples (m uniform random positions on [0, 1]) with the same
number of coefficients P and are evaluated on the same G-point grid; the table gives times
and the RMS error against the true signal on that grid. Needs numpy and scipy (optional,
not used by CI); see README.md beside this file.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.interpolate import LSQUnivariateSpline


def signal(name, x):
    """The test signal: "smooth", "sinexp" (sin(20x) + exp(x), issue 11's accuracy signal)
    or "jumps" (steps of +1 at 0.29, 0.53, 0.81)."""
    if name == "smooth":
        return np.sin(2 * np.pi * x) + 0.5 * np.cos(5 * np.pi * x)
    if name == "sinexp":
        return np.sin(20 * x) + np.exp(x)
    steps = sum((x >= c).astype(np.float64) for c in (0.29, 0.53, 0.81))
    return 0.5 * np.sin(2 * np.pi * x) + steps


def make_samples(m, seed, name, path):
    """Writes m samples (columns x, value; float64, shape (m, 2)) to `path`; returns them."""
    x = np.random.default_rng(seed).uniform(0.0, 1.0, m)
    data = np.column_stack([x, signal(name, x)])
    np.save(path, data)
    return data


def rms(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def rkwave_problem(binary):
    """None when `binary reconstruct --help` works, else a message saying why not."""
    if not os.path.isfile(binary):
        return (f"rkwave binary not found at {binary} "
                "(build it with `cargo build --release` or pass --rkwave)")
    proc = subprocess.run([binary, "reconstruct", "--help"], capture_output=True, text=True)
    if proc.returncode != 0:
        return (f"`{binary} reconstruct --help` failed (exit {proc.returncode}); "
                "the binary has no working `reconstruct` subcommand:\n" + proc.stderr.strip())
    return None


def run_rkwave(binary, npy, grid, out_npy, name, p=3, factorization="qr"):
    """Runs `rkwave reconstruct` (grid written as .npy); returns (its JSON, wall seconds,
    grid RMS error).

    Raises RuntimeError with a readable message when it fails or its output is unexpected."""
    cmd = [binary, "reconstruct", "--input", npy, "--domain", "0,1", "--p", str(p),
           "--levels", "auto", "--grid", str(grid), "--output", out_npy, "--force", "--json",
           "--factorization", factorization]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"`{' '.join(cmd)}` exited with {proc.returncode}:\n"
                           + (proc.stderr.strip() or proc.stdout.strip()))
    try:
        report = json.loads(proc.stdout)
        int(report["functions"])  # the keys used below
        [float(report["time_s"][k]) for k in ("kernel", "solve", "evaluate", "total")]
    except (ValueError, KeyError, TypeError) as err:
        raise RuntimeError(f"unexpected JSON from rkwave ({err!r}):\n{proc.stdout[:500]}")
    out = np.load(out_npy)
    if out.shape != (grid, 2):
        raise RuntimeError(f"{out_npy}: expected {grid} rows of x,value, got {out.shape}")
    return report, wall, rms(out[:, 1], signal(name, out[:, 0]))


def run_scipy(data, n_coef, grid, name, knots="uniform"):
    """Cubic LSQ spline with n_coef coefficients: n_coef - 4 interior knots, equally spaced
    (knots="uniform") or at sample quantiles (knots="quantile").

    The samples are sorted before the clock starts (FITPACK needs increasing x; rkwave does
    not). Timed: fit, then evaluation on np.linspace(0, 1, grid).
    Returns (fit seconds, evaluation seconds, RMS error)."""
    order = np.argsort(data[:, 0], kind="stable")
    xs, ys = data[order, 0].copy(), data[order, 1].copy()
    if knots == "quantile":
        inner = np.quantile(xs, np.linspace(0.0, 1.0, n_coef - 2)[1:-1])
    else:
        inner = np.linspace(0.0, 1.0, n_coef - 2)[1:-1]
    xg = np.linspace(0.0, 1.0, grid)
    t0 = time.perf_counter()
    spline = LSQUnivariateSpline(xs, ys, inner, k=3, bbox=[0.0, 1.0])
    t1 = time.perf_counter()
    yg = spline(xg)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, rms(yg, signal(name, xg))


def compare(args, m, seed, p, fact, tmp, use_rkwave, scipy_cache):
    """One row: same data for both; P from rkwave, or the largest power of two <= m/2.
    FITPACK runs once per (m, seed, P) and is reused by the rows that share them."""
    npy, out = os.path.join(tmp, f"s{m}_{seed}.npy"), os.path.join(tmp, f"r{m}_{seed}.npy")
    data = make_samples(m, seed, args.signal, npy)
    row = {"m": m, "seed": seed, "p": p, "factorization": fact, "signal": args.signal,
           "grid": args.grid}
    if use_rkwave:
        try:
            report, wall, err = run_rkwave(args.rkwave, npy, args.grid, out, args.signal, p, fact)
            ts = report["time_s"]  # total may include reading input and writing the CSV
            row.update(P=int(report["functions"]), rkwave_total_s=ts["total"],
                       rkwave_fit_eval_s=ts["kernel"] + ts["solve"] + ts["evaluate"],
                       rkwave_wall_s=wall, rkwave_rms=err, rkwave=report)
        except RuntimeError as exc:
            print(f"rkwave failed for m={m}, seed={seed}: {exc}\n"
                  "-> scipy only for this row", file=sys.stderr)
            row["rkwave_error"] = str(exc)
    row.setdefault("P", 1 << int(math.log2(m // 2)))
    try:
        key = (m, seed, row["P"])
        if key not in scipy_cache:
            scipy_cache[key] = run_scipy(data, row["P"], args.grid, args.signal, args.knots)
        fit, ev, row["scipy_rms"] = scipy_cache[key]
        row.update(scipy_s=fit + ev, scipy_fit_s=fit, scipy_eval_s=ev)
    except ValueError as exc:  # FITPACK's fpchec: with these knots, only Schoenberg-Whitney
        row["scipy_error"] = str(exc).splitlines()[0]  # can fail (too few samples somewhere)
        print(f"scipy failed for m={m}, seed={seed}, P={row['P']}: FITPACK rejected the knots "
              "(Schoenberg-Whitney: some B-spline has no sample of its own)", file=sys.stderr)
    if "rkwave_total_s" in row and "scipy_s" in row:
        row["ratio_fit_eval"] = row["scipy_s"] / row["rkwave_fit_eval_s"]
        row["ratio_total"] = row["scipy_s"] / row["rkwave_total_s"]
        row["ratio_wall"] = row["scipy_s"] / row["rkwave_wall_s"]
    return row


def print_table(rows):
    def f(row, key, fmt):
        return format(row[key], fmt) if key in row else "n/a"
    cols = (("m", "m", "d"), ("p", "p", "d"), ("solve", "factorization", "s"), ("P", "P", "d"), ("rk fit+ev", "rkwave_fit_eval_s", ".4f"),
            ("rk total", "rkwave_total_s", ".4f"), ("rk wall", "rkwave_wall_s", ".4f"),
            ("scipy", "scipy_s", ".4f"), ("sp/rk f+e", "ratio_fit_eval", ".2f"),
            ("sp/rk tot", "ratio_total", ".2f"), ("sp/rk wal", "ratio_wall", ".2f"),
            ("rk RMS", "rkwave_rms", ".2e"), ("scipy RMS", "scipy_rms", ".2e"))
    print("times in seconds; sp/rk > 1: rkwave faster")
    print(" ".join(f"{c[0]:>9}" for c in cols))
    for r in rows:
        print(" ".join(f"{f(r, key, fmt):>9}" for _, key, fmt in cols))


def main():
    ints = lambda s: [int(float(v)) for v in s.split(",") if v]  # noqa: E731 (accepts 1e5)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--rkwave", default=os.path.normpath(
                    os.path.join(here, "..", "..", "target", "release", "rkwave")),
                    help="rkwave binary (default: target/release/rkwave of this checkout)")
    ap.add_argument("--sizes", type=ints, default=[10**4, 10**5, 10**6],
                    help="comma-separated sample counts m (default 1e4,1e5,1e6)")
    ap.add_argument("--seeds", type=ints, default=[0], help="comma-separated seeds (default 0)")
    ap.add_argument("--signal", choices=["smooth", "sinexp", "jumps"], default="smooth")
    ap.add_argument("--p", type=ints, default=[3],
                    help="comma-separated vanishing moments of rkwave (3: order 3; 4 matches "
                         "the cubic spline's order 4)")
    ap.add_argument("--factorization", default="qr",
                    help="comma-separated rkwave single-scale factorizations: qr, normal")
    ap.add_argument("--knots", choices=["uniform", "quantile"], default="uniform",
                    help="FITPACK interior knots: equally spaced or at sample quantiles")
    ap.add_argument("--grid", type=int, default=1_000_000,
                    help="evaluation grid points G (default 1000000)")
    ap.add_argument("--scipy-only", action="store_true",
                    help="skip rkwave; P = largest power of two <= m/2")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args()
    if min(args.sizes) < 16 or args.grid < 2:
        ap.error("sizes must be >= 16 and --grid >= 2")
    problem = None if args.scipy_only else rkwave_problem(args.rkwave)
    if problem:
        print(f"{problem}\n-> scipy only (P = largest power of two <= m/2)", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="rkwave-scipy-") as tmp:
        cache = {}
        facts = [f for f in args.factorization.split(",") if f]
        rows = [compare(args, m, seed, p, fact, tmp, not (args.scipy_only or problem), cache)
                for m in args.sizes for seed in args.seeds for p in args.p for fact in facts]
    if args.json:
        print(json.dumps(rows, indent=2))
    else:
        print_table(rows)
    return 1 if problem or any("rkwave_error" in r for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
