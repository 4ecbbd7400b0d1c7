"""rkwave.adapt: a Python oracle gives the refinement of the same function given as the
library's expression, bit for bit; the CLI's run of a built-in signal is reproduced."""

import numpy as np
import pytest

import rkwave


def test_python_oracle_equals_expression():
    # x*x and a comparison are exact in both evaluators: the same samples, the same fit.
    expr = rkwave.adapt("x*x + (x > 0.6)", budget=4000, max_depth=14)
    calls = []

    def f(x):
        calls.append(x)
        return x * x + (1.0 if x > 0.6 else 0.0)

    mine = rkwave.adapt(f, budget=4000, max_depth=14)
    np.testing.assert_array_equal(mine.samples, expr.samples)
    np.testing.assert_array_equal(mine.coefficients, expr.coefficients)
    assert len(calls) == len(mine.samples)  # every oracle call is a sample, made once
    t = np.linspace(0, 1, 1001)
    np.testing.assert_array_equal(mine(t), expr(t))
    assert mine.report["stop"] == expr.report["stop"]


def test_builtin_signal_equals_cli(cli_json):
    report = cli_json("adapt", "--signal", "jumps", "--budget", 3000, "--max-depth", 12)
    mine = rkwave.adapt("jumps", budget=3000, max_depth=12)
    r = mine.report
    assert r["samples"] == report["samples"]
    assert r["functions"] == report["basis_size"]
    assert r["stop"] == report["stop"]
    assert len(r["rounds"]) == len(report["rounds"])
    assert r["rounds"][-1]["estimated_error"] == report["estimated_error"]


def test_oracle_exceptions_and_bad_values():
    def broken(x):
        if x > 0.5:
            raise KeyError("renderer crashed")
        return x

    with pytest.raises(KeyError, match="renderer crashed"):
        rkwave.adapt(broken, budget=2000)
    with pytest.raises(rkwave.RkwaveError, match="not finite"):
        rkwave.adapt(lambda x: np.nan if x > 0.5 else x, budget=2000)
    with pytest.raises(rkwave.RkwaveError, match="theta"):
        rkwave.adapt(lambda x: x, theta=2.0)
    with pytest.raises(rkwave.RkwaveError, match="does not parse|expected|unknown|parse"):
        rkwave.adapt("sin(", budget=2000)
    with pytest.raises(rkwave.RkwaveError, match="callable"):
        rkwave.adapt(3.0)
