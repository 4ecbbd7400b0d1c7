"""Non-finite radiance (issue 28, item 3): NaN or Inf values are refused with the count and
the first sample, or dropped with drop_nonfinite=True and counted; a refused Plan.add leaves
the plan as it was, so the same round can be added again."""

import warnings

import numpy as np
import pytest

import rkwave
from conftest import disc_scene

W, H = 32, 24


def test_reconstruct_image_refuses_then_drops():
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 1, (4 * W * H, 2)) * [W, H]
    values = disc_scene(xy)
    values[[3, 50], 1] = [np.nan, np.inf]
    with pytest.raises(ValueError, match=r"2 samples.*row 4.*drop_nonfinite=True"):
        rkwave.reconstruct_image(xy, values, resolution=(W, H))
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        img, rep = rkwave.reconstruct_image(
            xy, values, resolution=(W, H), drop_nonfinite=True, pixels="fit"
        )
    assert rep["nonfinite"]["count"] == 2 and rep["samples"] == len(xy) - 2
    keep = np.ones(len(xy), bool)
    keep[[3, 50]] = False
    expected, _ = rkwave.reconstruct_image(xy[keep], values[keep], resolution=(W, H), pixels="fit")
    assert np.array_equal(img, expected)


def test_plan_add_refused_round_can_be_added_again():
    plan = rkwave.Plan(resolution=(W, H), spp=4)
    xy = plan.positions()
    values = disc_scene(xy)
    values[7, 0] = np.nan
    before = plan.report
    with pytest.raises(ValueError, match=r"1 samples.*row 8"):
        plan.add(xy, values)
    assert plan.report == before and plan.round == 0
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        plan.add(xy, values, drop_nonfinite=True)
    assert any("non-finite" in str(w.message) for w in seen)
    assert plan.report["steps"][-1]["dropped"]["count"] == 1
    while not plan.done:
        xy = plan.positions()
        plan.add(xy, disc_scene(xy))
    image = plan.image()
    assert np.isfinite(image).all()
