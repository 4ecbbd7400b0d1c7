#!/usr/bin/env python3
"""Where the Dask tiled plan's extra time goes: one local run and one Dask run of the same
plan, the Dask run's time split into its parts.

    python python/benchmarks/dask_plan_parts.py [SIZE] [PAIRS]   # default 256, 1 pair

Per pair: the local plan (``rkwave.Plan(tile=128)``, 8 spp, rayon over the tiles with the
machine's threads), then ``rkwave.dask.TiledPlan`` on a ``LocalCluster(n_workers=2,
processes=True, threads_per_worker=1)`` with Dask's task stream recorded. The Dask run's
wall time (the plan's calls, the renderer ``dask_plan_overhead.render`` excluded) is split:

- ``client``: the client's own calls of ``_rkwave.TiledPlanRounds`` (``new``: the plan's
  start and base positions; ``begin``: checks, shares, each band's samples; ``commit``;
  ``final_tasks``; ``stitch``; the rest),
  timed through a proxy;
- per round (and the final image), the wall of the band tasks (submit to gather) split as
  ``busy``: the mean over the two workers of their band tasks' compute time (the tiles'
  steps, the held states' digests, the samples' copy into the task), ``imbalance``: the
  busiest worker's compute minus that mean (a worker idle while the other finishes its
  bands: rayon in the local plan balances tiles, Dask balances whole bands), and ``rest``:
  the wall minus the busiest worker's compute (scheduling, transfers, the outcomes'
  (de)serialisation, ``TiledPlan``'s own Python code in ``add`` such as the held samples'
  digests, the small tasks: the samples' concatenation, the outcomes' getitem);
- ``python``: the run's wall outside ``add`` and ``image`` and the core's calls (about 0).

Against the local run's wall, the overhead is the sum of the parts beyond the tiles' steps.
Every round's positions and the image are checked identical to the local run's. The load
average (``os.getloadavg``) is printed with each run.
"""

import collections
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

import rkwave  # noqa: E402
import rkwave.dask as rd  # noqa: E402
from dask_plan_overhead import load, render, run  # noqa: E402

warnings.simplefilter("ignore")


class Timed:
    """A proxy of the client's core timing its method calls, by name."""

    def __init__(self, core):
        self.core, self.seconds = core, collections.defaultdict(float)

    def __getattr__(self, name):
        attr = getattr(self.core, name)
        if not callable(attr):
            return attr

        def timed(*args, **kw):
            t = time.perf_counter()
            try:
                return attr(*args, **kw)
            finally:
                self.seconds[name] += time.perf_counter() - t

        return timed


class Rounds:
    """The plan with each ``add`` and ``image`` call's wall interval recorded (epoch
    seconds, as Dask's task stream)."""

    def __init__(self, plan):
        self.plan, self.intervals = plan, []

    def __getattr__(self, name):
        return getattr(self.plan, name)

    def _timed(self, fn, *args):
        t = time.time()
        try:
            return fn(*args)
        finally:
            self.intervals.append((t, time.time()))

    def add(self, xy, values):
        return self._timed(self.plan.add, xy, values)

    def image(self):
        return self._timed(self.plan.image)


def split(stream, intervals):
    """Per interval (round or image): (wall, mean worker busy, busiest worker busy) of the
    band tasks' compute, from the task stream."""
    rows = []
    for t0, t1 in intervals:
        busy = collections.defaultdict(float)
        for task in stream:
            name = str(task["key"])
            if not name.startswith(("_plan_band_task", "_plan_final_task")):
                continue
            for ss in task["startstops"]:
                if ss["action"] == "compute" and t0 <= ss["start"] <= t1:
                    busy[task["worker"]] += ss["stop"] - ss["start"]
        values = list(busy.values()) + [0.0] * (2 - len(busy))
        rows.append((t1 - t0, sum(values) / len(values), max(values)))
    return rows


def main():
    from distributed import Client, LocalCluster, get_task_stream

    size = int(sys.argv[1]) if len(sys.argv) > 1 else 256
    pairs = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    cluster = LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    client = Client(cluster)
    print(f"dask_plan_parts: {size}^2, 8 spp, tiles of 128, {pairs} pair(s)", flush=True)
    try:
        for k in range(pairs):
            l0 = load()
            a, ra, ia, _ = run(
                lambda: rkwave.Plan(resolution=(size, size), spp=8, tile=128), size
            )
            l1 = load()
            holder = {}

            def make():
                t = time.perf_counter()
                plan = rd.TiledPlan((size, size), spp=8, tile=128, client=client)
                plan._core = Timed(plan._core)
                plan._core.seconds["new"] = time.perf_counter() - t
                holder["plan"] = Rounds(plan)
                return holder["plan"]

            with get_task_stream(client) as ts:
                b, rb, ib, _ = run(make, size)
            l2 = load()
            plan = holder["plan"]
            same = (
                len(ra) == len(rb)
                and all(np.array_equal(p, q) for p, q in zip(ra, rb))
                and np.array_equal(ia, ib)
            )
            client_s = dict(plan.plan._core.seconds)
            rows = split(ts.data, plan.intervals)
            inner = {"begin", "commit"}
            outer = sum(client_s.values())
            # the client's calls inside the intervals are not band-task wall
            band_wall = sum(w for w, _, _ in rows) - sum(
                v for n, v in client_s.items() if n in inner | {"final_tasks", "stitch"}
            )
            busy = sum(m for _, m, _ in rows)
            imbalance = sum(x - m for _, m, x in rows)
            rest = band_wall - sum(x for _, _, x in rows)
            python = b - outer - band_wall
            r = plan.report
            print(
                f"pair {k}: local {a:.1f} s (load {l0:.1f} -> {l1:.1f}), dask {b:.1f} s "
                f"(load {l1:.1f} -> {l2:.1f}), ratio {b / a:.3f}, identical: "
                f"{'yes' if same else 'NO'}",
                flush=True,
            )
            print(
                f"  dask {b:.1f} s = client {outer:.2f} s ("
                + ", ".join(f"{n} {v:.2f}" for n, v in sorted(client_s.items()))
                + f") + band tasks' wall {band_wall:.1f} s (busy {busy:.1f}, imbalance "
                f"{imbalance:.1f}, rest {rest:.1f}) + python {python:.2f} s",
                flush=True,
            )
            print(
                "  per round (wall, mean busy, busiest): "
                + "; ".join(f"{w:.1f} {m:.1f} {x:.1f}" for w, m, x in rows)
                + f"; sent: samples {r['samples_sent_mb']:.1f} MB, tasks {r['tasks_mb']:.2f}"
                f" MB, outcomes {r['outcomes_mb']:.2f} MB",
                flush=True,
            )
    finally:
        client.close()
        cluster.close()


if __name__ == "__main__":
    main()
