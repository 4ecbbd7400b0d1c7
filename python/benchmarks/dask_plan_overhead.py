#!/usr/bin/env python3
"""The tiled plan's rounds on Dask (``rkwave.dask.TiledPlan``) against the local tiled plan
(``rkwave.Plan(tile=)``): runs interleaved in one invocation, ratios per pair.

    python python/benchmarks/dask_plan_overhead.py [--size 256 512] [--pairs 3] [--spp 8]
        [--tile 128] [--halo 0] [--rows-per-task 1]

Renderer: an analytic RGB image evaluated at the positions (a disc on a ramp times a sine
product, plus a deterministic hash "noise" of amplitude 0.05 so the plan does not stop at its
tolerance early); its time is not counted. Per size, ``--pairs`` pairs run as L D L D ...:
the local plan (one process, the plan's workers = the machine's threads) then the Dask plan
on a ``LocalCluster(n_workers=2, processes=True, threads_per_worker=1)`` started before the
first pair (one task per band of ``rows_per_task`` tile rows, one tile at a time in a task),
each run from its start to its stop and its final image. A pair's two runs are next to each
other in time, so a change of the machine's load between pairs moves both; the figure is
the median over the pairs of the ratio Dask / local, minus one (with the min and the max).
Time: wall clock of the plan's calls (construction, every ``add``, ``image``), the
renderer's calls excluded. Each run prints the 1-minute load average at its start and end
(``os.getloadavg``, the machine's 2 cores shared with other work), what travelled (the band
samples sent, the tasks' and outcomes' bytes: the tiles' whole states stay on the workers),
and whether every round's positions and the final image are identical bit for bit to the
local run's. The last line is a JSON summary.
"""

import argparse
import json
import os
import statistics
import time

import numpy as np

import rkwave
import rkwave.dask as rd


def render(xy, size):
    """The analytic scene at the positions (three channels)."""
    x, y = xy[:, 0] / size, xy[:, 1] / size
    disc = np.where((x - 0.35) ** 2 + (y - 0.5) ** 2 < 0.06, 1.0, 0.2 + 0.5 * x)
    v = disc * (0.6 + 0.4 * np.sin(40 * x) * np.cos(25 * y))
    noise = np.modf(np.sin(xy[:, 0] * 12.9898 + xy[:, 1] * 78.233) * 43758.5453)[0]
    return np.stack([v + 0.05 * noise, 0.5 * v, 1.0 - 0.5 * v], axis=1)


def run(make, size):
    """The plan made by ``make()`` to its stop and its image: (seconds in the plan's calls,
    rounds' positions, image, plan)."""
    t = time.perf_counter()
    plan = make()
    spent, rounds = time.perf_counter() - t, []
    while True:
        t = time.perf_counter()
        done = plan.done
        xy = None if done else plan.positions()
        spent += time.perf_counter() - t
        if done:
            break
        rounds.append(xy)
        values = render(xy, size)
        t = time.perf_counter()
        plan.add(xy, values)
        spent += time.perf_counter() - t
    t = time.perf_counter()
    image = plan.image()
    spent += time.perf_counter() - t
    return spent, rounds, image, plan


def load():
    return os.getloadavg()[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--tile", type=int, default=128)
    ap.add_argument("--halo", type=int, default=0)
    ap.add_argument("--rows-per-task", type=int, default=1)
    args = ap.parse_args()

    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    client = Client(cluster)
    print(
        f"dask_plan_overhead: sizes {args.size}, {args.pairs} pairs L D, {args.spp} spp, "
        f"tiles of {args.tile}, halo {args.halo}, {args.rows_per_task} tile row(s) a task, "
        f"{os.cpu_count()} CPUs, Dask: 2 worker processes x 1 thread; rkwave "
        f"{rkwave.__version__}",
        flush=True,
    )
    out = {"spp": args.spp, "tile": args.tile, "halo": args.halo, "sizes": []}
    all_same = True
    try:
        for size in args.size:
            pairs = []
            for k in range(args.pairs):
                l0 = load()
                a, ra, ia, _ = run(
                    lambda: rkwave.Plan(
                        resolution=(size, size), spp=args.spp, tile=args.tile,
                        halo=args.halo,
                    ),
                    size,
                )
                l1 = load()
                b, rb, ib, dplan = run(
                    lambda: rd.TiledPlan(
                        (size, size), spp=args.spp, tile=args.tile, halo=args.halo,
                        client=client, rows_per_task=args.rows_per_task,
                    ),
                    size,
                )
                l2 = load()
                same = (
                    len(ra) == len(rb)
                    and all(np.array_equal(p, q) for p, q in zip(ra, rb))
                    and np.array_equal(ia, ib)
                )
                all_same &= same
                r = dplan.report
                pair = {
                    "local_s": a, "dask_s": b, "ratio": b / a,
                    "load": [l0, l1, l2], "identical": same,
                    "plan_rounds": len(ra), "samples": r["handed_out"],
                    "tasks": r["tasks_run"], "samples_sent_mb": r["samples_sent_mb"],
                    "tasks_mb": r["tasks_mb"], "outcomes_mb": r["outcomes_mb"],
                }
                pairs.append(pair)
                print(
                    f"{size}^2 pair {k}: local {a:.1f} s (load {l0:.1f} -> {l1:.1f}), dask "
                    f"{b:.1f} s (load {l1:.1f} -> {l2:.1f}), ratio {b / a:.3f}; "
                    f"{len(ra)} rounds, {r['handed_out']} samples, {r['tasks_run']} tasks; "
                    f"sent: samples {r['samples_sent_mb']:.1f} MB, tasks "
                    f"{r['tasks_mb']:.2f} MB, outcomes {r['outcomes_mb']:.2f} MB; "
                    f"identical: {'yes' if same else 'NO'}",
                    flush=True,
                )
            ratios = [p["ratio"] for p in pairs]
            med = statistics.median(ratios)
            loads = [v for p in pairs for v in p["load"]]
            out["sizes"].append(
                {
                    "size": size,
                    "pairs": pairs,
                    "overhead": {
                        "median": med - 1, "min": min(ratios) - 1, "max": max(ratios) - 1,
                    },
                    "load": [min(loads), max(loads)],
                }
            )
            print(
                f"{size}^2: overhead median {100 * (med - 1):+.1f} % (pairs "
                + ", ".join(f"{100 * (x - 1):+.1f}" for x in ratios)
                + f" %), load {min(loads):.1f}-{max(loads):.1f}, identical: "
                + ("yes" if all(p["identical"] for p in pairs) else "NO"),
                flush=True,
            )
    finally:
        client.close()
        cluster.close()
    out["identical"] = all_same
    print(json.dumps(out))
    if not all_same:
        raise SystemExit("the Dask plan differs from the local plan")


if __name__ == "__main__":
    main()
