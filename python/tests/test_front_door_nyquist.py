"""Issue 39's failure class "the tiled fit differing from the untiled one far beyond the tile
study's tolerance on a scene with detail near Nyquist", through Python: the untiled image of
`reconstruct_image` against the command line's tiled image of the same samples (the
binary's side: tests/front_door_nyquist.rs; the library's: tests/tiles_nyquist.rs)."""

import numpy as np

import rkwave

N = 96


def nyquist_samples(n=N, spp=8, seed=5):
    """Detail at and near Nyquist on `n x n`, stratified (a jittered 4 x 2 grid a pixel):
    stripes of 0.4 cycles a pixel, a chirp whose local frequency passes 0.5, a thin line, and
    a deterministic hash so the values are no low-degree polynomial."""
    rng = np.random.default_rng(seed)
    gx, gy = 4, 2
    px, py = np.meshgrid(np.arange(n), np.arange(n))
    sx, sy = np.meshgrid(np.arange(gx), np.arange(gy))
    x = (px[..., None, None] + (sx + rng.uniform(0, 1, (n, n, gy, gx))) / gx).ravel()
    y = (py[..., None, None] + (sy + rng.uniform(0, 1, (n, n, gy, gx))) / gy).ravel()
    stripes = 0.5 + 0.4 * np.sin(2 * np.pi * 0.4 * x)
    chirp = 0.5 + 0.4 * np.cos(np.pi * 0.9 * n * (x * x + y * y) / (n * n))
    line = np.where(np.abs(y - 0.37 * x - 5.0) < 0.3, 0.6, 0.0)
    noise = 0.05 * np.sin(12.9898 * x + 78.233 * y)
    values = np.c_[stripes + noise, chirp + line, 0.5 * stripes + 0.5 * chirp + noise]
    return np.c_[x, y], values


def test_tiled_and_untiled_images_agree_near_nyquist(tmp_path, cli):
    xy, values = nyquist_samples()
    assert len(xy) == 8 * N * N
    untiled, _ = rkwave.reconstruct_image(xy, values, (N, N), pixels="fit")
    path = tmp_path / "s.npy"
    np.save(path, np.c_[xy, values])
    cli("reconstruct", "--dim", 2, "--input", path, "--resolution", f"{N}x{N}",
        "--pixels", "fit", "--output", tmp_path / "untiled.npy")
    cli("reconstruct", "--dim", 2, "--input", path, "--resolution", f"{N}x{N}",
        "--pixels", "fit", "--tile", 32, "--halo", 12, "--output", tmp_path / "tiled.npy")
    # The same library call on both sides: the same untiled pixels, bit for bit.
    np.testing.assert_array_equal(np.load(tmp_path / "untiled.npy"), untiled)
    tiled = np.load(tmp_path / "tiled.npy")
    # Within 1.1e-5 of the range: the default untiled fit within 1e-5 of the exact fit, the
    # tiled within 1e-6 of it (tests/tiles_nyquist.rs); 4.4e-5 before the CG's error stop.
    d = np.abs(tiled - untiled).max() / np.ptp(untiled)
    assert d <= 1.1e-5, d
