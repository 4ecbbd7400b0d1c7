"""rkwave.dask on a LocalCluster of two worker processes: the 1D fit of chunks against
rkwave.fit, a worker killed mid-run, and bad input refused before any task runs."""

import os
import signal

import numpy as np
import pytest

import rkwave

distributed = pytest.importorskip("distributed")
import rkwave.dask as rdask  # noqa: E402

M = 40_000
CHUNKS = 8


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def samples():
    rng = np.random.default_rng(5)
    x = np.sort(rng.uniform(0, 1, M))
    y = np.column_stack([np.sin(6 * x), np.abs(x - 0.4)])
    return x, y


@pytest.fixture()
def npy_chunks(tmp_path, samples):
    x, y = samples
    paths = []
    for i, rows in enumerate(np.array_split(np.arange(M), CHUNKS)):
        path = tmp_path / f"chunk{i}.npy"
        np.save(path, np.column_stack([x[rows], y[rows]]))
        paths.append(str(path))
    return paths


def max_rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


# A different merge tree rounds the same orthogonal reduction differently: the coefficients
# move by O(eps cond(K_J)) relative; cond(K_J) is about 10 at the automatic oversampling of
# 2-4 samples per function, so 1e-11 leaves a margin of 100 and more.
BOUND = 1e-11


def test_fit_chunks_matches_fit(client, samples, npy_chunks):
    x, y = samples
    whole = rkwave.fit(x, y, domain=(0, 1))
    for chunks in (npy_chunks, [(x[r], y[r]) for r in np.array_split(np.arange(M), 5)]):
        fitted = rdask.fit_chunks(chunks, domain=(0, 1), client=client)
        assert fitted.report["functions"] == whole.report["functions"]
        assert max_rel(fitted.coefficients, whole.coefficients) < BOUND
        grid = np.linspace(0, 1, 101)
        assert np.max(np.abs(fitted(grid) - whole(grid))) < 1e-9


def test_fit_chunks_of_a_dask_array(client, samples):
    da = pytest.importorskip("dask.array")
    x, y = samples
    arr = da.from_array(np.column_stack([x, y]), chunks=(7_000, 3))
    fitted = rdask.fit_chunks(arr, domain=(0, 1), client=client)
    whole = rkwave.fit(x, y, domain=(0, 1))
    assert max_rel(fitted.coefficients, whole.coefficients) < BOUND


def test_a_killed_worker_costs_a_retry_not_the_result(client, samples, npy_chunks):
    x, y = samples
    expected = rdask.fit_chunks(npy_chunks, domain=(0, 1), client=client).coefficients
    pids = list(client.run(os.getpid).values())

    def slow_partial(chunk, start, problem, _orig=rdask._partial):
        import time

        time.sleep(0.3)
        return _orig(chunk, start, problem)

    future = client.submit(lambda: None)  # warm the connection
    future.result()
    original = rdask._partial
    rdask._partial = slow_partial
    try:
        import threading

        killer = threading.Timer(0.5, lambda: os.kill(pids[0], signal.SIGKILL))
        killer.start()
        again = rdask.fit_chunks(npy_chunks, domain=(0, 1), client=client).coefficients
        killer.join()
    finally:
        rdask._partial = original
    np.testing.assert_array_equal(again, expected)
    client.wait_for_workers(2, timeout=30)


def test_bad_input_is_refused_before_work(tmp_path, npy_chunks, samples):
    x, y = samples
    with pytest.raises(rkwave.RkwaveError, match="no such file"):
        rdask.fit_chunks(npy_chunks + [str(tmp_path / "missing.npy")], domain=(0, 1))
    empty = tmp_path / "empty.npy"
    np.save(empty, np.zeros((0, 3)))
    with pytest.raises(rkwave.RkwaveError, match="empty"):
        rdask.fit_chunks(npy_chunks + [str(empty)], domain=(0, 1))
    narrow = tmp_path / "narrow.npy"
    np.save(narrow, np.column_stack([x[:10], y[:10, 0]]))
    with pytest.raises(rkwave.RkwaveError, match="channels"):
        rdask.fit_chunks(npy_chunks + [str(narrow)], domain=(0, 1))
    with pytest.raises(rkwave.RkwaveError, match="no chunks"):
        rdask.fit_chunks([], domain=(0, 1))


def test_partials_out_of_order_name_the_fix(samples):
    x, y = samples
    kw = dict(samples=M, domain=(0, 1))
    with pytest.raises(rkwave.RkwaveError, match="sort"):
        rkwave.partial_fit(x[::-1].copy(), y[::-1].copy(), **kw)
    a = rkwave.partial_fit(x[: M // 2], y[: M // 2], **kw)
    b = rkwave.partial_fit(x[M // 2:], y[M // 2:], start=M // 2, **kw)
    with pytest.raises(rkwave.RkwaveError, match="earlier first"):
        rkwave.merge_partials(b, a, **kw)
    with pytest.raises(rkwave.RkwaveError, match="merge the partials"):
        rkwave.finish_partial(a, **kw)
