"""rkwave.dask.TiledPlan on a LocalCluster of two worker processes (one thread each): the
tiled plan's rounds as one task per band of tile rows give the positions and the final image
of the local `rkwave.Plan(tile=)` bit for bit; a band's task that fails once (injected) or
whose worker is killed is rerun with the identical result; a worker lost between rounds
costs a resend of the bands' samples it held, not the bits; a round with a bad value count,
or whose tasks fail for good, is refused with the plan unchanged. Skipped without Dask."""

import os
import sys

import numpy as np
import pytest

import rkwave
from conftest import disc_scene

W, H, SPP, TILE = 48, 40, 4, 16

# halo 4 grows the windows to 32 pixels, which the plan says in a warning each time
pytestmark = pytest.mark.filterwarnings("ignore:windows of 32x32")


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


def run(plan, limit=100):
    """Renders every round with disc_scene until the plan stops; every round's positions and
    the final image."""
    rounds = []
    for _ in range(limit):
        if plan.done:
            break
        xy = plan.positions()
        rounds.append(xy)
        plan.add(xy, disc_scene(xy))
    assert plan.done, "the plan did not stop"
    return rounds, plan.image()


@pytest.fixture(scope="module")
def local():
    """The local tiled plan's rounds and image (halo 4: windows of 32 overlapping)."""
    return run(rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE, halo=4))


def assert_same_run(a, b):
    (ra, ia), (rb, ib) = a, b
    assert len(ra) == len(rb)
    for k, (x, y) in enumerate(zip(ra, rb)):
        # bit for bit: the same per-tile steps on the same samples (no tolerance)
        np.testing.assert_array_equal(x, y, err_msg=f"round {k}")
    np.testing.assert_array_equal(ia, ib)


@pytest.mark.parametrize("rows_per_task", [1, 2])
def test_dask_rounds_give_the_local_tiled_plan_bit_for_bit(rd, client, local, rows_per_task):
    plan = rd.TiledPlan(
        (W, H), spp=SPP, tile=TILE, halo=4, client=client, rows_per_task=rows_per_task
    )
    got = run(plan)
    assert_same_run(local, got)
    report = plan.report
    assert report["done"] and report["tiles"] == [TILE, 4]
    grid_rows = -(-H // TILE)
    assert report["tasks_per_round"] == -(-grid_rows // rows_per_task)
    assert report["tasks_run"] > len(got[0])


def test_the_threaded_scheduler_without_a_client_gives_the_same_bits(rd, local):
    assert_same_run(local, run(rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=None)))


class FailOnce:
    """Raises in the first band task that reaches it, once (the marker file says it did)."""

    def __init__(self, marker, kill=False):
        self.marker, self.kill = str(marker), kill

    def __call__(self, task):
        if not os.path.exists(self.marker):
            with open(self.marker, "w") as f:
                f.write("failed")
            if self.kill:
                os._exit(1)
            raise RuntimeError("injected band failure")


@pytest.mark.parametrize("kill", [False, True], ids=["raises", "worker_killed"])
def test_a_failed_band_task_is_rerun_with_the_identical_result(
    rd, client, local, tmp_path, kill
):
    marker = tmp_path / "failed"
    plan = rd.TiledPlan(
        (W, H), spp=SPP, tile=TILE, halo=4, client=client, retries=2,
        before_band=FailOnce(marker, kill),
    )
    got = run(plan)
    assert marker.exists(), "the hook never ran: nothing failed"
    assert_same_run(local, got)


def test_a_worker_lost_between_rounds_costs_a_resend_not_the_bits(rd, client, local):
    """Each band's samples stay on a worker between rounds; a worker restarted between two
    rounds loses the bands it held, which come back with the same bits."""
    plan = rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=client)
    rounds = []
    for _ in range(2):
        xy = plan.positions()
        rounds.append(xy)
        plan.add(xy, disc_scene(xy))
    assert not plan.done, "the plan stopped before a worker could be lost between rounds"
    sent = plan.report["samples_sent_mb"]
    held = [f for f, _, _ in plan._held.values()]
    holders = {w for ws in client.who_has(held).values() for w in ws}
    assert holders, "no band's samples are held on a worker"
    client.restart_workers([sorted(holders)[0]])
    more, image = run(plan)
    assert_same_run(local, (rounds + more, image))
    # the lost bands came back either recomputed by the scheduler from what it was sent
    # (their tasks' inputs) or sent whole again (`bands_resent`): the same bits either way
    assert plan.report["samples_sent_mb"] > sent


class AlwaysFail:
    def __call__(self, task):
        raise RuntimeError("injected band failure")


def test_a_round_is_committed_whole_or_not_at_all(rd, client, local):
    plan = rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=client, retries=0)
    xy = plan.positions()
    plan.add(xy, disc_scene(xy))
    nxt = plan.positions()
    before = (plan.round, plan.state_json())
    # a bad value count: refused on the client, before any task
    with pytest.raises(ValueError, match="values"):
        plan.add(nxt, disc_scene(nxt)[:-1])
    assert (plan.round, plan.state_json()) == before
    # samples that are not the positions handed out
    forged = nxt.copy()
    forged[0, 0] = min(forged[0, 0] + 0.25, W)
    with pytest.raises(rkwave.RkwaveError, match="positions"):
        plan.add(forged, disc_scene(forged))
    assert (plan.round, plan.state_json()) == before
    # every band's task failing for good: nothing committed
    plan._before = AlwaysFail()
    with pytest.raises(RuntimeError, match="injected"):
        plan.add(nxt, disc_scene(nxt))
    assert (plan.round, plan.state_json()) == before
    np.testing.assert_array_equal(plan.positions(), nxt)
    # the same round then goes through, and the run ends as the local one
    plan._before = None
    plan.add(nxt, disc_scene(nxt))
    rounds, image = run(plan)
    assert_same_run(local, ([xy, nxt] + rounds, image))


def test_bad_arguments_are_refused_naming_the_keyword(rd):
    with pytest.raises(ValueError, match="tile="):
        rd.TiledPlan((W, H), spp=SPP, tile=0)
    with pytest.raises(ValueError, match="rows_per_task"):
        rd.TiledPlan((W, H), spp=SPP, tile=TILE, rows_per_task=0)
