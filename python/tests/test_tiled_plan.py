"""rkwave.Plan(tile=..., halo=...): the plan on tiles in process, the job `rkwave plan --tile`
drives, with its refusals (a bad grid names the keyword, samples that are not the positions
handed out are refused and leave the plan as it was), its state saved and read back, and the
command line's positions and final image bit for bit."""

import json

import numpy as np
import pytest

import rkwave
from conftest import disc_scene

W, H, SPP, TILE = 64, 48, 4, 16


def run_to_stop(plan, limit=100):
    """Renders every round's positions with disc_scene until the plan stops; returns the
    positions of every round."""
    rounds = []
    for _ in range(limit):
        if plan.done:
            break
        xy = plan.positions()
        rounds.append(xy)
        plan.add(xy, disc_scene(xy))
    assert plan.done, "the tiled plan did not stop"
    return rounds


def test_tiled_plan_runs_to_its_stop_within_the_budget():
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE)
    rounds = run_to_stop(plan)
    everything = np.concatenate(rounds)
    assert len(everything) <= SPP * W * H
    assert (everything[:, 0] >= 0).all() and (everything[:, 0] <= W).all()
    assert (everything[:, 1] >= 0).all() and (everything[:, 1] <= H).all()
    report = plan.report
    assert report["tiles"] == [TILE, 0]
    assert report["done"] and report["stop"] is not None
    assert len(report["steps"]) == len(rounds)
    image = plan.image()
    assert image.shape == (H, W, 3) and np.isfinite(image).all()
    # the green channel is the ramp 0.02 x, whose box pixels are exactly 0.02 (x + 1/2): the
    # tiles' fits reproduce it across their seams up to 0.01 (the untiled plan's own largest
    # error on this scene is 0.009, from the solver's tolerance and the output's correction)
    ramp = 0.02 * (np.arange(W) + 0.5)
    assert np.abs(image[:, :, 1] - ramp[None, :]).max() < 0.01
    assert "tile=16" in repr(plan)


@pytest.mark.parametrize(
    "kwargs, keyword",
    [
        (dict(tile=0), "tile="),
        (dict(tile=W + 1), "tile="),
        (dict(tile=TILE, halo=TILE + 1), "halo="),
        (dict(halo=4), "halo="),
    ],
)
def test_a_bad_grid_is_refused_naming_the_keyword(kwargs, keyword):
    with pytest.raises(ValueError, match=keyword):
        rkwave.Plan(resolution=(W, H), spp=SPP, **kwargs)


def test_a_forged_round_is_refused_and_the_plan_is_unchanged():
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE)
    xy = plan.positions()
    forged = xy.copy()
    forged[0, 0] = min(forged[0, 0] + 0.25, W)
    with pytest.raises(rkwave.RkwaveError, match="positions"):
        plan.add(forged, disc_scene(forged))
    assert plan.round == 0 and plan.samples is None
    np.testing.assert_array_equal(plan.positions(), xy)
    # the true round is then taken
    plan.add(xy, disc_scene(xy))
    assert plan.round == 1
    with pytest.raises(ValueError, match="drop_nonfinite"):
        nxt = plan.positions()
        plan.add(nxt, disc_scene(nxt), drop_nonfinite=True)


def test_a_saved_tiled_plan_continues_bit_for_bit(tmp_path):
    with pytest.warns(rkwave.RkwaveWarning, match="grown to a power of two"):
        a = rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE, halo=4)
    for _ in range(2):
        xy = a.positions()
        a.add(xy, disc_scene(xy))
    a.save(tmp_path)
    assert (tmp_path / "tiled-state.json").exists()
    b = rkwave.Plan.load(tmp_path)
    assert b.report["tiles"] == [TILE, 4] and b.round == a.round
    np.testing.assert_array_equal(b.positions(), a.positions())
    xy = a.positions()
    a.add(xy, disc_scene(xy))
    b.add(xy, disc_scene(xy))
    np.testing.assert_array_equal(a.positions(), b.positions())


def test_the_command_line_gives_the_same_positions_and_image(cli, tmp_path):
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE)
    rounds = run_to_stop(plan)
    run = tmp_path / "run"
    cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--tile", TILE, "--state", run,
        "--out", run / "n0.npy")
    everything = None
    for k, xy in enumerate(rounds):
        np.testing.assert_array_equal(np.load(run / f"n{k}.npy"), xy, err_msg=f"round {k}")
        rendered = np.c_[xy, disc_scene(xy)]
        everything = rendered if everything is None else np.r_[everything, rendered]
        np.save(run / f"s{k}.npy", everything)
        report = json.loads(
            cli("plan", "--state", run, "--samples", run / f"s{k}.npy", "--out",
                run / f"n{k + 1}.npy", "--final-image", run / "final.npy", "--json")[1]
        )
    assert report["stop"] is not None
    np.testing.assert_array_equal(np.load(run / "final.npy"), plan.image())
