"""``rkwave.dask.TiledPlan``: the tiled plan's rounds as Dask tasks, one per band of tile rows
(the class docs; the design in docs/distributed.md). Imported by ``rkwave.dask``, whose
helpers it uses."""

import hashlib
import operator
import warnings

import dask
import numpy as np

from rkwave import _rkwave
from rkwave.dask import _client, _compute, _keep_heap


def _band_samples(held, new):
    """Task: a band's samples so far on its worker, planar ``(2 + C, m)``: the columns it
    held since the last round (``None``: none) followed by the round's new ones."""
    if held is None:
        return new
    return np.concatenate([held, new], axis=1)


def _band_prefix(samples, m):
    """Task: the first ``m`` columns of a band's planar samples (an earlier round's, for a
    replay: a band's samples grow only at their end)."""
    return samples[:, :m]


def _prefix_digest(samples, m):
    """A digest of the first ``m`` columns of a planar band array (row by row, each row's
    prefix contiguous): what a worker holds is checked against the client's copy with it."""
    h = hashlib.blake2b(digest_size=16)
    h.update(np.int64(m).tobytes())
    for row in samples:
        h.update(np.ascontiguousarray(row[:m]).data)
    return h.digest()


def _plan_band_task(task, held, samples, before_band, keep_heap):
    """Task: one band's step of a round (``_rkwave.tiled_plan_band``): its outcome as bytes
    and the band's new held states (``_rkwave.HeldBand``)."""
    if keep_heap:
        _keep_heap()
    if before_band is not None:
        before_band(task)
    return _rkwave.tiled_plan_band(task, held, samples)


def _plan_final_task(task, held, samples, before_band, keep_heap):
    """Task: one band's part of the final image, ``(r0, r1, y0, y1, pixels)``."""
    if keep_heap:
        _keep_heap()
    if before_band is not None:
        before_band(task)
    return _rkwave.tiled_plan_final_band(task, held, samples)


#: Futures of these states hold their data (else a band's held states are replayed).
_LIVE = ("finished",)


class TiledPlan:
    """The adaptive plan on tiles with its rounds as Dask tasks, one per band of tile rows.

    ``resolution``, ``spp``/``budget``, ``tile``, ``halo`` and the other keywords (``p``,
    ``rho``, ``below_pixel``, ``seed``, ``false_alarm``, ``solver``, ``output_pixels``) are
    ``rkwave.Plan``'s, with the same defaults and refusals; the positions handed out and the
    final image are those of ``rkwave.Plan(tile=, halo=)`` bit for bit (the same per-tile
    steps on the same samples, committed in the same order).

    A round (``add``): the client checks the samples (they must be the positions handed
    out, finite, of one channel count; else refused, the plan unchanged), computes each
    tile's share of the round's growth from the tiles' last indicators, and submits one task
    per band of ``rows_per_task`` tile rows holding a tile with a share: the stepped tiles'
    records, their shares, the digest of the band's held states, and the samples in the
    band's windows (each task steps its tiles in turn, ``threads`` at once). The bands' new
    positions and tile records are committed together once every band has returned; a
    failed task is rerun (``retries``; a task is a pure function of its inputs, so the rerun
    gives the same outcome), and a round whose tasks fail for good leaves the plan as it was
    (the round can be added again). ``image()`` fits every tile in band tasks the same way
    and stitches the interiors.

    **What stays on the workers.** A band's tiles' whole states (refinement history, PCG's
    start: ``_rkwave.HeldBand``) stay where the band's task made them, as a future; the
    client keeps each tile's record (index, parameters, last indicator, stop, steps) and each
    band's digest, and a task's outcome brings back the records, the next positions and the
    new states' digest. A band's samples stay too: they are every sample in one of its tiles'
    windows in the order handed out, so the next round's are this round's followed by the
    new ones, and only those new columns are sent (checked: the held columns' digest must be
    the client's copy's, else the band is sent whole).

    **A lost worker.** Held data lost with its worker is rebuilt from the client: a band's
    samples are sent whole again from the client's copy (``bands_resent``), and a band's
    states are **replayed** (``bands_replayed``): from the band's initial states (the
    records with their history reset) through the band's task of every round that stepped
    it, each on that round's prefix of the band's samples. For this the client keeps, per
    band and round, the task's bytes and the band's sample count: a few hundred bytes a tile
    and round (``report["replay_kb"]``). Each replayed task checks the states it steps by
    their digest, so the replay gives the same bits or is refused. (Dask's scheduler may
    also recompute a lost future from the tasks that made it: the same bits.) A round whose
    tasks fail where held data was used is run once more with every band's samples sent
    whole and its states replayed where their future is gone.

    ``client``: a ``distributed.Client`` (default: the current one, else dask's local
    threaded scheduler, where the held states are the objects themselves).
    ``before_band(task_bytes)``, if given, runs at the start of every band's task (a hook
    for progress or fault injection; it must be picklable). ``keep_heap``: as
    :func:`reconstruct_image_tiles` (each worker's allocator keeps freed memory, as the
    command line's does).
    """

    def __init__(
        self,
        resolution,
        spp=None,
        budget=None,
        *,
        tile,
        halo=None,
        client=None,
        rows_per_task=1,
        threads=1,
        retries=3,
        before_band=None,
        keep_heap=True,
        **plan,
    ):
        self._core = _rkwave.TiledPlanRounds(
            tuple(resolution),
            spp,
            budget,
            tile=tile,
            halo=halo,
            rows_per_task=rows_per_task,
            threads=threads,
            **plan,
        )
        self._client = client
        self._retries = retries
        self._before = before_band
        self._keep_heap = keep_heap
        self._tasks_run = 0
        # band rows -> (future of its samples on a worker, their columns, their digest)
        self._held = {}
        # band rows -> future (threaded scheduler: the object) of its HeldBand
        self._states = {}
        # band rows -> [(task bytes, the band's sample count)] per round that stepped it
        self._replay = {}
        self._sent_bytes = 0
        self._task_bytes = 0
        self._outcome_bytes = 0
        self._resent = 0
        self._replayed = 0

    # -- a band's held data ----------------------------------------------------------------

    def _band_data(self, client, rows, samples):
        """The future of band ``rows``' samples on a worker: the held columns extended by the
        new ones, or (nothing held, the holder lost, or the held columns not the client's)
        the whole band. Returns ``(future, whether held columns were used)``."""
        m = samples.shape[1]
        held = self._held.get(rows)
        if held is not None:
            future, n, digest = held
            if future.status in _LIVE and n <= m and _prefix_digest(samples, n) == digest:
                if n == m:
                    return future, True
                new = np.ascontiguousarray(samples[:, n:])
                self._sent_bytes += new.nbytes
                data = client.submit(_band_samples, future, new, pure=False)
                self._held[rows] = (data, m, _prefix_digest(samples, m))
                return data, True
            if future.status not in _LIVE:
                self._resent += 1
        self._sent_bytes += samples.nbytes
        data = client.submit(_band_samples, None, samples, pure=False)
        self._held[rows] = (data, m, _prefix_digest(samples, m))
        return data, False

    def _band_states(self, client, rows, data):
        """Band ``rows``' held states for a task on ``data`` (its samples' future): the
        future of the last round's, else (never stepped) the client's own, else (lost) a
        replay (class docs). Returns ``(states, whether a held future was used)``."""
        future = self._states.get(rows)
        if future is not None and future.status in _LIVE:
            return future, True
        if rows not in self._replay:
            return self._core.held_band(rows), False
        self._replayed += 1
        states = self._core.initial_band(rows)
        for task, m in self._replay[rows]:
            prefix = client.submit(_band_prefix, data, m, pure=False)
            step = client.submit(
                _plan_band_task, task, states, prefix, self._before, self._keep_heap,
                pure=False, retries=self._retries,
            )
            states = client.submit(operator.getitem, step, 1, pure=False)
            self._tasks_run += 1
        return states, False

    def _run_held(self, client, fn, tasks, final):
        """The band tasks on the data their workers hold (class docs); a failure where held
        data was used runs the round again with every band's samples sent whole and its
        states replayed where their future is gone; a second failure is raised. Returns
        ``(outcome, states future)`` per band (``final``: the strips)."""
        for attempt in (0, 1):
            if attempt:
                self._resent += len(self._held)
                self._held.clear()
                self._states = {
                    r: f for r, f in self._states.items() if f.status in _LIVE
                }
            outs, states, used = [], [], False
            for t, s, rows in tasks:
                rows = tuple(rows)
                data, held = self._band_data(client, rows, s)
                band, kept = self._band_states(client, rows, data)
                used |= held or kept
                step = client.submit(
                    fn, t, band, data, self._before, self._keep_heap, pure=False,
                    retries=self._retries,
                )
                self._task_bytes += len(t)
                if final:
                    outs.append(step)
                else:
                    outs.append(client.submit(operator.getitem, step, 0, pure=False))
                    states.append(client.submit(operator.getitem, step, 1, pure=False))
            self._tasks_run += len(outs)
            try:
                got = client.gather(outs)
            except Exception:
                if attempt or not used:
                    raise
                continue
            return got if final else list(zip(got, states))

    def _run(self, fn, tasks, final=False):
        client = _client(self._client)
        if client is not None:
            with warnings.catch_warnings():
                # a band sent whole travels in its task on purpose: the scheduler then holds
                # it and can rerun the task after its worker was lost
                warnings.filterwarnings("ignore", message="Large object", category=UserWarning)
                warnings.filterwarnings(
                    "ignore", message="Sending large graph", category=UserWarning
                )
                return self._run_held(client, fn, tasks, final)
        graph = []
        for t, s, rows in tasks:
            rows = tuple(rows)
            band = self._states.get(rows)
            if band is None:
                band = self._core.held_band(rows)
            graph.append(
                dask.delayed(fn, pure=False)(t, band, s, self._before, self._keep_heap)
            )
            self._task_bytes += len(t)
        self._tasks_run += len(graph)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)
            got = _compute(graph, None, self._retries)
        return got if final else [(out, band) for out, band in got]

    # -- the plan --------------------------------------------------------------------------

    def positions(self):
        """The positions to render next, ``(n, 2)`` (``(0, 2)`` once done)."""
        return self._core.positions()

    def add(self, xy, values):
        """Adds the rendered samples of the positions handed out and plans the next round
        (class docs): committed as one step, or refused with the plan unchanged."""
        pending, tasks = self._core.begin(xy, values)
        if pending is None:
            return
        results = self._run(_plan_band_task, tasks)
        outcomes = [out for out, _ in results]
        self._outcome_bytes += sum(map(len, outcomes))
        self._core.commit(pending, outcomes)
        # committed: the bands' new states are the held ones, and their tasks the replay's
        for (t, s, rows), (_, band) in zip(tasks, results):
            rows = tuple(rows)
            self._states[rows] = band
            self._replay.setdefault(rows, []).append((t, s.shape[1]))

    def image(self, residual=True):
        """The image ``(H, W, C)``: every tile's fit in band tasks, the interiors stitched
        (``residual=False``: the fit's box pixels alone), as ``rkwave.Plan(tile=).image``."""
        strips = self._run(_plan_final_task, self._core.final_tasks(residual), final=True)
        return self._core.stitch(list(strips))

    @property
    def done(self):
        """Whether the plan has stopped."""
        return self._core.done

    @property
    def round(self):
        """The last round whose positions were handed out (0: the base positions)."""
        return self._core.round

    @property
    def report(self):
        """Where the plan stands (as ``rkwave.Plan.report``), the bands' layout, the tasks
        run so far (``tasks_run``), what travelled (MB): the band samples sent to workers
        (``samples_sent_mb``), the tasks' bytes (``tasks_mb``: records, shares, digests) and
        the outcomes' (``outcomes_mb``: records, next positions, digests); the bands whose
        held samples were sent whole again (``bands_resent``) or whose held states were
        replayed (``bands_replayed``), and the client's replay records (``replay_kb``)."""
        r = self._core.report
        r["tasks_run"] = self._tasks_run
        r["samples_sent_mb"] = self._sent_bytes / 1e6
        r["tasks_mb"] = self._task_bytes / 1e6
        r["outcomes_mb"] = self._outcome_bytes / 1e6
        r["bands_resent"] = self._resent
        r["bands_replayed"] = self._replayed
        r["replay_kb"] = sum(len(t) + 8 for v in self._replay.values() for t, _ in v) / 1e3
        return r

    def state_json(self):
        """The plan's state as ``rkwave plan --tile --state`` writes it: the held bands'
        whole states gathered from their workers and spliced in."""
        client = _client(self._client)
        held = [self._states[tuple(r)] for r in self._core.held_bands]
        if client is not None and held:
            held = client.gather(held)
        return self._core.state_json(held)
