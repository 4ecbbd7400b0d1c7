"""The GIL is released while the library computes: two fits in two Python threads run at
the same time. Each report stamps when its library call started and finished (wall clock);
the two intervals overlap. With the GIL held through a call the other thread could not even
enter its own, so the intervals could not overlap (no timing threshold is involved)."""

import threading

import numpy as np

import rkwave


def test_two_fits_in_two_threads_overlap():
    rng = np.random.default_rng(3)
    x = rng.uniform(0, 1, 1_000_000)
    y = np.sin(40 * x)
    barrier = threading.Barrier(2)
    reports = [None, None]

    def work(i):
        barrier.wait()
        reports[i] = rkwave.fit(x, y).report["time_s"]

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    a, b = reports
    assert a["started"] < a["finished"] and b["started"] < b["finished"]
    assert a["started"] < b["finished"] and b["started"] < a["finished"], reports
