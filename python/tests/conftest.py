"""Shared fixtures: the `rkwave` command line of the same checkout (results are compared with
it), scratch folders, a small analytic "renderer"."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _binary():
    given = os.environ.get("RKWAVE_BIN")
    if given:
        return pathlib.Path(given)
    return ROOT / "target" / "release" / "rkwave"


@pytest.fixture(scope="session")
def cli():
    """Runs `rkwave ARGS...`; returns (exit code, stdout, stderr). The binary is the checkout's
    release build (`cargo build --release`, or `RKWAVE_BIN`); without it the comparisons with
    the command line are skipped, unless RKWAVE_REQUIRE_CLI=1 (set by .ci/run) makes that a
    failure."""
    binary = _binary()
    if not binary.exists():
        if os.environ.get("RKWAVE_REQUIRE_CLI") == "1":
            pytest.fail(f"{binary} is missing: run cargo build --release first")
        pytest.skip(f"{binary} is missing: run cargo build --release to compare with the CLI")

    def run(*args, check=True):
        out = subprocess.run(
            [str(binary), *map(str, args)], capture_output=True, text=True, timeout=600
        )
        if check and out.returncode != 0:
            raise AssertionError(f"rkwave {' '.join(map(str, args))}: {out.stderr}")
        return out.returncode, out.stdout, out.stderr

    return run


@pytest.fixture(scope="session")
def cli_json(cli):
    """Runs `rkwave ARGS... --json` and parses its report."""

    def run(*args):
        return json.loads(cli(*args, "--json")[1])

    return run


def cli_error(stderr):
    """The message of the CLI's `error: ...` line."""
    lines = [l for l in stderr.splitlines() if l.startswith("error: ")]
    assert len(lines) == 1, stderr
    return lines[0][len("error: ") :]


def disc_scene(xy):
    """A renderer stand-in: an RGB image of a disc with a sharp edge and a smooth ramp,
    evaluated exactly at the positions (pixel units)."""
    x, y = xy[:, 0], xy[:, 1]
    inside = ((x - 20.0) ** 2 + (y - 14.0) ** 2 < 81.0).astype(float)
    return np.stack([inside, 0.02 * x, 0.5 * inside + 0.01 * y], axis=1)
