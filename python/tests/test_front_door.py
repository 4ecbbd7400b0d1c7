"""The image plane's front door from Python: the failure classes of issue 39, each decided once
by the library call the command line also makes (rkwave::image::job), so Python refuses what
the command line refuses, in its own keywords. The binary's side: tests/front_door.rs."""

import re
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

import rkwave
from conftest import cli_error

W, H = 16, 16


def scattered(spp=4, seed=7, channels=1):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1, (spp * W * H, 2)) * [W, H]
    values = np.c_[[np.sin(xy[:, 0] / 5 + c) for c in range(channels)]].T
    return xy, values


def test_default_estimate_at_the_largest_resolution_raises_memory_error(tmp_path, cli):
    # In a child interpreter: before the fix the default estimate allocated its per-pixel
    # statistics for 65536^2 pixels before any check, and the allocation failure aborted the
    # interpreter (a test in this process would die with it).
    script = textwrap.dedent(
        """
        import numpy as np, rkwave
        rng = np.random.default_rng(7)
        xy = rng.uniform(0, 16, (1024, 2))
        rkwave.set_memory_limit("8G")
        try:
            rkwave.reconstruct_image(xy, xy[:, 0], (65536, 65536))
        except MemoryError as e:
            assert isinstance(e, rkwave.ResourceLimitError)
            print("REFUSED", e)
        """
    )
    child = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert child.returncode == 0, child.stderr
    assert child.stdout.startswith("REFUSED "), child.stdout
    message = child.stdout[len("REFUSED ") :].strip()
    assert 'pixels=auto' in message and "resolution=" in message, message
    # The command line refuses the same request with the same estimate and limit.
    xy = np.random.default_rng(7).uniform(0, 16, (1024, 2))
    np.save(tmp_path / "s.npy", np.c_[xy, xy[:, 0]])
    code, _, err = cli(
        "--memory-limit", "8G", "reconstruct", "--dim", 2, "--resolution", "65536x65536",
        "--input", tmp_path / "s.npy", "--output", tmp_path / "o.npy", check=False,
    )
    assert code == 2
    theirs = cli_error(err)
    needs = re.compile(r"would need about .*? of memory, above the limit of \S+")
    assert needs.search(theirs).group(0) == needs.search(message).group(0)


@pytest.mark.parametrize(
    "keyword, flag, value",
    [("p", "--p", 7), ("rho", "--rho", 0.0), ("ridge", "--ridge", 1.0),
     ("smoothing", "--smoothing", -1.0)],
)
def test_same_refusals_as_the_command_line(tmp_path, cli, keyword, flag, value):
    xy, values = scattered()
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.reconstruct_image(xy, values, (W, H), **{keyword: value})
    assert py_err.value.kind == "InvalidInput"
    np.save(tmp_path / "s.npy", np.c_[xy, values])
    code, _, err = cli(
        "reconstruct", "--dim", 2, "--resolution", f"{W}x{H}", "--input", tmp_path / "s.npy",
        "--output", tmp_path / "o.npy", f"{flag}={value}", check=False,
    )
    assert code == 2
    # The same message, the parameter spelled as a flag there and as a keyword here.
    ours = str(py_err.value)
    assert ours.startswith(f"{keyword}=")
    assert cli_error(err).replace(f"{flag} ", f"{keyword}=", 1) == ours


@pytest.mark.parametrize(
    "bad, why",
    [
        (lambda v: v.astype(np.complex128) + 1j, "imaginary"),
        (lambda v: np.full(v.shape, 2**60, dtype=np.int64), r"2\^53"),
        (lambda v: v.astype(np.longdouble), "precision"),
    ],
)
def test_a_dtype_that_loses_information_is_refused(bad, why):
    xy, values = scattered()
    if why == "precision" and np.finfo(np.longdouble).eps >= np.finfo(np.float64).eps:
        pytest.skip("longdouble is float64 on this platform")
    with pytest.raises(rkwave.RkwaveError, match=why) as err:
        rkwave.reconstruct_image(xy, bad(values), (W, H), pixels="fit")
    assert "dtype" in str(err.value)


def test_lossless_dtypes_are_accepted_unchanged():
    xy, values = scattered()
    ints = np.round(values * 100).astype(np.int32)
    a, _ = rkwave.reconstruct_image(xy, ints, (W, H), pixels="fit")
    b, _ = rkwave.reconstruct_image(xy, ints.astype(np.float64), (W, H), pixels="fit")
    np.testing.assert_array_equal(a, b)
    small = np.round(values * 100).astype(np.int64)  # every value far below 2^53
    c, _ = rkwave.reconstruct_image(xy, small, (W, H), pixels="fit")
    np.testing.assert_array_equal(a, c)


def test_plan_save_refuses_another_plans_folder(tmp_path, cli):
    # The command line's one refusal (PlanState::check_new): the same kind and message, the
    # fixes spelled as keywords here and as flags there.
    first = rkwave.Plan(resolution=(W, H), spp=4)
    first.save(tmp_path)
    first.save(tmp_path)  # its own folder: saved again, no question
    other = rkwave.Plan(resolution=(W, H), spp=8, seed=3)
    with pytest.raises(rkwave.RkwaveError, match="overwrite=True") as err:
        other.save(tmp_path)
    code, _, cli_err = cli(
        "plan", "--resolution", f"{W}x{H}", "--spp", 8, "--state", tmp_path, "--out",
        tmp_path / "n0.npy", check=False,
    )
    assert code == 2, cli_err
    theirs = cli_error(cli_err)
    assert err.value.kind == "InvalidInput"
    assert theirs.startswith(f"{tmp_path} holds a plan already: continue it (--samples)"), theirs
    spelled = {"--samples": "the rendered samples of the plan's positions",
               "--force": "overwrite=True", "--state": "the Plan"}
    for flag, keyword in spelled.items():
        theirs = theirs.replace(f"({flag})", f"({keyword})")
    assert theirs == str(err.value)
    assert not (tmp_path / "n0.npy").exists()
    assert rkwave.Plan.load(tmp_path).report["budget"] == first.report["budget"]
    other.save(tmp_path, overwrite=True)
    assert rkwave.Plan.load(tmp_path).report["budget"] == other.report["budget"]
    loaded = rkwave.Plan.load(tmp_path)
    loaded.save(tmp_path)  # the folder it was loaded from


def test_the_default_estimate_names_the_keywords_that_changed_it():
    # Python's warnings keep each note as one message (the command line wraps its printed
    # notes at 100 characters; tests/front_door.rs).
    xy, values = scattered()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        rkwave.reconstruct_image(xy, values, (W, H), p=2, rho=4.0, smoothing=0.0)
    texts = [str(w.message) for w in seen if issubclass(w.category, rkwave.RkwaveWarning)]
    assert any("because p=, rho=, smoothing= (read by the fit only)" in t for t in texts), texts


# The plan's jobs (rkwave::image::job: PlanStart, PlanRound, PlanFinal): the same refusals and
# the same final image as `rkwave plan` and `rkwave reconstruct --dim 2 --state`.


def cli_plan_error(cli, tmp_path, *flags):
    code, _, err = cli(
        "plan", "--resolution", f"{W}x{H}", "--state", tmp_path / "state", "--out",
        tmp_path / "n0.npy", *flags, check=False,
    )
    assert code == 2, err
    assert not (tmp_path / "state" / "state.json").exists()
    return cli_error(err)


@pytest.mark.parametrize(
    "keyword, flag, value",
    [("p", "--p", 7), ("rho", "--rho", 0.5), ("false_alarm", "--false-alarm", 2.0),
     ("below_pixel", "--below-pixel", 9)],
)
def test_same_plan_refusals_as_the_command_line(tmp_path, cli, keyword, flag, value):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H), spp=4, **{keyword: value})
    assert py_err.value.kind == "InvalidInput"
    theirs = cli_plan_error(cli, tmp_path, "--spp", 4, f"{flag}={value}")
    # The same message, a parameter the library names as data spelled as a flag there and as
    # a keyword here (the refiner's own ranges name the parameter itself in both).
    assert theirs.replace(f"{flag} ", f"{keyword}=", 1) == str(py_err.value)


def test_a_plan_without_a_budget_is_refused_alike(tmp_path, cli):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H))
    assert py_err.value.kind == "InvalidInput"
    theirs = cli_plan_error(cli, tmp_path)
    assert theirs.replace("--budget", "budget=") == str(py_err.value)
    assert str(py_err.value).startswith("a new plan needs a sample budget: set budget=")


def test_a_plan_too_large_raises_memory_error_before_it_allocates(tmp_path, cli):
    # In a child interpreter: before the fix the start built the tree's flags of a 65536^2
    # image, whose allocation failure aborts the process.
    script = textwrap.dedent(
        """
        import rkwave
        rkwave.set_memory_limit("8G")
        try:
            rkwave.Plan(resolution=(65536, 65536), budget=100000)
        except MemoryError as e:
            assert isinstance(e, rkwave.ResourceLimitError)
            print("REFUSED", e)
        """
    )
    child = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert child.returncode == 0, child.stderr
    assert child.stdout.startswith("REFUSED "), child.stdout
    message = child.stdout[len("REFUSED ") :].strip()
    assert "budget=" in message and "below_pixel=" in message, message
    code, _, err = cli(
        "--memory-limit", "8G", "plan", "--resolution", "65536x65536", "--budget", 100000,
        "--state", tmp_path / "state", "--out", tmp_path / "n0.npy", check=False,
    )
    assert code == 2
    theirs = cli_error(err)
    needs = re.compile(r"would need about .*? of memory .*?, above the limit of \S+")
    assert needs.search(theirs).group(0) == needs.search(message).group(0)


def test_plan_image_is_the_command_lines_final_image(tmp_path, cli):
    from conftest import disc_scene

    plan = rkwave.Plan(resolution=(W, H), spp=4)
    while not plan.done:
        xy = plan.positions()
        plan.add(xy, disc_scene(xy))
    plan.save(tmp_path / "plan")
    cli("reconstruct", "--dim", 2, "--state", tmp_path / "plan", "--input",
        tmp_path / "plan" / "samples.npy", "--output", tmp_path / "final.npy")
    # one library call (PlanFinal) on both sides: the same pixels, bit for bit
    np.testing.assert_array_equal(np.load(tmp_path / "final.npy"), plan.image())
