"""Rendering and caching the suite (`suite.py cache`): per scene, into `CACHE/SCENE/`:

* `ref-a.npy`, `ref-b.npy` -- Mitsuba's box film at `REF_SPP` spp (`REF_SPP_SCENE` for
  the scenes that need more), multijitter, seeds
  `REF_SEEDS` (two independent halves), float32 (H, W, 3); `ref.npy` their mean (float64).
  The noise floor: A against B. With e = A - B, each half's error against the truth has
  variance s^2 per value and the halves are independent, so E|A - B|^2 = 2 s^2 and the
  mean's error E|(A+B)/2 - truth|^2 = s^2 / 2 = E|A - B|^2 / 4: the mean's PSNR floor is
  PSNR(A, B) + 10 log10 4 = + 6.02 dB and its relMSE floor relMSE(A, B) / 4 (the relMSE
  weights 1 / (ref^2 + 0.01) taken as fixed).
* `film-FILTER-SPP.npy` -- `mi.render` with that film filter at SPP, seed `FILM_SEED`.
* `samples-SPP.npy` -- the harness's own uniform samples (`render.Renderer`, one sample at a
  time from Python): `m x 5` float64 (x, y, r, g, b), pixel units, x right, y down, the
  format `rkwave reconstruct --dim 2` reads, in row-major pixel order. Each pixel's
  multijitter sampler is seeded exactly as `mi.render(seed=FILM_SEED)` seeds it
  (`mitsuba_seeds.pixel_seeds`), so these are the very samples of Mitsuba's box film: the
  harness check (box of these samples against `film-box-SPP.npy`) is exact up to float32
  accumulation, and is printed.
* `aov-albedo.npy`, `aov-normal.npy` -- Mitsuba's `aov` integrator (albedo, shading normal
  of the first hit) at `AOV_SPP` spp, box film: the auxiliary images for OIDN.
* `meta.json` -- seeds, counts, times, the noise floor and the harness check.

**Sample counts.** Mitsuba's `multijitter` lays its samples on a `ceil(n / r) x r` grid
with `r = floor(sqrt(n))` and rounds n up to fill it: 4, 8 and 16 are exact, 32 becomes
35 (7 x 5). `mi.render(spp=32)` therefore renders 35 samples a pixel; the previous harness
drew 32 of those 35 strata per pixel (three strata empty in every pixel), which is why its
positions were 3.7 dB below Mitsuba's box film on `direct` at 32 spp. The suite renders
every budget at the sampler's own count (`rendered_spp`): the row named 32 spp holds 35
samples a pixel for every method (films, uniform samples, the plan's budget), stated in
`meta.json` and in every table.
"""

import json
import os
import time

import mitsuba as mi
import numpy as np

import metrics
import suite_scenes as ss
from mitsuba_seeds import pixel_seeds
from render import Renderer

REF_SPP = 1024
# Scenes whose 2 x 1024-spp reference was too noisy to resolve the rows (fireflies: A vs B at
# 26.2 dB on `glass`, below the 4-spp films' error): 4096 spp a half, +6 dB on the floor.
REF_SPP_SCENE = {"glass": 4096}
REF_SEEDS = (1001, 2002)
FILM_SEED = 1
SAMPLE_SEED = FILM_SEED  # the samples are those of Mitsuba's own film renders
AOV_SPP = 256
AOV_SEED = 3003


def rendered_spp(spp):
    """The sample count Mitsuba's multijitter actually uses when asked for `spp`."""
    s = mi.load_dict({"type": "multijitter", "sample_count": 4})
    s.set_sample_count(int(spp))
    return int(s.sample_count())


def floor_stats(a, b):
    """The noise floor of the reference (A + B) / 2 from its two halves."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    p = metrics.psnr(a, b)
    r = metrics.relmse(a, b)
    return {"psnr_a_vs_b": p, "relmse_a_vs_b": r,
            "psnr_floor_of_mean": p + 10 * np.log10(4.0), "relmse_floor_of_mean": r / 4.0}


class MitsubaSeededRenderer(Renderer):
    """`render.Renderer` whose per-pixel sampler seeds are those of scalar `mi.render`
    (`seeds[j, i]`), for `render_pixels`; `render_positions` (the plan) is unchanged."""

    def __init__(self, scene, seeds):
        super().__init__(scene)
        self.seeds = seeds
        self._pixel_seeding = False

    def render_pixels(self, counts, seed):
        self._pixel_seeding = True
        try:
            return super().render_pixels(counts, seed)
        finally:
            self._pixel_seeding = False

    def _seed(self, seed, pixel, n):
        if not self._pixel_seeding:
            return super()._seed(seed, pixel, n)
        self.sampler.set_sample_count(n)
        w = self.seeds.shape[1]
        self.sampler.seed(int(self.seeds[pixel // w, pixel % w]))


def _save(path, arr):
    np.save(path, arr)


def _film(name, w, h, f, spp, seed):
    scene = ss.load(name, w, h, f, spp)
    t0 = time.perf_counter()
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float32)
    return img, time.perf_counter() - t0


def cache_scene(name, root, w, h, spps, log=print):
    """Render (or reuse) everything of one scene; returns its meta dict."""
    d = os.path.join(root, name)
    os.makedirs(d, exist_ok=True)
    mpath = os.path.join(d, "meta.json")
    meta = json.load(open(mpath)) if os.path.exists(mpath) else {}
    ref_spp = REF_SPP_SCENE.get(name, REF_SPP)
    if meta.get("ref_spp", ref_spp) != ref_spp:  # the halves were rendered at another count
        for tag in "ab":
            if os.path.exists(os.path.join(d, f"ref-{tag}.npy")):
                os.remove(os.path.join(d, f"ref-{tag}.npy"))
    meta.update({"scene": name, "resolution": [w, h], "half": "tuning" if name in ss.TUNING else "validation",
                 "mitsuba": mi.__version__, "variant": mi.variant(), "ref_spp": ref_spp,
                 "ref_seeds": list(REF_SEEDS), "film_seed": FILM_SEED, "sample_seed": SAMPLE_SEED,
                 "aov_spp": AOV_SPP, "aov_seed": AOV_SEED})
    meta.setdefault("times", {})
    meta.setdefault("spp", {})
    halves = []
    for tag, seed in zip("ab", REF_SEEDS):
        p = os.path.join(d, f"ref-{tag}.npy")
        if not os.path.exists(p):
            img, dt = _film(name, w, h, "box", ref_spp, seed)
            _save(p, img)
            meta["times"][f"ref-{tag}"] = dt
            log(f"{name}: reference half {tag} ({ref_spp} spp, seed {seed}) {dt:.1f} s")
        halves.append(np.load(p).astype(np.float64))
    ref = 0.5 * (halves[0] + halves[1])
    _save(os.path.join(d, "ref.npy"), ref)
    meta["floor"] = floor_stats(*halves)
    f = meta["floor"]
    log(f"{name}: reference floor: A vs B {f['psnr_a_vs_b']:.2f} dB, relMSE {f['relmse_a_vs_b']:.3g}; "
        f"the mean's floor {f['psnr_floor_of_mean']:.2f} dB, relMSE {f['relmse_floor_of_mean']:.3g}")
    for key, aov in (("albedo", slice(0, 3)), ("normal", slice(3, 6))):
        p = os.path.join(d, f"aov-{key}.npy")
        if not os.path.exists(p):
            scene = mi.load_dict(ss.aov_dict(name, w, h, AOV_SPP))
            t0 = time.perf_counter()
            img = np.array(mi.render(scene, spp=AOV_SPP, seed=AOV_SEED), dtype=np.float32)
            meta["times"]["aov"] = time.perf_counter() - t0
            _save(os.path.join(d, "aov-albedo.npy"), img[..., 0:3])
            _save(os.path.join(d, "aov-normal.npy"), img[..., 3:6])
            break
    for spp in spps:
        n = rendered_spp(spp)
        entry = meta["spp"].setdefault(str(spp), {})
        entry["rendered_spp"] = n
        for f in ss.FILTERS:
            p = os.path.join(d, f"film-{f}-{spp}.npy")
            if not os.path.exists(p):
                img, dt = _film(name, w, h, f, spp, FILM_SEED)
                _save(p, img)
                entry[f"film_{f}_s"] = dt
        p = os.path.join(d, f"samples-{spp}.npy")
        if not os.path.exists(p):
            ren = MitsubaSeededRenderer(ss.load(name, w, h, "box", spp), pixel_seeds(w, h, SAMPLE_SEED))
            s = ren.render_pixels(np.full((h, w), n), SAMPLE_SEED)
            _save(p, s)
            entry["samples_render_s"] = ren.seconds
        s = np.load(p)
        box = metrics.box_film(s[:, 0], s[:, 1], s[:, 2:], w, h)
        film = np.load(os.path.join(d, f"film-box-{spp}.npy")).astype(np.float64)
        entry["samples"] = int(len(s))
        entry["check"] = {"harness_box_psnr": metrics.psnr(box, ref), "mitsuba_box_psnr": metrics.psnr(film, ref),
                          "harness_box_relmse": metrics.relmse(box, ref),
                          "mitsuba_box_relmse": metrics.relmse(film, ref)}
        c = entry["check"]
        c["gap_db"] = c["harness_box_psnr"] - c["mitsuba_box_psnr"]
        c["within_0.2_db"] = bool(abs(c["gap_db"]) <= 0.2)
        log(f"{name} {spp:3d} spp ({n} rendered): harness box {c['harness_box_psnr']:.2f} dB, "
            f"Mitsuba box {c['mitsuba_box_psnr']:.2f} dB, gap {c['gap_db']:+.2f} dB "
            f"{'OK' if c['within_0.2_db'] else 'OUTSIDE 0.2 dB'}")
    with open(mpath, "w") as fh:
        json.dump(meta, fh, indent=1)
    return meta


def write_fixtures(out, names, w, h, spps, command, log=print):
    """Small sample sets with their references for `cargo test` (as `harness.py --fixtures`):
    `{scene}-{w}x{h}-{spp}spp-samples.npy` (float32 m x 5, each position kept strictly inside
    its pixel after rounding to float32), `{scene}-{w}x{h}-reference.npy` (the mean of the two
    reference halves as a table of pixel centres: x + 1/2, y + 1/2, r, g, b, float64, row-major),
    and `fixtures.json` with the numpy box-film figures of the float32 samples."""
    os.makedirs(out, exist_ok=True)
    meta = {"mitsuba": mi.__version__, "variant": mi.variant(), "film_seed": FILM_SEED,
            "ref_spp": REF_SPP, "ref_seeds": list(REF_SEEDS), "resolution": [w, h], "command": command,
            "sets": []}
    for name in names:
        halves = [np.array(mi.render(ss.load(name, w, h, "box", REF_SPP), spp=REF_SPP, seed=sd), dtype=np.float64)
                  for sd in REF_SEEDS]
        ref = 0.5 * (halves[0] + halves[1])
        ys, xs = np.mgrid[0:h, 0:w]
        table = np.column_stack([xs.ravel() + 0.5, ys.ravel() + 0.5, ref.reshape(-1, 3)])
        ref_name = f"{name}-{w}x{h}-reference.npy"
        np.save(os.path.join(out, ref_name), table)
        for spp in spps:
            n = rendered_spp(spp)
            ren = MitsubaSeededRenderer(ss.load(name, w, h, "box", spp), pixel_seeds(w, h, FILM_SEED))
            s = ren.render_pixels(np.full((h, w), n), FILM_SEED)
            s32 = s.astype(np.float32)
            for c, size in ((0, w), (1, h)):
                cell = np.floor(s[:, c])
                lo = cell.astype(np.float32)
                hi = np.nextafter((cell + 1).astype(np.float32), np.float32(0))
                s32[:, c] = np.clip(s32[:, c], np.nextafter(lo, np.float32(size)), hi)
            base = f"{name}-{w}x{h}-{spp}spp"
            np.save(os.path.join(out, f"{base}-samples.npy"), s32)
            s64 = s32.astype(np.float64)
            box = metrics.box_film(s64[:, 0], s64[:, 1], s64[:, 2:], w, h)
            meta["sets"].append({"samples": f"{base}-samples.npy", "reference": ref_name, "scene": name,
                                 "half": "tuning" if name in ss.TUNING else "validation",
                                 "spp": spp, "rendered_spp": n, "samples_count": int(len(s32)),
                                 "box_psnr_numpy": metrics.psnr(box, ref),
                                 "box_relmse_numpy": metrics.relmse(box, ref),
                                 "sample_min": float(s64[:, 2:].min()), "sample_max": float(s64[:, 2:].max()),
                                 "floor": floor_stats(*halves)})
            log(f"fixture {base}: box PSNR {meta['sets'][-1]['box_psnr_numpy']:.3f} dB, "
                f"relMSE {meta['sets'][-1]['box_relmse_numpy']:.4g}")
    with open(os.path.join(out, "fixtures.json"), "w") as fh:
        json.dump(meta, fh, indent=2)
