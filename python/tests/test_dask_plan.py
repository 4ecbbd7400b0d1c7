"""rkwave.dask.TiledPlan on a LocalCluster of two worker processes (one thread each): the
tiled plan's rounds as one task per band of tile rows give the positions and the final image
of the local `rkwave.Plan(tile=)` bit for bit; a band's task that fails once (injected) or
whose worker is killed is rerun with the identical result; a worker lost between rounds
costs a resend of the bands' samples and a replay of the bands' states it held, not the
bits; the tiles' whole states held on the workers are the local plan's; a band's task
refuses held states of another band or round, and the commit an outcome missing, repeated
or stepped from other states; a round with a bad value count, or whose tasks fail for good,
is refused with the plan unchanged. Skipped without Dask."""

import json

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


def two_rounds(plan):
    """The plan's first two rounds rendered with disc_scene; their positions."""
    rounds = []
    for _ in range(2):
        xy = plan.positions()
        rounds.append(xy)
        plan.add(xy, disc_scene(xy))
    assert not plan.done, "the plan stopped before its held data could be lost"
    return rounds


def test_a_worker_lost_between_rounds_costs_a_resend_not_the_bits(rd, client, local):
    """Each band's samples and tiles' states stay on a worker between rounds; a worker
    restarted between two rounds loses the bands it held, which come back with the same
    bits."""
    plan = rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=client)
    rounds = two_rounds(plan)
    held = [f for f, _, _ in plan._held.values()] + list(plan._states.values())
    holders = {w for ws in client.who_has(held).values() for w in ws}
    assert holders, "no band's samples or states are held on a worker"
    client.restart_workers([sorted(holders)[0]])
    more, image = run(plan)
    assert_same_run(local, (rounds + more, image))
    # the lost bands came back recomputed by the scheduler from the tasks that made them,
    # or sent whole again (`bands_resent`) and replayed (`bands_replayed`): the same bits
    assert plan.report["bands_held"] == -(-H // TILE)


def test_lost_held_states_are_replayed_from_the_clients_records(rd, client, local):
    """Every band's held states dropped between rounds (their futures cancelled): each band is
    replayed from its initial states through its recorded tasks, and the run is the local
    plan's bit for bit."""
    plan = rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=client)
    rounds = two_rounds(plan)
    bands = len(plan._states)
    client.cancel(list(plan._states.values()))
    more, image = run(plan)
    assert_same_run(local, (rounds + more, image))
    report = plan.report
    assert report["bands_replayed"] == bands
    # the records a replay needs: one task's bytes a band and round, small beside a state
    assert 0 < report["replay_kb"] < 64 * len(rounds + more) * bands


def test_the_held_states_are_the_local_plans_whole_states(rd, client, tmp_path):
    """After the same rounds the Dask plan's state, its held bands gathered and spliced into
    the client's records, is the local tiled plan's state file: every tile's history, PCG's
    start (as bits) and indicator."""
    local = rkwave.Plan(resolution=(W, H), spp=SPP, tile=TILE, halo=4)
    plan = rd.TiledPlan((W, H), spp=SPP, tile=TILE, halo=4, client=client)
    for _ in range(2):
        xy = plan.positions()
        np.testing.assert_array_equal(xy, local.positions())
        plan.add(xy, disc_scene(xy))
        local.add(xy, disc_scene(xy))
    local.save(tmp_path / "local")
    want = json.loads((tmp_path / "local" / "tiled-state.json").read_text())
    got = json.loads(plan.state_json())
    assert any(t["start"] is not None for t in got["tiles"]), "no tile carries a start yet"
    assert got["tiles"] == want["tiles"]
    assert got["issued"] == want["issued"]
    # the client alone holds the records: the whole state needs the held bands
    with pytest.raises(rkwave.RkwaveError, match="held"):
        plan._core.state_json([])


def test_held_states_of_another_band_or_round_and_foreign_outcomes_are_refused(rd):
    """The band tasks and the commit on the client's core, in this process: a task given
    another band's or an earlier round's held states is refused; the commit refuses an
    outcome missing, repeated or of another round, and leaves the plan unchanged."""
    from rkwave import _rkwave

    core = _rkwave.TiledPlanRounds((W, H), SPP, tile=TILE, halo=4, rows_per_task=1)
    xy = core.positions()
    pending, tasks = core.begin(xy, disc_scene(xy))
    first = {rows: core.held_band(rows) for _, _, rows in tasks}
    results = [
        _rkwave.tiled_plan_band(t, first[rows], s) for t, s, rows in tasks
    ]
    old = [out for out, _ in results]
    core.commit(pending, old)
    held = {rows: band for (_, _, rows), (_, band) in zip(tasks, results)}
    assert sorted(core.held_bands) == sorted(held)
    with pytest.raises(rkwave.RkwaveError, match="held by a worker"):
        core.held_band(tasks[0][2])
    nxt = core.positions()
    before = (core.round, core.state_json(list(held.values())))
    pending, tasks = core.begin(nxt, disc_scene(nxt))
    (t0, s0, r0), (t1, s1, r1) = tasks[0], tasks[1]
    # the first round's states of the band (an earlier round), another band's states
    for wrong in (first[r0], held[r1]):
        with pytest.raises(rkwave.RkwaveError, match="held states"):
            _rkwave.tiled_plan_band(t0, wrong, s0)
    outs = [_rkwave.tiled_plan_band(t, held[rows], s)[0] for t, s, rows in tasks]
    for bad in ([], outs[:-1], outs + outs[:1], old, [old[0]] + outs[1:]):
        with pytest.raises(rkwave.RkwaveError):
            core.commit(pending, bad)
        assert (core.round, core.state_json(list(held.values()))) == before
    # the same outcomes, run again from the same held states, are the same bytes
    assert _rkwave.tiled_plan_band(t0, held[r0], s0)[0] == outs[0]
    core.commit(pending, outs)
    assert core.round == before[0] + 1


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
