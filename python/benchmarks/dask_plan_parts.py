#!/usr/bin/env python3
"""The parts of a round of ``rkwave.dask.TiledPlan`` timed in one process, no Dask: the
client's ``begin`` (checks, shares, each band's samples), every band's task
(``_rkwave.tiled_plan_band``) in turn, the client's ``commit``, and the bytes a round sends
(tasks' JSON, bands' samples) and gets back (outcomes' JSON).

    python python/benchmarks/dask_plan_parts.py [SIZE]    # default 256, 8 spp, tiles of 128

The renderer is ``dask_plan_overhead.render``.
"""

import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from dask_plan_overhead import render  # noqa: E402
from rkwave import _rkwave  # noqa: E402

warnings.simplefilter("ignore")
size = int(sys.argv[1]) if len(sys.argv) > 1 else 256
core = _rkwave.TiledPlanRounds((size, size), 8, None, tile=128)
while not core.done:
    xy = core.positions()
    v = render(xy, size)
    t = time.perf_counter()
    pending, tasks = core.begin(xy, v)
    tb = time.perf_counter() - t
    if pending is None:
        break
    outs, tt = [], []
    for task, s, _ in tasks:
        t = time.perf_counter()
        outs.append(_rkwave.tiled_plan_band(task, s))
        tt.append(time.perf_counter() - t)
    t = time.perf_counter()
    core.commit(pending, outs)
    tc = time.perf_counter() - t
    print(
        f"round {core.round}: begin {tb:.2f} s, tasks {[round(x, 1) for x in tt]} s, "
        f"commit {tc:.2f} s, task JSON {sum(len(a) for a, _, _ in tasks) / 1e6:.1f} MB, "
        f"samples {sum(s.nbytes for _, s, _ in tasks) / 1e6:.1f} MB, "
        f"outcomes {sum(map(len, outs)) / 1e6:.1f} MB",
        flush=True,
    )
