"""The image plane: rkwave.reconstruct_image against the command line (bit for bit), against
mathematics (linear reproduction, the box filter as a per-pixel mean), and bad input."""

import warnings

import numpy as np
import pytest

import rkwave
from conftest import disc_scene

W, H = 32, 24


def scattered(spp=4, seed=11):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, (spp * W * H, 2)) * [W, H]


@pytest.mark.parametrize(
    "method, flags, p",
    [("wavelet", [], 2), ("wavelet", [], 3), ("local", ["--method", "local"], 2)],
)
def test_image_equals_cli_bit_for_bit(tmp_path, cli_json, method, flags, p):
    # `--pixels fit` and pixels="fit": the default estimate of both is `auto` (films chosen by
    # SURE), which uses no fit.
    xy = scattered()
    values = disc_scene(xy)
    np.save(tmp_path / "s.npy", np.c_[xy, values])
    theirs = cli_json(
        "reconstruct", "--dim", 2, "--input", tmp_path / "s.npy", "--resolution", f"{W}x{H}",
        "--output", tmp_path / "i.npy", "--p", p, "--pixels", "fit", *flags,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rkwave.RkwaveWarning)
        image, report = rkwave.reconstruct_image(
            xy, values, (W, H), p=p, method=method, pixels="fit"
        )
    assert image.shape == (H, W, 3) and image.dtype == np.float64
    np.testing.assert_array_equal(image, np.load(tmp_path / "i.npy"))
    assert report["method"] == method and report["samples"] == len(xy)
    # The command line's report, field for field (paths and times aside).
    assert report.keys() == theirs.keys()
    for key in ["resolution", "samples", "channels", "method", "p", "functions", "notes"]:
        assert report[key] == theirs[key], key


def test_linear_functions_are_reproduced():
    # p = 2 reproduces linear functions, and a pixel's box integral of a linear function is its
    # value at the pixel centre; the ridge 1e-9 of the normal equations perturbs the fit by
    # about that relative size.
    xy = scattered()
    f = 0.5 + 0.01 * xy[:, 0] - 0.02 * xy[:, 1]
    image, _ = rkwave.reconstruct_image(xy, f, (W, H), pixels="fit")
    cy, cx = np.mgrid[0:H, 0:W] + 0.5
    np.testing.assert_allclose(image[:, :, 0], 0.5 + 0.01 * cx - 0.02 * cy, atol=1e-6)


def test_box_filter_is_the_pixel_mean():
    # The box film filter (radius 1/2) is the mean of the samples inside each pixel: an
    # independent reference by numpy's bincount (rounding only: sums of at most ~15 terms).
    xy = scattered(8)
    values = np.c_[np.sin(xy[:, 0]), xy[:, 1]]
    image, report = rkwave.reconstruct_image(xy, values, (W, H), filter="box")
    pix = np.floor(xy[:, 1]).astype(int) * W + np.floor(xy[:, 0]).astype(int)
    count = np.bincount(pix, minlength=W * H)
    assert count.min() > 0, "every pixel has a sample with this seed"
    for c in range(2):
        mean = np.bincount(pix, values[:, c], minlength=W * H) / count
        np.testing.assert_allclose(image[:, :, c].ravel(), mean, rtol=1e-13, atol=1e-15)
    assert report["method"] == "box" and report["functions"] is None


def test_film_filters_by_name():
    xy = scattered()
    for name in ["box", "triangle", "gaussian", "mitchell", "lanczos"]:
        image, report = rkwave.reconstruct_image(xy, xy[:, 0], (W, H), filter=name)
        assert report["method"] == name and image.shape == (H, W, 1)
        assert np.isfinite(image).all()
    same, _ = rkwave.reconstruct_image(xy, xy[:, 0], (W, H), method="gaussian")
    np.testing.assert_array_equal(
        same, rkwave.reconstruct_image(xy, xy[:, 0], (W, H), filter="gaussian")[0]
    )


def stratified(spp=4, seed=5):
    """`spp` jittered strata (a 2 x 2 grid at 4) in every pixel, as a renderer's."""
    rng = np.random.default_rng(seed)
    g = int(np.sqrt(spp))
    py, px, sy, sx = np.meshgrid(np.arange(H), np.arange(W), np.arange(g), np.arange(g), indexing="ij")
    x = px.ravel() + (sx.ravel() + rng.uniform(size=px.size)) / g
    y = py.ravel() + (sy.ravel() + rng.uniform(size=py.size)) / g
    return np.c_[x, y]


def test_auto_is_the_default_and_equals_cli_bit_for_bit(tmp_path, cli_json):
    # Every pixel has four stratified samples, so auto makes its films (no fallback); the
    # command line without --pixels runs the same library function on the same samples.
    xy = stratified()
    values = disc_scene(xy) + 0.05 * np.random.default_rng(2).standard_normal((len(xy), 3))
    np.save(tmp_path / "s.npy", np.c_[xy, values])
    theirs = cli_json(
        "reconstruct", "--dim", 2, "--input", tmp_path / "s.npy", "--resolution", f"{W}x{H}",
        "--output", tmp_path / "i.npy",
    )
    image, report = rkwave.reconstruct_image(xy, values, (W, H))
    np.testing.assert_array_equal(image, np.load(tmp_path / "i.npy"))
    assert report["method"] == theirs["method"] == "auto"
    assert report["pixels"]["estimate"] == "auto" and report["pixels"]["fallback"] is None
    for key in ["films", "noise_level", "threshold", "description"]:
        assert report["pixels"][key] == theirs["pixels"][key], key
    same, _ = rkwave.reconstruct_image(xy, values, (W, H), pixels="auto")
    np.testing.assert_array_equal(same, image)


def test_a_fit_only_argument_selects_the_fit_with_a_warning():
    xy = stratified()
    values = disc_scene(xy)
    with pytest.warns(rkwave.RkwaveWarning, match="because p"):
        image, report = rkwave.reconstruct_image(xy, values, (W, H), p=2)
    assert report["method"] == "wavelet" and report["pixels"]["estimate"] == "fit"
    fit, _ = rkwave.reconstruct_image(xy, values, (W, H), pixels="fit")
    np.testing.assert_array_equal(image, fit)
    with pytest.raises(rkwave.RkwaveError, match="drop pixels= or filter="):
        rkwave.reconstruct_image(xy, values, (W, H), filter="gaussian", pixels="auto")
    with pytest.raises(rkwave.RkwaveError, match="unknown pixel estimate"):
        rkwave.reconstruct_image(xy, values, (W, H), pixels="median")


@pytest.mark.parametrize(
    "xy, values, kwargs, words",
    [
        (np.ones((10, 3)), np.ones(10), {}, "xy must have shape (m, 2)"),
        (np.ones((10, 2)), np.ones(9), {}, "values has shape (9,)"),
        (np.ones((10, 2)), np.r_[np.ones(9), np.nan], {}, "drop_nonfinite=True"),
        (np.r_[np.ones((9, 2)), [[np.nan, 1]]], np.ones(10), {}, "sample 9: position (NaN, 1) is not finite"),
        (np.r_[np.ones((9, 2)), [[40.0, 1]]], np.ones(10), {}, "outside"),
        (np.ones((10, 2)), np.ones((10, 5)), {}, "channels"),
        (np.ones((10, 2)), np.ones(10), {"resolution": (0, 5)}, "at least 1 pixel"),
        (np.ones((10, 2)), np.ones(10), {"p": 7}, "p = 1 to 4"),
        (np.ones((10, 2)), np.ones(10), {"filter": "sinc"}, "unknown film filter"),
        (np.ones((10, 2)), np.ones(10), {"method": "local", "filter": "box"}, "two methods"),
    ],
)
def test_bad_input_raises_value_error(xy, values, kwargs, words):
    kwargs = {"resolution": (W, H), **kwargs}
    with pytest.raises(rkwave.RkwaveError) as err:
        rkwave.reconstruct_image(xy, values, **kwargs)
    assert words in str(err.value), str(err.value)
