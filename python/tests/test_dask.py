"""rkwave.dask on a LocalCluster of two worker processes (one thread each): the tiled image
bit for bit that of `rkwave reconstruct --dim 2 --tile`, also after a worker is killed
mid-run; the 1D fit of chunks against `rkwave.fit`; bad input refused on the client before
any task. The ImportError without Dask is checked in a subprocess that hides Dask, so it runs
whether Dask is installed or not; the cluster tests are skipped without Dask."""

import os
import pickle
import platform
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import rkwave

EPS = np.finfo(float).eps


def test_rkwave_imports_without_dask_and_rkwave_dask_names_the_install():
    code = textwrap.dedent(
        """
        import sys
        class Hide:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in ("dask", "distributed"):
                    raise ImportError(f"No module named {name!r}")
        sys.meta_path.insert(0, Hide())
        import rkwave
        assert rkwave.TileGeometry((8, 8), 4, 1).count == 4
        try:
            import rkwave.dask
        except ImportError as e:
            print(e)
        else:
            raise SystemExit("rkwave.dask imported without dask")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "pip install dask[distributed]" in out.stdout


@pytest.fixture(scope="module")
def rd():
    pytest.importorskip("distributed")
    import rkwave.dask

    return rkwave.dask


@pytest.fixture(scope="module")
def client(rd):
    import cloudpickle
    from distributed import Client, LocalCluster

    # The fault-injecting hooks below travel to the workers by value.
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    cluster = LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    )
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


# ----------------------------------------------------------------------------------------
# 2D


W, H, TILE, HALO = 96, 80, 32, 8


@pytest.fixture(scope="module")
def image_files(tmp_path_factory):
    """Samples of a smooth two-channel image in three files, and their concatenation."""
    d = tmp_path_factory.mktemp("tiles")
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, [W, H], (4 * W * H, 2))
    a = np.c_[xy, np.sin(xy[:, 0] / 9), np.cos(xy[:, 1] / 7) * xy[:, 0] / W]
    np.save(d / "all.npy", a)
    paths = []
    for i, c in enumerate(np.array_split(a, 3)):
        paths.append(str(d / f"chunk{i}.npy"))
        np.save(paths[-1], c)
    return d, paths


@pytest.fixture(scope="module")
def cli_image(cli, image_files):
    d, _ = image_files
    out = d / "cli.npy"
    cli(
        "reconstruct", "--dim", "2", "--input", d / "all.npy", "--output", out,
        "--resolution", f"{W}x{H}", "--tile", TILE, "--halo", HALO, "--force",
    )
    return np.load(out)


def test_tiles_on_the_cluster_are_the_cli_tiled_image_bit_for_bit(
    rd, client, image_files, cli_image, tmp_path
):
    _, paths = image_files
    out = tmp_path / "image.npy"
    image, report = rd.reconstruct_image_tiles(paths, (W, H), TILE, HALO, out, client=client)
    assert image.shape == (H, W, 2)
    assert np.array_equal(image, cli_image)
    assert np.array_equal(np.load(out), cli_image)
    assert report["samples"] == 4 * W * H and len(report["tiles"]) == 9
    # One task per band of tile rows (3 x 3 tiles: 3 bands), every tile reported in order.
    assert report["tasks"] == 3
    assert [r["tile"] for r in report["tiles"]] == list(range(9))
    assert os.listdir(tmp_path) == ["image.npy"]


def test_the_workers_heap_setting_is_said_and_leaves_the_bits_alone(
    rd, client, image_files, cli_image
):
    """keep_heap (the allocator keeps freed memory, as the command line's) changes speed
    only: the same bits with it and without, and the notes say which was done."""
    _, paths = image_files
    kept, r1 = rd.reconstruct_image_tiles(paths, (W, H), TILE, HALO, client=client)
    alone, r2 = rd.reconstruct_image_tiles(
        paths, (W, H), TILE, HALO, client=client, keep_heap=False
    )
    assert np.array_equal(kept, cli_image) and np.array_equal(alone, cli_image)
    if platform.libc_ver()[0] == "glibc":
        assert r1["heap_kept"] == [True, True, True]
    assert any(n.startswith("worker heap: freed memory kept") for n in r1["notes"])
    assert any(n.startswith("worker heap: left alone") for n in r2["notes"])


def test_files_per_band_of_tile_rows_give_the_same_image(rd, client, image_files, tmp_path):
    """Samples split by band of tile rows (each tile opens only the files its window meets),
    in the order of the concatenated file: the same bits as the one-file layout."""
    d, _ = image_files
    a = np.load(d / "all.npy")
    band = np.minimum((a[:, 1] // TILE).astype(int), H // TILE)
    paths = []
    for b in range(band.max() + 1):
        paths.append(str(tmp_path / f"band{b}.npy"))
        np.save(paths[-1], a[band == b])
    single = [str(tmp_path / "one.npy")]
    np.save(single[0], a[np.argsort(band, kind="stable")])
    by_band, _ = rd.reconstruct_image_tiles(paths, (W, H), TILE, HALO, client=client)
    one, _ = rd.reconstruct_image_tiles(single, (W, H), TILE, HALO, client=client)
    assert np.array_equal(by_band, one)


class KillOnce:
    """Kills the worker process that runs tile `tile`, once (the marker file says it did)."""

    def __init__(self, marker, tile):
        self.marker, self.tile = str(marker), tile

    def __call__(self, tile):
        if tile == self.tile and not os.path.exists(self.marker):
            with open(self.marker, "w") as f:
                f.write(str(os.getpid()))
            os._exit(1)


class FailOn:
    """Raises in the task of tile `tile`."""

    def __init__(self, tile):
        self.tile = tile

    def __call__(self, tile):
        if tile == self.tile:
            raise RuntimeError(f"injected failure in tile {tile}")


def test_a_worker_killed_mid_run_costs_a_retry_and_the_image_is_identical(
    rd, client, image_files, cli_image, tmp_path
):
    _, paths = image_files
    marker = tmp_path / "killed"
    out = tmp_path / "image.npy"
    image, _ = rd.reconstruct_image_tiles(
        paths, (W, H), TILE, HALO, out, client=client, before_tile=KillOnce(marker, 4)
    )
    assert marker.exists(), "the hook never ran: nothing was killed"
    assert np.array_equal(image, cli_image)
    assert np.array_equal(np.load(out), cli_image)
    client.wait_for_workers(2, timeout=60)


def test_a_failed_tile_leaves_no_output(rd, client, image_files, tmp_path):
    _, paths = image_files
    out = tmp_path / "image.npy"
    with pytest.raises(RuntimeError, match="injected failure in tile 5"):
        rd.reconstruct_image_tiles(
            paths, (W, H), TILE, HALO, out, client=client, retries=0, before_tile=FailOn(5)
        )
    assert os.listdir(tmp_path) == []


class Touch:
    """Marks that a tile task ran."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __call__(self, tile):
        open(self.marker, "a").close()


@pytest.mark.parametrize(
    "case, message",
    [
        ("missing", "no such sample file"),
        ("tile0", "tile size 0"),
        ("halo", "halo 40 is larger than the tile size 32"),
        ("outside", "is outside the 96 x 80 image"),
        ("nonfinite", "non-finite value"),
        ("columns", "2 columns"),
        ("exists", "exists: give force=True"),
    ],
)
def test_bad_input_is_refused_before_any_task(rd, client, image_files, tmp_path, case, message):
    _, paths = image_files
    paths = list(paths)
    tile, halo, out = TILE, HALO, tmp_path / "image.npy"
    if case == "missing":
        paths.append(str(tmp_path / "nowhere.npy"))
    elif case == "tile0":
        tile = 0
    elif case == "halo":
        halo = 40
    elif case in ("outside", "nonfinite", "columns"):
        a = np.load(paths[1])
        if case == "outside":
            a[7, 1] = H + 0.5
        elif case == "nonfinite":
            a[7, 3] = np.nan
        else:
            a = a[:, :2]
        paths[1] = str(tmp_path / "bad.npy")
        np.save(paths[1], a)
    elif case == "exists":
        out.write_bytes(b"keep me")
    marker = tmp_path / "ran"
    with pytest.raises(rkwave.RkwaveError, match=message.replace("[", r"\[")):
        rd.reconstruct_image_tiles(
            paths, (W, H), tile, halo, out, client=client, before_tile=Touch(marker)
        )
    assert not marker.exists(), "a tile task ran before the input was refused"
    if case == "exists":
        assert out.read_bytes() == b"keep me"
    else:
        assert not out.exists()


# ----------------------------------------------------------------------------------------
# 1D


M, DOMAIN, P, LEVELS = 40_000, (0.0, 1.0), 3, (4, 11)


@pytest.fixture(scope="module")
def samples():
    x = np.sort(np.random.default_rng(5).uniform(0, 1, M))
    y = np.c_[np.sin(7 * x), np.exp(-x) * np.cos(20 * x)]
    return x, y


def save_chunks(folder, x, y, bounds):
    paths = []
    for i, (s, e) in enumerate(zip(bounds[:-1], bounds[1:])):
        paths.append(str(folder / f"chunk{i:03d}.npy"))
        np.save(paths[-1], np.c_[x[s:e], y[s:e]])
    return paths


def rayon_threads():
    """The worker-thread count of the library's global pool (rayon: RAYON_NUM_THREADS, else
    the CPUs this process may run on)."""
    given = os.environ.get("RAYON_NUM_THREADS")
    if given and given.isdigit() and int(given) > 0:
        return int(given)
    return len(os.sched_getaffinity(0))


def in_memory_parts(m):
    """The ranges the in-memory single-scale QR splits m sorted samples into, one per thread
    (reconstruct::single_scale::qr_parts: at least 16384 samples each)."""
    threads, least = rayon_threads(), 16_384
    if m < 2 * least or threads == 1:
        return [0, m]
    per = max(-(-m // threads), least)
    return list(range(0, m, per)) + [m]


def test_chunks_merged_as_the_in_memory_qr_merges_give_its_bits(rd, client, samples, tmp_path):
    """The in-memory QR rotates each of its parts into a triangle and merges them left to
    right; with one chunk per part, the tree of `merge_tree` is the same left-to-right
    order for up to three parts, so the coefficients are identical."""
    x, y = samples
    bounds = in_memory_parts(M)
    if len(bounds) - 1 > 3:
        pytest.skip(f"{len(bounds) - 1} in-memory parts: the pairwise tree differs from them")
    fit = rd.fit_chunks(save_chunks(tmp_path, x, y, bounds), DOMAIN, P, LEVELS, client=client)
    whole = rkwave.fit(x, y, domain=DOMAIN, p=P, levels=LEVELS)
    assert np.array_equal(fit.coefficients, whole.coefficients)


def test_chunks_in_another_tree_agree_within_the_qr_rounding(rd, client, samples, tmp_path):
    """Seven chunks of unequal sizes merge in a tree of depth 3 that the in-memory QR never
    takes. Both results are backward-stable least-squares solutions of the same problem, the
    rows rotated in another order: they differ by a small multiple of eps cond(K_J) ||c||.
    cond(K_J) of the equilibrated triangle is about 1 / sqrt(min_pivot) (the report's
    smallest pivot); the multiple 64 allows a rounding per rotation across the band
    (w = 3p - 2 = 7) and the tree's depth, with margin."""
    x, y = samples
    bounds = [0, 1000, 7000, 8000, 19000, 26000, 33333, M]
    fit = rd.fit_chunks(save_chunks(tmp_path, x, y, bounds), DOMAIN, P, LEVELS, client=client)
    whole = rkwave.fit(x, y, domain=DOMAIN, p=P, levels=LEVELS)
    c, ref = fit.coefficients, whole.coefficients
    cond = 1 / np.sqrt(whole.report["solve"]["single_scale"]["min_pivot"])
    bound = 64 * EPS * cond * np.abs(ref).max()
    assert np.abs(c - ref).max() <= bound
    assert fit.report["samples"] == M and fit.levels == LEVELS
    # The tree is fixed by the chunks, not by timing: the same bits without the cluster.
    parts = [
        rkwave.partial(x[s:e], y[s:e], DOMAIN, P, LEVELS, start=s)
        for s, e in zip(bounds[:-1], bounds[1:])
    ]
    local = rd.merge_tree(parts, lambda a, b: a.merge(b)).finish()
    assert np.array_equal(local.coefficients, c)


def test_a_dask_array_gives_the_bits_of_the_same_chunks_as_files(rd, client, samples, tmp_path):
    import dask.array as da

    x, y = samples
    bounds = [0, 5000, 20000, 31000, M]
    files = rd.fit_chunks(save_chunks(tmp_path, x, y, bounds), DOMAIN, P, LEVELS, client=client)
    arr = da.from_array(np.c_[x, y], chunks=(tuple(np.diff(bounds)), 3))
    from_array = rd.fit_chunks(arr, DOMAIN, P, LEVELS, client=client)
    assert np.array_equal(files.coefficients, from_array.coefficients)
    # One value column: the fit evaluates to (m,), as rkwave.fit of a 1-D y.
    single = rd.fit_chunks(arr[:, :2], DOMAIN, P, LEVELS, client=client)
    assert single(np.array([0.25, 0.5])).shape == (2,)


def test_automatic_levels_come_from_the_total_count(rd, client, samples, tmp_path):
    x, y = samples
    paths = save_chunks(tmp_path, x, y, [0, 20000, M])
    fit = rd.fit_chunks(paths, DOMAIN, P, client=client)
    assert fit.levels == rkwave.auto_levels(M, P)


def test_a_partial_pickles_to_the_same_bits(samples):
    x, y = samples
    a = rkwave.partial(x[:9000], y[:9000], DOMAIN, P, LEVELS)
    rest = rkwave.partial(x[9000:], y[9000:], DOMAIN, P, LEVELS, start=9000)
    b = pickle.loads(pickle.dumps(a))
    assert b.samples == a.samples and b.levels == a.levels
    assert pickle.dumps(b) == pickle.dumps(a)
    assert np.array_equal(a.merge(rest).finish().coefficients, b.merge(rest).finish().coefficients)
    # A part alone leaves most functions unsampled: refused, naming the fix.
    with pytest.raises(rkwave.RkwaveError, match="lower the fine level"):
        a.finish()
    with pytest.raises(rkwave.RkwaveError, match="same domain, p, family, levels"):
        a.merge(rkwave.partial(x[9000:], y[9000:], DOMAIN, P, (4, 10), start=9000))


def test_bad_chunks_are_refused_naming_the_problem(rd, client, samples, tmp_path):
    x, y = samples
    paths = save_chunks(tmp_path, x, y, [0, 20000, M])
    with pytest.raises(rkwave.RkwaveError, match="no such sample file"):
        rd.fit_chunks(paths + [str(tmp_path / "nowhere.npy")], DOMAIN, P, LEVELS, client=client)
    # Chunks out of order: the merge names the order to keep.
    with pytest.raises(rkwave.RkwaveError, match="merge partials of consecutive sorted chunks"):
        rd.fit_chunks(paths[::-1], DOMAIN, P, LEVELS, client=client)
    # A sample outside the domain: the task names its row in the whole set.
    a = np.load(paths[1])
    a[10, 0] = 1.5
    np.save(paths[1], a)
    with pytest.raises(rkwave.RkwaveError, match="20011"):
        rd.fit_chunks(paths, DOMAIN, P, LEVELS, client=client)
    with pytest.raises(rkwave.RkwaveError, match="list of .npy files"):
        rd.fit_chunks(paths[0], DOMAIN, P, LEVELS, client=client)
