"""`suite.py table`: every row of the suite per (scene, spp), both measures, times.

Rows (all against the mean of the two 1024-spp reference halves):

* `mitsuba FILTER` -- Mitsuba's five films (cached, `mi.render`, seed 1); `render_s` is
  `mi.render`'s time (multithreaded C++).
* `box of the same samples` -- the per-pixel mean of the cached uniform samples (equal to
  Mitsuba's box film: they are its samples); `render_s` is the harness's Python renderer's
  time for them (one sample at a time, not comparable to `mi.render`).
* `rkwave uniform` -- `rkwave reconstruct --dim 2` (default pixels) on those samples.
* `rkwave plan` -- the `rkwave plan` loop, final image (`--final-image`); skipped at the spp
  in `--no-plan-spp`.
* `OIDN box` / `OIDN box +aux` -- OIDN on Mitsuba's box film, colour only / with the `aov`
  albedo and normal; `tool_s` is OIDN's time.
* `plan samples mean` -- the per-pixel mean of the plan's samples (empty pixels filled from
  the nearest window, counted), and `OIDN plan mean` / `OIDN plan mean +aux` on it: against
  `OIDN box` at equal sample count.
"""

import json
import os
import sys
import time

import numpy as np

import metrics
import oidn
from rkwave_cli import Rkwave
from suite_score import _gmean, compare, films, load, range_check, reconstruct, row, run_plan

KEY = ["box of the same samples", "best film", "rkwave uniform", "rkwave plan", "OIDN box", "OIDN box +aux",
       "OIDN plan mean", "OIDN plan mean +aux"]


def scene_rows(args, name, spp, w, h, rk):
    data = load(args.cache, name, spp)
    rows, best = films(name, spp, data)
    s = data["samples"]
    t = data["meta"]["spp"][str(spp)]
    box = metrics.box_film(s[:, 0], s[:, 1], s[:, 2:], w, h)
    mean = row(name, spp, data, "box of the same samples", box, render_s=t.get("samples_render_s", float("nan")))
    rows.append(mean)
    path = os.path.join(args.cache, name, f"samples-{spp}.npy")
    img, dt, rep = reconstruct(args.rkwave, path, w, h, os.path.join(args.workdir, f"{name}-{spp}-u.npy"), "")
    u = row(name, spp, data, "rkwave uniform", img, render_s=mean["render_s"], tool_s=dt,
            estimate=(rep.get("pixels") or {}).get("estimate"), notes=rep.get("notes"))
    u["range"] = range_check(img, s, w, h)
    rows.append(compare(u, mean, best))
    film_box = data["films"]["box"]
    for label, aux in (("OIDN box", False), ("OIDN box +aux", True)):
        img, dt = oidn.denoise(film_box, data["albedo"] if aux else None, data["normal"] if aux else None)
        rows.append(row(name, spp, data, label, img, render_s=t.get("film_box_s", float("nan")), tool_s=dt))
    if spp not in args.no_plan_spp:
        img, s_all, rs, dt, rounds = run_plan(args, name, spp, data, w, h, rk)
        pm, _, filled, rad = oidn.pixel_mean(s_all, w, h)
        pmean = row(name, spp, data, "plan samples mean", pm, render_s=rs, samples=len(s_all),
                    empty_pixels=filled, fill_radius=rad)
        p = row(name, spp, data, "rkwave plan", img, render_s=rs, tool_s=dt, samples=len(s_all), rounds=rounds,
                empty_pixels=filled)
        p["range"] = range_check(img, s_all, w, h)
        rows.append(compare(p, pmean, best))
        rows.append(pmean)
        for label, aux in (("OIDN plan mean", False), ("OIDN plan mean +aux", True)):
            img, dt2 = oidn.denoise(pm, data["albedo"] if aux else None, data["normal"] if aux else None)
            rows.append(row(name, spp, data, label, img, render_s=rs, tool_s=dt2, samples=len(s_all)))
    return rows, best


def _cell(r, key):
    return "—" if r is None else (f"{r[key]:.2f}" if key == "psnr" else f"{r[key]:.3g}") + ("†" if r["near_floor"] else "")


def summary(rows, key):
    """Per half: one line per (scene, spp) with the KEY methods, then the means."""
    out = []
    for half in ("tuning", "validation"):
        sel = [r for r in rows if r["half"] == half]
        if not sel:
            continue
        cases = []
        for r in sel:
            if (r["scene"], r["spp"]) not in cases:
                cases.append((r["scene"], r["spp"]))
        unit = "PSNR (dB, clipped)" if key == "psnr" else "relMSE (HDR)"
        out.append(f"\n{unit}, {half} half\n")
        out.append("| scene | spp | " + " | ".join(KEY) + " | uniform − mean | plan − best film | OIDN plan − OIDN box |")
        out.append("|---" * (len(KEY) + 5) + "|")
        cols = {k: [] for k in KEY + ["d1", "d2", "d3"]}
        for scene, spp in cases:
            get = {r["method"]: r for r in sel if (r["scene"], r["spp"]) == (scene, spp)}
            get["best film"] = max((r for m, r in get.items() if m.startswith("mitsuba ")), key=lambda r: r["psnr"])
            cells = []
            for k in KEY:
                r = get.get(k)
                cells.append(_cell(r, key) + (f" ({r['method'].split()[-1]})" if k == "best film" else ""))
                if r is not None:
                    cols[k].append(r[key])
            diffs = []
            for tag, (a, b) in zip(("d1", "d2", "d3"), (("rkwave uniform", "box of the same samples"),
                                                        ("rkwave plan", "best film"), ("OIDN plan mean", "OIDN box"))):
                if a in get and b in get:
                    v = get[a][key] - get[b][key] if key == "psnr" else get[a][key] / get[b][key]
                    cols[tag].append(v)
                    diffs.append(f"{v:+.2f}" if key == "psnr" else f"×{v:.3g}")
                else:
                    diffs.append("—")
            rs = f"{spp}" + ("" if get["rkwave uniform"]["rendered_spp"] == spp else f" ({get['rkwave uniform']['rendered_spp']})")
            out.append(f"| {scene} | {rs} | " + " | ".join(cells + diffs) + " |")
        agg = (lambda v: f"{np.mean(v):.2f}") if key == "psnr" else (lambda v: f"{_gmean(v):.3g}")
        aggd = (lambda v: f"{np.mean(v):+.2f}") if key == "psnr" else (lambda v: f"×{_gmean(v):.3g}")
        out.append(f"| **mean, {half}** | | " + " | ".join(agg(cols[k]) if cols[k] else "—" for k in KEY) + " | "
                   + " | ".join(aggd(cols[k]) if cols[k] else "—" for k in ("d1", "d2", "d3")) + " |")
    return "\n".join(out)


def full(rows):
    out = ["| scene | spp | method | PSNR (dB) | relMSE | render (s) | rkwave / OIDN (s) | samples | image min / max | outside local range: any / > 1 % |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        g = r.get("range")
        rg = "" if g is None else f"{g['image_min']:.3g} / {g['image_max']:.3g} (samples {g['samples_min']:.3g} / {g['samples_max']:.3g})"
        og = "" if g is None else f"{g['outside_local']} / {g.get('outside_local_1pct', '?')} (−{g['worst_below']:.3g}, +{g['worst_above']:.3g})"
        out.append(f"| {r['scene']} | {r['spp']} | {r['method']} | {r['psnr']:.2f}{'†' if r['near_floor'] else ''} | "
                   f"{r['relmse']:.3g} | {r['render_s']:.2f} | {r['tool_s']:.2f} | {r['samples']} | {rg} | {og} |")
    return "\n".join(out)


def floors(scenes, cache):
    out = ["| scene | half | PSNR A vs B | relMSE A vs B | floor of the mean: PSNR | relMSE | harness check: box of the samples − Mitsuba box (dB) at 4 / 8 / 16 / 32 |",
           "|---|---|---|---|---|---|---|"]
    for name in scenes:
        m = json.load(open(os.path.join(cache, name, "meta.json")))
        f = m["floor"]
        checks = " / ".join(f"{m['spp'][k]['check']['gap_db']:+.3f}" for k in sorted(m["spp"], key=int))
        out.append(f"| {name} | {m['half']} | {f['psnr_a_vs_b']:.2f} | {f['relmse_a_vs_b']:.3g} | "
                   f"{f['psnr_floor_of_mean']:.2f} | {f['relmse_floor_of_mean']:.3g} | {checks} |")
    return "\n".join(out)


def table(args, scenes, w, h):
    os.makedirs(args.workdir, exist_ok=True)
    rk = Rkwave(args.rkwave, args.workdir, nice=False)  # inherits this process's niceness
    rows = []
    t0 = time.time()
    meta = {"command": " ".join(sys.argv), "machine": f"{os.cpu_count()} cores",
            "load_start": os.getloadavg()}
    for name in scenes:
        for spp in args.spp:
            new, best = scene_rows(args, name, spp, w, h, rk)
            rows.extend(new)
            get = {r["method"]: r for r in new}
            print(f"{name:8s} {spp:3d}: box {get['box of the same samples']['psnr']:.2f}, best film {best['psnr']:.2f}, "
                  f"uniform {get['rkwave uniform']['psnr']:.2f}, plan {get.get('rkwave plan', {}).get('psnr', float('nan')):.2f}, "
                  f"OIDN {get['OIDN box']['psnr']:.2f} / +aux {get['OIDN box +aux']['psnr']:.2f} dB "
                  f"[{time.time() - t0:.0f} s, load {os.getloadavg()[0]:.1f}]", file=sys.stderr, flush=True)
            if args.json:
                with open(args.json, "w") as fh:
                    json.dump({"meta": meta, "rows": rows}, fh, indent=1)
    meta["load_end"] = os.getloadavg()
    meta["wall_s"] = time.time() - t0
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"meta": meta, "rows": rows}, fh, indent=1)
    print(floors(scenes, args.cache))
    print(summary(rows, "psnr"))
    print(summary(rows, "relmse"))
    print()
    print(full(rows))
    return rows
