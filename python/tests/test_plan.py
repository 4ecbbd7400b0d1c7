"""rkwave.Plan: the renderer's loop in process gives the positions, tree and image of
`rkwave plan` driven through files, bit for bit, and its state moves between the two. The
image compared is the stopping call's (`--final-image`), which is also `reconstruct --dim 2
--state`'s: all three make it by the library's one final-image job (test_front_door.py)."""

import json
import warnings

import numpy as np
import pytest

import rkwave
from conftest import disc_scene

W, H, SPP = 32, 24, 4


def cli_loop(cli, run, rounds=None, flags=()):
    """`rkwave plan` through files with disc_scene as the renderer (`flags` added to the
    first call, the one that makes the plan); stops after `rounds` calls (None: until the plan
    stops, whose call writes `run / "final.npy"`). Returns the positions of every round and
    the path of the last sample file."""
    cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state", run, "--out", run / "n0.npy",
        *flags)
    positions, everything = [np.load(run / "n0.npy")], None
    k = 0
    while rounds is None or k < rounds:
        new = positions[-1]
        rendered = np.c_[new, disc_scene(new)]
        everything = rendered if everything is None else np.r_[everything, rendered]
        np.save(run / f"s{k}.npy", everything)
        k += 1
        report = json.loads(
            cli("plan", "--state", run, "--samples", run / f"s{k - 1}.npy", "--out",
                run / f"n{k}.npy", "--final-image", run / "final.npy", "--json")[1]
        )
        if report["stop"] is not None:
            break
        positions.append(np.load(run / f"n{k}.npy"))
    return positions, run / f"s{k - 1}.npy"


def python_loop(plan):
    positions = []
    while not plan.done:
        xy = plan.positions()
        positions.append(xy)
        plan.add(xy, disc_scene(xy))
    return positions


def image_of_python_loop():
    """The final image of the whole loop run in Python alone."""
    whole = rkwave.Plan(resolution=(W, H), spp=SPP)
    python_loop(whole)
    return whole.image()


def saved_after_two_rounds(folder):
    """A plan given two rounds of samples in Python, then saved to `folder`."""
    plan = rkwave.Plan(resolution=(W, H), spp=SPP)
    for _ in range(2):
        xy = plan.positions()
        plan.add(xy, disc_scene(xy))
    plan.save(folder)
    return plan


def test_plan_equals_cli_from_files(tmp_path, cli):
    run = tmp_path / "run"
    cli_positions, last = cli_loop(cli, run)
    plan = rkwave.Plan(resolution=(W, H), spp=SPP)
    positions = python_loop(plan)
    assert len(positions) == len(cli_positions) > 2
    for mine, theirs in zip(positions, cli_positions):
        np.testing.assert_array_equal(mine, theirs)
    image = plan.image()
    assert image.shape == (H, W, 3)
    np.testing.assert_array_equal(image, np.load(run / "final.npy"))
    np.testing.assert_array_equal(plan.samples, np.load(last))
    report = plan.report
    assert report["done"] and report["samples"] == len(np.load(last)) <= W * H * SPP
    assert len(report["steps"]) == len(positions)
    assert plan.positions().shape == (0, 2)


@pytest.mark.parametrize("solver,output", [("direct", "auto"), ("pcg", "residual_clamped")])
def test_plan_keywords_are_the_cli_flags(tmp_path, cli, solver, output):
    """`solver=` and `output_pixels=` make the plan of `--solver` and `--output-pixels`: the
    same positions every round and the same final image, bit for bit."""
    run = tmp_path / "run"
    cli_positions, last = cli_loop(
        cli, run, flags=("--solver", solver, "--output-pixels", output))
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, solver=solver, output_pixels=output)
    positions = python_loop(plan)
    assert len(positions) == len(cli_positions) > 2
    for mine, theirs in zip(positions, cli_positions):
        np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_array_equal(plan.image(), np.load(run / "final.npy"))
    default = rkwave.Plan(resolution=(W, H), spp=SPP)
    python_loop(default)
    # another output or solver is another image (the keywords are not ignored)
    assert not np.array_equal(plan.image(), default.image())
    if solver == "direct":
        # under the direct solve `reconstruct --state` refits to the same image (README)
        cli("reconstruct", "--dim", "2", "--state", run, "--input", last, "--output",
            tmp_path / "again.npy")
        np.testing.assert_array_equal(np.load(tmp_path / "again.npy"), plan.image())


def test_state_moves_between_cli_and_python(tmp_path, cli):
    expected = image_of_python_loop()
    # Python -> CLI: two rounds here, saved, then continued by the CLI (its stopping call
    # writes the image).
    plan = saved_after_two_rounds(tmp_path / "a")
    samples, nxt = np.load(tmp_path / "a" / "samples.npy"), np.load(tmp_path / "a" / "next.npy")
    np.testing.assert_array_equal(nxt, plan.positions())
    k = 0
    while len(nxt):
        samples = np.r_[samples, np.c_[nxt, disc_scene(nxt)]]
        np.save(tmp_path / f"s{k}.npy", samples)
        cli("plan", "--state", tmp_path / "a", "--samples", tmp_path / f"s{k}.npy", "--out",
            tmp_path / f"n{k}.npy", "--final-image", tmp_path / "a.npy")
        nxt, k = np.load(tmp_path / f"n{k}.npy"), k + 1
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), expected)
    # CLI -> Python: two calls of the CLI, loaded with its files, finished here.
    run = tmp_path / "b"
    positions, last = cli_loop(cli, run, rounds=2)
    loaded = rkwave.Plan.load(run, samples=last, positions=run / "n2.npy")
    np.testing.assert_array_equal(loaded.positions(), positions[-1])
    python_loop(loaded)
    np.testing.assert_array_equal(loaded.image(), expected)
    # save / load in Python alone.
    plan.save(tmp_path / "c")
    again = rkwave.Plan.load(tmp_path / "c")
    np.testing.assert_array_equal(again.positions(), plan.positions())
    python_loop(again)
    np.testing.assert_array_equal(again.image(), expected)


def test_plan_refuses_what_the_cli_refuses(tmp_path):
    plan = rkwave.Plan(resolution=(W, H), spp=SPP)
    xy = plan.positions()
    with pytest.raises(rkwave.RkwaveError, match="samples given as the new round, but this plan "
                       "handed out"):
        plan.add(xy[1:], disc_scene(xy[1:]))  # a lost sample
    with pytest.raises(rkwave.RkwaveError, match="not the positions this plan handed out"):
        rounded = xy.astype(np.float32).astype(float)
        plan.add(rounded, disc_scene(rounded))  # positions rounded to float32 on the way
    with pytest.raises(rkwave.RkwaveError, match="no samples yet"):
        plan.image()
    plan.add(xy, disc_scene(xy))  # the refusals changed nothing
    assert plan.round == 1
    # add takes the new round alone: round 0 again is refused, naming the round expected
    with pytest.raises(rkwave.RkwaveError, match="positions of round 0, which this plan has "
                       "read already"):
        plan.add(xy, disc_scene(xy))
    assert plan.round == 1
    nxt = plan.positions()
    with pytest.raises(rkwave.RkwaveError, match="channels"):
        plan.add(nxt, disc_scene(nxt)[:, :2])
    with pytest.raises(rkwave.RkwaveError, match="budget="):
        rkwave.Plan(resolution=(W, H))
    with pytest.raises(rkwave.RkwaveError, match="not both"):
        rkwave.Plan(resolution=(W, H), spp=4, budget=100)
    with pytest.raises(rkwave.RkwaveError, match="solver=.*pcg"):
        rkwave.Plan(resolution=(W, H), spp=4, solver="cholesky")
    with pytest.raises(rkwave.RkwaveError, match="output_pixels=.*shrunk"):
        rkwave.Plan(resolution=(W, H), spp=4, output_pixels="gaussian")
    with pytest.raises(rkwave.RkwaveError, match="p = 1 to 4"):
        rkwave.Plan(resolution=(W, H), spp=4, p=6)
    with pytest.raises(rkwave.RkwaveError, match="no plan in"):
        rkwave.Plan.load(tmp_path / "nothing")
    with pytest.raises(rkwave.RkwaveError, match="budget"):
        rkwave.Plan(resolution=(W, H), budget=10)
    done = rkwave.Plan(resolution=(16, 16), spp=4)
    python_loop(done)
    with pytest.raises(rkwave.RkwaveError, match="stopped"):
        done.add(np.ones((1, 2)), np.ones(1))


def test_intermediate_image_warns():
    plan = rkwave.Plan(resolution=(W, H), spp=SPP)
    xy = plan.positions()
    plan.add(xy, disc_scene(xy))
    with pytest.warns(rkwave.RkwaveWarning, match="has not stopped"):
        image = plan.image(residual=False)
    assert image.shape == (H, W, 3)


def test_new_samples_move_between_cli_and_python(tmp_path, cli):
    """`rkwave plan --new-samples` and `Plan.add` are one protocol: a plan saved by Python goes
    on in the CLI given only each round's new samples (`save` writes `samples.bin`), and a
    plan the CLI drove that way is loaded with its kept samples; both give the image of the
    loop run in Python alone, bit for bit."""
    expected = image_of_python_loop()
    # Python -> CLI with --new-samples
    plan = saved_after_two_rounds(tmp_path / "a")
    nxt, k = plan.positions(), 0
    while len(nxt):
        np.save(tmp_path / f"new{k}.npy", np.c_[nxt, disc_scene(nxt)])
        cli("plan", "--state", tmp_path / "a", "--new-samples", tmp_path / f"new{k}.npy",
            "--out", tmp_path / f"n{k}.npy", "--final-image", tmp_path / "a.npy")
        nxt, k = np.load(tmp_path / f"n{k}.npy"), k + 1
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), expected)
    # CLI (--new-samples) -> Python: loaded with the samples the CLI kept
    run = tmp_path / "b"
    cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state", run, "--out",
        run / "n0.npy")
    for k in range(2):
        xy = np.load(run / f"n{k}.npy")
        np.save(run / f"new{k}.npy", np.c_[xy, disc_scene(xy)])
        cli("plan", "--state", run, "--new-samples", run / f"new{k}.npy", "--out",
            run / f"n{k + 1}.npy")
    loaded = rkwave.Plan.load(run, positions=run / "n2.npy")
    assert loaded.report["samples"] == len(np.load(run / "new0.npy")) + len(
        np.load(run / "new1.npy"))
    python_loop(loaded)
    np.testing.assert_array_equal(loaded.image(), expected)
