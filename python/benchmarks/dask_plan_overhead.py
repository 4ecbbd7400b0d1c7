#!/usr/bin/env python3
"""The tiled plan's rounds on Dask (``rkwave.dask.TiledPlan``) against the local tiled plan
(``rkwave.Plan(tile=)``), as ratios in one run.

    python python/benchmarks/dask_plan_overhead.py [--size 512 1024] [--spp 8] [--tile 128]
        [--halo 0] [--rounds 1] [--rows-per-task 1]

Renderer: an analytic RGB image evaluated at the positions (a disc on a ramp times a sine
product, plus a deterministic hash "noise" of amplitude 0.05 so the plan does not stop at its
tolerance early); its time is not counted. Per size and round, alternating: the local plan
(one process, the plan's workers = the machine's threads) and the Dask plan on a
``LocalCluster(n_workers=2, processes=True, threads_per_worker=1)`` started before the rounds
(one task per band of ``rows_per_task`` tile rows, one tile at a time in a task), each run
from its start to its stop and its final image. Time: wall clock of the plan's calls
(construction, every ``add``, ``image``), the renderer's calls excluded. The band samples
sent to the workers are counted (each band's samples stay on a worker between rounds, only
the new ones are sent). The overhead is the
per-round ratio Dask / local minus one (median, min, max). Every round's positions and the
final image are checked equal bit for bit.
"""

import argparse
import json
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


def run(plan, size):
    """The plan to its stop and its image: (seconds in the plan's calls, rounds' positions,
    image)."""
    spent, rounds = 0.0, []
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
    return spent, rounds, image


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--tile", type=int, default=128)
    ap.add_argument("--halo", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--rows-per-task", type=int, default=1)
    args = ap.parse_args()

    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    client = Client(cluster)
    out = {"spp": args.spp, "tile": args.tile, "halo": args.halo, "sizes": []}
    try:
        for size in args.size:
            ratios, local_s, dask_s = [], [], []
            for r in range(args.rounds):
                t0 = time.perf_counter()
                t = time.perf_counter()
                plan = rkwave.Plan(
                    resolution=(size, size), spp=args.spp, tile=args.tile, halo=args.halo
                )
                start = time.perf_counter() - t
                a, ra, ia = run(plan, size)
                a += start
                t = time.perf_counter()
                dplan = rd.TiledPlan(
                    (size, size), spp=args.spp, tile=args.tile, halo=args.halo,
                    client=client, rows_per_task=args.rows_per_task,
                )
                start = time.perf_counter() - t
                b, rb, ib = run(dplan, size)
                b += start
                same = len(ra) == len(rb) and all(
                    np.array_equal(p, q) for p, q in zip(ra, rb)
                ) and np.array_equal(ia, ib)
                local_s.append(a)
                dask_s.append(b)
                ratios.append(b / a)
                report = dplan.report
                print(
                    f"{size}^2 round {r}: local {a:.1f} s, dask {b:.1f} s, ratio {b / a:.3f}, "
                    f"{len(ra)} plan rounds, {report['handed_out']} samples, "
                    f"{report['tasks_run']} tasks, band samples sent "
                    f"{report['samples_sent_mb']:.0f} MB, identical {same} "
                    f"(wall {time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
                if not same:
                    raise SystemExit("the Dask plan differs from the local plan")
            med = statistics.median(ratios)
            out["sizes"].append(
                {
                    "size": size,
                    "samples": report["handed_out"],
                    "plan_rounds": len(ra),
                    "tasks": report["tasks_run"],
                    "samples_sent_mb": report["samples_sent_mb"],
                    "local_s": local_s,
                    "dask_s": dask_s,
                    "overhead": {"median": med - 1, "min": min(ratios) - 1, "max": max(ratios) - 1},
                }
            )
            print(f"{size}^2: overhead median {100 * (med - 1):+.1f} %", flush=True)
    finally:
        client.close()
        cluster.close()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
