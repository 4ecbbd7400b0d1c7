"""1D: rkwave.fit against the command line (bit for bit: the same library entry point runs),
against mathematics (polynomial reproduction), the input conversions, and bad input."""

import warnings

import numpy as np
import pytest

import rkwave
from conftest import cli_error


def samples(m=3000, seed=5):
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(-1.0, 2.0, m))
    return x, np.sin(3 * x) + (x > 0.7)


@pytest.mark.parametrize(
    "flags, kwargs",
    [
        ([], {}),
        (["--method", "local", "--solver", "qr"], {"method": "local", "solver": "qr"}),
        (["--method", "global", "--levels", "4..8"], {"method": "global", "levels": (4, 8)}),
        (["--method", "dense", "--levels", "4..7"], {"method": "dense", "levels": (4, 7)}),
        (["--p", "5", "--rho", "3"], {"p": 5, "rho": 3.0}),
        (["--factorization", "normal"], {"factorization": "normal"}),
    ],
)
def test_fit_equals_cli_bit_for_bit(tmp_path, cli, cli_json, flags, kwargs):
    x, y = samples()
    np.save(tmp_path / "s.npy", np.c_[x, y, 2 * y])
    report = cli_json(
        "reconstruct", "--input", tmp_path / "s.npy", "--output", tmp_path / "g.npy",
        "--grid", 777, *flags,
    )
    grid = np.load(tmp_path / "g.npy")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rkwave.RkwaveWarning)
        f = rkwave.fit(x, np.c_[y, 2 * y], **kwargs)
    # The same library entry point on the same float64 input: equal, not close.
    np.testing.assert_array_equal(f(grid[:, 0]), grid[:, 1:])
    r = f.report
    for key in ["functions", "coarse", "fine", "oversampling", "warnings", "method"]:
        assert r[key] == report[key], key
    assert r["residual_rms"] == report["residual_rms"]
    assert r["domain"] == report["domain"] == [x.min(), x.max()]


def test_polynomials_are_reproduced():
    # p vanishing moments reproduce polynomials of degree < p exactly; the residual is then
    # rounding only: m samples of size O(1) give errors of a few ulps times cond(K) ~ 1e2.
    x, _ = samples(4000, 9)
    for p in (2, 3, 4):
        y = np.polyval(np.arange(1.0, p + 1), x)
        f = rkwave.fit(x, y, p=p)
        t = np.linspace(x.min(), x.max(), 101)
        np.testing.assert_allclose(f(t), np.polyval(np.arange(1.0, p + 1), t), atol=1e-9)
        assert max(f.report["residual_rms"]) < 1e-9


def test_shapes_and_conversions_agree():
    x, y = samples()
    y2 = np.c_[y, -y]
    base = rkwave.fit(x, y2)
    # Strided and Fortran-ordered float64 input: the same numbers, the same fit.
    xs = np.repeat(x, 2)[::2]
    assert not xs.flags.c_contiguous or xs.strides == (8,)
    same = rkwave.fit(np.asfortranarray(np.c_[x, x])[:, 0], np.asfortranarray(y2))
    np.testing.assert_array_equal(same.coefficients, base.coefficients)
    np.testing.assert_array_equal(rkwave.fit(xs, y2).coefficients, base.coefficients)
    # float32 input is converted once to float64: equal to the fit of the converted values.
    f32 = rkwave.fit(x.astype(np.float32), y2.astype(np.float32))
    f64 = rkwave.fit(x.astype(np.float32).astype(float), y2.astype(np.float32).astype(float))
    np.testing.assert_array_equal(f32.coefficients, f64.coefficients)
    # (m,) in, (m,) out; (m, k) in, (m, k) out; a single channel keeps the positions' shape.
    one = rkwave.fit(x, y)
    assert one(x[:5]).shape == (5,) and base(x[:5]).shape == (5, 2)
    assert one(x[:6].reshape(2, 3)).shape == (2, 3)
    assert one.coefficients.shape == (one.report["functions"],)
    assert base.coefficients.shape == (base.report["functions"], 2)
    np.testing.assert_array_equal(one(x[:7]), base(x[:7])[:, 0])
    assert one.levels == (one.report["coarse"], one.report["fine"])
    assert len(one.indices) == one.report["functions"]
    # A list is converted by numpy.
    np.testing.assert_array_equal(one(list(x[:3])), one(x[:3]))


@pytest.mark.parametrize(
    "args, kwargs, words",
    [
        ((np.linspace(0, 1, 100), np.r_[np.ones(99), np.nan]), {}, "not finite"),
        ((np.r_[np.linspace(0, 1, 99), np.nan], np.ones(100)), {}, "x[99] = NaN is not finite"),
        ((np.linspace(0, 1, 100), np.ones(99)), {}, "y has shape (99,)"),
        ((np.linspace(0, 1, 100), np.ones((100, 2, 2))), {}, "(m,) or (m, channels)"),
        ((np.ones((10, 10)), np.ones(10)), {}, "x must be 1-dimensional"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"p": 11}, "p = 11"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"method": "fast"}, 'method="fast"'),
        ((np.linspace(0, 1, 100), np.ones(100)), {"levels": "deep"}, "neither"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"rho": -1.0}, "rho=-1"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"cutoff": 2.0}, "cutoff=2"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"rings": 11}, "rings=11"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"domain": (1.0, 0.0)}, "domain=(1.0, 0.0)"),
        ((np.linspace(0, 1, 100), np.ones(100)), {"domain": (0.0, 0.5)}, "outside"),
        ((np.full(100, 0.5), np.ones(100)), {}, "give domain=(a, b)"),
        ((np.array(["a", "b"]), np.ones(2)), {}, "x must be a float64 or float32 array"),
    ],
)
def test_bad_input_raises_value_error(args, kwargs, words):
    with pytest.raises(rkwave.RkwaveError) as err:
        rkwave.fit(*args, **kwargs)
    assert isinstance(err.value, ValueError)
    assert words in str(err.value), str(err.value)
    assert err.value.kind in ("InvalidInput", "Undetermined")


def test_errors_carry_the_cli_message(tmp_path, cli):
    # The library's message, with the fix in this module's keywords where the CLI names its
    # flags: too few samples for fixed levels, and a p out of range.
    x = np.linspace(0, 1, 50)
    np.save(tmp_path / "s.npy", np.c_[x, x])
    code, _, err = cli(
        "reconstruct", "--input", tmp_path / "s.npy", "--output", tmp_path / "g.npy",
        "--levels", "4..9", check=False,
    )
    assert code == 2
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.fit(x, x, levels=(4, 9))
    assert py_err.value.kind == "Undetermined"
    expected = (
        cli_error(err).replace("--levels n..N", "levels=(n, N)").replace("--levels auto", 'levels="auto"')
    )
    assert str(py_err.value) == expected
    code, _, err = cli(
        "reconstruct", "--input", tmp_path / "s.npy", "--output", tmp_path / "g2.npy",
        "--p", "11", check=False,
    )
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.fit(x, x, p=11)
    assert code == 2 and str(py_err.value) == cli_error(err)


def test_resource_refusal_is_memory_error():
    x, y = samples(100_000)
    rkwave.set_memory_limit("1M")
    try:
        with pytest.raises(MemoryError) as err:
            rkwave.fit(x, y)
        assert isinstance(err.value, rkwave.ResourceLimitError)
        assert "above the limit" in str(err.value)
    finally:
        rkwave.set_memory_limit(None)
    rkwave.fit(x, y)  # the default limit is back


def test_fallbacks_are_warnings():
    # Samples with a hole: the automatic levels take a density tree, and say so.
    x = np.r_[np.linspace(0, 0.4, 1000), np.linspace(0.6, 1, 1000)]
    with pytest.warns(rkwave.RkwaveWarning, match="strongly non-uniform") as seen:
        f = rkwave.fit(x, x)
    assert [str(w.message) for w in seen] == f.report["warnings"]
    assert f.report["fallbacks"][0]["fallback"]["kind"] == "density_tree"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rkwave.fit(*samples())  # no fallback, no warning


def test_local_vs_global_equals_cli(cli_json):
    report = cli_json("report", "--p", 3, "--fine", 6, "--samples", 600, "--layout", "random")
    mine = rkwave.local_vs_global(p=3, fine=6, samples=600, layout="random")
    for key in ["functions", "oversampling", "reference", "error", "reconstruction", "cut"]:
        assert mine[key] == report[key], key
    with pytest.raises(rkwave.RkwaveError, match="samples=0"):
        rkwave.local_vs_global(samples=0)
    with pytest.raises(rkwave.RkwaveError, match="signal"):
        rkwave.local_vs_global(signal="nonesuch")
