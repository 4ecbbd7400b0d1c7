#!/usr/bin/env python3
"""The speed-accuracy trade as a curve (issue 40, item 3): quality against total time
(renderer + rkwave) for Mitsuba's films at 1-64 spp, OIDN on the box film, and the `rkwave
plan` loop at 4-32 spp, on the issue-38 suite (`suite.py`, cache in /work/suite-cache), and
the **break-even**: the renderer cost per sample above which the plan pays.

    curve.py run    --rkwave BIN --scenes cornell metal glass wires --json results/128-trade-curve.json
    curve.py report --json results/128-trade-curve.json --figure docs/measurements/trade-curve.png

`run` renders (films, OIDN, the plan loop) and writes every point; `report` renders nothing:
it prints the tables and the break-even and draws the figure from the JSON.

**Cost model.** A renderer that takes `N` samples costs `c N` seconds, `c` its cost per
sample. `c` is measured from `mi.render` (Mitsuba 3 `scalar_rgb`, C++, multithreaded) on the
box film at the largest film spp: `c = seconds / (rendered spp x pixels)`, both as wall time
and as the process's CPU time (`time.process_time`, every thread). The plan's own renderer
(`render.Renderer`, one sample at a time from Python) is not Mitsuba's speed and its time is
not used. Then
* a film of `N` samples: `T_film = c N`;
* OIDN on the box film of `N` samples: `T = c N + t_oidn`;
* the plan with `N_p` samples: `T_plan = t_rk + c N_p`, `t_rk` the summed wall (or CPU, user
  + system, from `getrusage(RUSAGE_CHILDREN)`) time of every `rkwave plan` process of the loop.

**Equal quality.** For a plan point of quality `q` (PSNR of the images clipped to [0, 1], or
log relMSE of the HDR values, against the two-half reference), the film's samples of equal
quality `N_eq` interpolate the film curve linearly in `log N` between the two film spp that
bracket `q` (the first bracket from 1 spp up; the curve is measured, not assumed monotone).
The film curve is either Mitsuba's box film or, per spp, the best of Mitsuba's five filters by
that measure (a user who picks the best filter per budget: the films' best case). The plan
pays when `c N_eq > t_rk + c N_p`, i.e. for `c > c* = t_rk / (N_eq - N_p)` when
`N_eq > N_p`. If `N_eq <= N_p` the plan is below the film at equal samples and never pays; if
`q` is better than the film at 64 spp, `N_eq > N_64` and `c* < t_rk / (N_64 - N_p)` (an upper
bound); if `q` is worse than the film at 1 spp, the plan never pays either.
"""

import argparse
import json
import os
import platform
import resource
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402

DEFAULT_CACHE = os.environ.get("RKWAVE_SUITE_CACHE", "/work/suite-cache")
MEASURES = ("psnr", "relmse")
RUN_KEYS = ("command", "started", "loadavg_start", "loadavg_end", "elapsed_s")


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _loadavg():
    try:
        return list(os.getloadavg())
    except OSError:
        return None


# ----------------------------------------------------------------------------- run

def run(args):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    mi.set_log_level(mi.LogLevel.Error)
    import metrics
    import oidn
    import suite_cache
    import suite_scenes as ss
    import suite_score
    from rkwave_cli import Rkwave

    class TimedRkwave(Rkwave):
        """`Rkwave` that also sums the CPU time (user + system) of its processes."""

        cpu = 0.0
        calls = 0

        def _run(self, a):
            c0 = _children_cpu()
            out = super()._run(a)
            self.cpu += _children_cpu() - c0
            self.calls += 1
            return out

    w = h = args.resolution
    pixels = w * h
    out = {"command": " ".join(["curve.py"] + sys.argv[1:]), "mitsuba": mi.__version__,
           "variant": mi.variant(), "resolution": [w, h], "machine": f"{platform.machine()}, {os.cpu_count()} cores",
           "rkwave": args.rkwave, "niceness": os.nice(0), "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
           "loadavg_start": _loadavg(), "film_seed": suite_cache.FILM_SEED, "scenes": {}}
    if args.json and os.path.exists(args.json) and args.resume:
        prev = json.load(open(args.json))
        out["scenes"] = prev.get("scenes", {})
        # The earlier runs' own headers (command, start, load, elapsed) are kept.
        out["runs"] = prev.get("runs", []) + [{k: prev.get(k) for k in RUN_KEYS}]
    t_start = time.perf_counter()
    for name in args.scenes:
        if name in out["scenes"] and out["scenes"][name].get("complete"):
            print(f"{name}: kept from {args.json}", flush=True)
            continue
        d = os.path.join(args.cache, name)
        ref = np.load(os.path.join(d, "ref.npy"))
        meta = json.load(open(os.path.join(d, "meta.json")))
        sc = {"half": "tuning" if name in ss.TUNING else "validation", "floor": meta["floor"],
              "films": [], "oidn": [], "plan": [], "loadavg": [_loadavg()]}
        out["scenes"][name] = sc
        # Mitsuba's films, rendered here (mi.render, seed FILM_SEED as the cache's), timed.
        for spp in args.film_spp:
            n = suite_cache.rendered_spp(spp)
            for f in ss.FILTERS:
                scene = ss.load(name, w, h, f, spp)
                c0, t0 = time.process_time(), time.perf_counter()
                img = np.array(mi.render(scene, spp=spp, seed=suite_cache.FILM_SEED), dtype=np.float64)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                sc["films"].append({"filter": f, "spp": spp, "rendered_spp": n, "samples": n * pixels,
                                    "wall_s": wall, "cpu_s": cpu,
                                    "psnr": metrics.psnr(img, ref), "relmse": metrics.relmse(img, ref)})
                if f == "box":
                    den, t_o = None, None
                    try:
                        c1 = time.process_time()
                        den, t_o = oidn.denoise(img)
                        cpu_o = time.process_time() - c1
                    except ValueError as e:  # negative or non-finite input: said, not clipped
                        sc["oidn"].append({"spp": spp, "rendered_spp": n, "samples": n * pixels, "error": str(e)})
                    if den is not None:
                        sc["oidn"].append({"spp": spp, "rendered_spp": n, "samples": n * pixels,
                                           "oidn_wall_s": t_o, "oidn_cpu_s": cpu_o,
                                           "psnr": metrics.psnr(den, ref), "relmse": metrics.relmse(den, ref)})
            b = sc["films"][-len(ss.FILTERS)]
            print(f"{name:8s} film {spp:3d} spp ({n}): box {b['psnr']:.2f} dB relMSE {b['relmse']:.3g} "
                  f"{b['wall_s']:.2f} s wall {b['cpu_s']:.2f} s CPU; OIDN "
                  f"{sc['oidn'][-1].get('psnr', float('nan')):.2f} dB", flush=True)
        sc["loadavg"].append(_loadavg())
        # The plan loop (suite_score.run_plan: the suite's own loop, default plan flags).
        rk = TimedRkwave(args.rkwave, os.path.join(args.workdir, name), nice=False)
        for spp in args.plan_spp:
            data = suite_score.load(args.cache, name, spp)
            rk.cpu, rk.calls = 0.0, 0
            img, s_all, render_s, dt, rounds = suite_score.run_plan(args, name, spp, data, w, h, rk)
            sc["plan"].append({"spp": spp, "rendered_spp": data["rendered_spp"], "samples": int(len(s_all)),
                               "rkwave_wall_s": dt, "rkwave_cpu_s": rk.cpu, "rkwave_calls": rk.calls,
                               "rounds": rounds, "python_render_s": render_s,
                               "psnr": metrics.psnr(img, ref), "relmse": metrics.relmse(img, ref)})
            p = sc["plan"][-1]
            print(f"{name:8s} plan {spp:3d} spp: {p['samples']} samples, {rounds} rounds, {p['psnr']:.2f} dB "
                  f"relMSE {p['relmse']:.3g}, rkwave {dt:.2f} s wall {rk.cpu:.2f} s CPU", flush=True)
        sc["loadavg"].append(_loadavg())
        sc["complete"] = True
        out["elapsed_s"] = time.perf_counter() - t_start
        out["loadavg_end"] = _loadavg()
        if args.json:
            os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
            with open(args.json, "w") as fh:
                json.dump(out, fh, indent=1)
    return out


# ----------------------------------------------------------------------------- analysis

def _q(point, measure):
    """The quality as an increasing function: PSNR, or -log10 relMSE."""
    return point["psnr"] if measure == "psnr" else -np.log10(point["relmse"])


def film_curve(sc, measure, which):
    """(samples, quality, labels) of the film curve, increasing samples: `box`, or per spp the
    best of the five filters by `measure`."""
    by_spp = {}
    for f in sc["films"]:
        by_spp.setdefault(f["spp"], []).append(f)
    ns, qs, labs = [], [], []
    for spp in sorted(by_spp):
        rows = by_spp[spp]
        r = next(x for x in rows if x["filter"] == "box") if which == "box" else max(rows, key=lambda x: _q(x, measure))
        ns.append(r["samples"])
        qs.append(_q(r, measure))
        labs.append(r["filter"])
    return np.array(ns, float), np.array(qs, float), labs


def equal_samples(ns, qs, q):
    """The fewest samples at which the curve (ns, qs), linear in log N between its points,
    reaches quality q: (N_eq, status) with status 'ok', 'above' (the curve never reaches q:
    N_eq is a lower bound, the largest N) or 'below' (the curve's first point already reaches
    q: N_eq <= ns[0]). On a non-monotone curve (fireflies) this is the first crossing."""
    if q < qs[0]:
        return ns[0], "below"
    for k in range(len(ns) - 1):
        a, b = qs[k], qs[k + 1]
        if (a <= q <= b) or (b <= q <= a):
            t = 0.0 if b == a else (q - a) / (b - a)
            return float(np.exp(np.log(ns[k]) + t * (np.log(ns[k + 1]) - np.log(ns[k])))), "ok"
    if q <= qs.max():  # only reachable for a non-monotone curve whose maximum is inside
        k = int(np.argmax(qs >= q))
        return ns[k], "ok"
    return ns[-1], "above"


def cost_per_sample(sc, clock):
    """c from the box film at the largest spp: seconds / samples (wall or CPU)."""
    box = [f for f in sc["films"] if f["filter"] == "box"]
    top = max(box, key=lambda f: f["samples"])
    return top[f"{clock}_s"] / top["samples"]


def breakeven_rows(data, clock="wall"):
    rows = []
    for name, sc in data["scenes"].items():
        c = cost_per_sample(sc, clock)
        for p in sc["plan"]:
            t_rk = p[f"rkwave_{clock}_s"]
            for measure in MEASURES:
                q = _q(p, measure)
                r = {"scene": name, "half": sc["half"], "spp": p["spp"], "measure": measure,
                     "plan_q": p[measure], "samples": p["samples"], "t_rk": t_rk, "c": c}
                for which in ("box", "best"):
                    ns, qs, labs = film_curve(sc, measure, which)
                    n_eq, status = equal_samples(ns, qs, q)
                    if status == "below" or n_eq <= p["samples"]:
                        cstar, kind = float("inf"), "never"
                    elif status == "above":
                        cstar, kind = t_rk / (n_eq - p["samples"]), "at most"
                    else:
                        cstar, kind = t_rk / (n_eq - p["samples"]), "="
                    r[which] = {"n_eq": n_eq, "status": status, "cstar": cstar, "kind": kind,
                                "spp_eq": n_eq / (data["resolution"][0] * data["resolution"][1]),
                                "t_plan": t_rk + c * p["samples"], "t_film": c * n_eq}
                ons, oqs = _oidn_curve(sc, measure)
                if len(ons):
                    n_o, st_o = equal_samples(ons, oqs, q)
                    t_o = _oidn_time(sc, n_o, clock)
                    r["oidn"] = {"n_eq": n_o, "status": st_o, "t": c * n_o + t_o}
                rows.append(r)
    return rows


def _oidn_curve(sc, measure):
    pts = [o for o in sc["oidn"] if "error" not in o]
    return np.array([o["samples"] for o in pts], float), np.array([_q(o, measure) for o in pts], float)


def _oidn_time(sc, n, clock):
    """OIDN's own time at the nearest measured spp (it depends on the pixels, not the samples)."""
    pts = [o for o in sc["oidn"] if "error" not in o]
    o = min(pts, key=lambda o: abs(np.log(o["samples"]) - np.log(n)))
    return o[f"oidn_{clock}_s"]


def _fmt_c(x):
    return "—" if not np.isfinite(x) else f"{x * 1e6:.3g} µs"


def print_report(data):
    px = data["resolution"][0] * data["resolution"][1]
    print(f"# {data['command']}\n# Mitsuba {data['mitsuba']} {data['variant']}, {data['resolution'][0]}x"
          f"{data['resolution'][1]}, {data['machine']}, niceness {data.get('niceness')}, "
          f"load average at start {data.get('loadavg_start')}, at end {data.get('loadavg_end')}, "
          f"elapsed {data.get('elapsed_s', float('nan')):.0f} s\n")
    print("## Renderer cost per sample (mi.render, box film, largest spp)\n")
    print("| scene | half | c wall (µs) | c CPU (µs) | rkwave plan wall / CPU at 8 spp (s) |")
    print("|---|---|---|---|---|")
    for name, sc in data["scenes"].items():
        p8 = next((p for p in sc["plan"] if p["spp"] == 8), None)
        rk = f"{p8['rkwave_wall_s']:.2f} / {p8['rkwave_cpu_s']:.2f}" if p8 else "—"
        print(f"| {name} | {sc['half']} | {cost_per_sample(sc, 'wall') * 1e6:.3g} | "
              f"{cost_per_sample(sc, 'cpu') * 1e6:.3g} | {rk} |")
    print("\n## Points within twice the reference's noise floor (clipped MSE or relMSE; not resolvable)\n")
    for name, sc in data["scenes"].items():
        f = sc["floor"]

        def near(r):
            return bool(10 ** (-r["psnr"] / 10) < 2 * 10 ** (-f["psnr_floor_of_mean"] / 10)
                        or r["relmse"] < 2 * f["relmse_floor_of_mean"])

        hits = ([f"plan {p['spp']}" for p in sc["plan"] if near(p)]
                + [f"film {x['filter']} {x['spp']}" for x in sc["films"] if near(x)]
                + [f"OIDN {x['spp']}" for x in sc["oidn"] if "error" not in x and near(x)])
        if hits:
            print(f"- {name}: " + ", ".join(hits) + f" (floor {f['psnr_floor_of_mean']:.1f} dB, "
                  f"relMSE {f['relmse_floor_of_mean']:.2g})")
    print("\n## Curves (quality per spp; films: box and the best filter by PSNR)\n")
    print("| scene | spp | box dB | box relMSE | best film dB | best relMSE | OIDN dB | OIDN relMSE | plan dB | plan relMSE | plan samples / px |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, sc in data["scenes"].items():
        spps = sorted({f["spp"] for f in sc["films"]} | {p["spp"] for p in sc["plan"]})
        for spp in spps:
            fl = [f for f in sc["films"] if f["spp"] == spp]
            o = next((x for x in sc["oidn"] if x["spp"] == spp and "error" not in x), None)
            p = next((x for x in sc["plan"] if x["spp"] == spp), None)
            cells = ["—"] * 4
            if fl:
                b = next(f for f in fl if f["filter"] == "box")
                bp = max(fl, key=lambda f: f["psnr"])
                br = min(fl, key=lambda f: f["relmse"])
                cells = [f"{b['psnr']:.2f}", f"{b['relmse']:.3g}", f"{bp['psnr']:.2f} ({bp['filter']})",
                         f"{br['relmse']:.3g} ({br['filter']})"]
            oc = [f"{o['psnr']:.2f}", f"{o['relmse']:.3g}"] if o else ["—", "—"]
            pc = [f"{p['psnr']:.2f}", f"{p['relmse']:.3g}", f"{p['samples'] / px:.2f}"] if p else ["—"] * 3
            print(f"| {name} | {spp} | " + " | ".join(cells + oc + pc) + " |")
    for clock in ("wall", "cpu"):
        rows = breakeven_rows(data, clock)
        print(f"\n## Break-even ({clock} time): c* = t_rk / (N_eq - N_plan); the plan pays for c > c*\n")
        print("| scene | spp | measure | plan | t_rk (s) | box film: spp of equal quality | c* vs box | "
              "best film: spp eq. | c* vs best | at measured c: plan / best film time | OIDN time to equal quality (s) |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            qs = f"{r['plan_q']:.2f} dB" if r["measure"] == "psnr" else f"{r['plan_q']:.3g}"
            cells = []
            for which in ("box", "best"):
                e = r[which]
                spp_eq = {"ok": f"{e['spp_eq']:.1f}", "above": f"> {e['spp_eq']:.0f}",
                          "below": f"≤ {e['spp_eq']:.0f}"}[e["status"]]
                cst = "never" if e["kind"] == "never" else (
                    ("≤ " if e["kind"] == "at most" else "") + _fmt_c(e["cstar"]))
                cells += [spp_eq, cst]
            b = r["best"]
            ratio = f"{b['t_plan'] / b['t_film']:.3g}" + {"ok": "", "above": " (film time a lower bound)",
                                                           "below": " (film time an upper bound)"}[b["status"]]
            o = r.get("oidn")
            ot = "—" if o is None else ({"ok": "", "above": "> ", "below": "≤ "}[o["status"]] + f"{o['t']:.3g}")
            print(f"| {r['scene']} | {r['spp']} | {r['measure']} | {qs} | {r['t_rk']:.2f} | {cells[0]} | {cells[1]} | "
                  f"{cells[2]} | {cells[3]} | {ratio} | {ot} |")
        print()
        for which, measure, half in [(w_, m_, h_) for w_ in ("box", "best") for m_ in MEASURES
                                     for h_ in ("tuning", "validation", "both")]:
            if True:
                sel = [r for r in rows if r["measure"] == measure and half in (r["half"], "both")]
                if not sel:
                    continue
                exact = [r[which]["cstar"] for r in sel if r[which]["kind"] == "="]
                bound = [r[which]["cstar"] for r in sel if r[which]["kind"] == "at most"]
                never = sum(1 for r in sel if r[which]["kind"] == "never")
                dec = [r for r in sel if r[which]["status"] != "above"]  # decided at the measured c
                px = data["resolution"][0] * data["resolution"][1]
                und = [r[which]["t_plan"] / (r["c"] * px) for r in sel if r[which]["status"] == "above"]
                pays = sum(1 for r in dec if r[which]["t_plan"] < r[which]["t_film"])
                ratio = np.median([r[which]["t_plan"] / r[which]["t_film"] for r in dec]) if dec else float("nan")
                cs = [cost_per_sample(sc, clock) for sc in data["scenes"].values()
                      if half in (sc["half"], "both")]
                rel = [r[which]["cstar"] / r["c"] for r in sel if r[which]["kind"] == "="]
                ex = (f"c* median {np.median(exact) * 1e6:.3g} µs, range {min(exact) * 1e6:.3g}–"
                      f"{max(exact) * 1e6:.3g} µs at {len(exact)} (c* / Mitsuba's c: median {np.median(rel):.3g}, "
                      f"range {min(rel):.3g}–{max(rel):.3g})") if exact else "c* exact at 0"
                bd = (f"c* <= {min(bound) * 1e6:.3g}–{max(bound) * 1e6:.3g} µs at {len(bound)} (films never "
                      f"reach the plan by 64 spp)") if bound else "no upper bounds"
                print(f"{clock:4s} vs {which:4s} film, {measure:6s}, {half:10s} ({len(sel)} plan points): {ex}; {bd}; "
                      f"never pays at {never}. At Mitsuba's c ({min(cs) * 1e6:.3g}–{max(cs) * 1e6:.3g} µs): "
                      f"the plan pays at {pays} of the {len(dec)} points the films reach (median plan / film time "
                      f"{ratio:.3g}); undecided at {len(sel) - len(dec)}" + (
                          f" (there the film would have to need more than {min(und):.0f}–{max(und):.0f} spp, "
                          f"median {np.median(und):.0f}, for the plan to pay)" if und else ""))


def print_condensed(data, clock="wall"):
    """One row per plan point against the best film per spp, both measures (the docs' table)."""
    rows = breakeven_rows(data, clock)
    print(f"\n## Per plan point against the best film ({clock} time)\n")
    print("| scene | spp | plan dB | film spp of equal PSNR | c* (PSNR) | plan relMSE | film spp of equal relMSE | "
          "c* (relMSE) | t_rk (s) | plan / film time at Mitsuba's c (PSNR) | OIDN's time to the plan's PSNR (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    by = {}
    for r in rows:
        by.setdefault((r["scene"], r["spp"]), {})[r["measure"]] = r
    for (scene, spp), d in by.items():
        cells = []
        for m in MEASURES:
            r = d[m]
            e = r["best"]
            q = f"{r['plan_q']:.2f}" if m == "psnr" else f"{r['plan_q']:.3g}"
            se = {"ok": f"{e['spp_eq']:.1f}", "above": "> 64", "below": "≤ 1"}[e["status"]]
            cs = "never" if e["kind"] == "never" else ("≤ " if e["kind"] == "at most" else "") + _fmt_c(e["cstar"])
            cells += [q, se, cs]
        r = d["psnr"]
        e = r["best"]
        ratio = ({"ok": "", "above": "≤ ", "below": "≥ "}[e["status"]]) + f"{e['t_plan'] / e['t_film']:.3g}"
        o = r.get("oidn")
        ot = "—" if o is None else ({"ok": "", "above": "> ", "below": "≤ "}[o["status"]] + f"{o['t']:.2g}")
        print(f"| {scene} ({data['scenes'][scene]['half'][0]}) | {spp} | " + " | ".join(cells)
              + f" | {r['t_rk']:.1f} | {ratio} | {ot} |")


# ----------------------------------------------------------------------------- figure

def figure(data, path, clock="wall", scenes=None):
    """`path`: quality against total time, one column per scene of `scenes` (default: the
    first four), PSNR above, relMSE below; `NAME-breakeven.png`: for every plan point of every
    scene, plan time / best film's time of equal quality as a function of c."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(scenes or list(data["scenes"])[:4])
    fig, axes = plt.subplots(2, len(names), figsize=(4.2 * len(names), 7.5), squeeze=False)
    for j, name in enumerate(names):
        sc = data["scenes"][name]
        c = cost_per_sample(sc, clock)
        for i, measure in enumerate(MEASURES):
            ax = axes[i][j]
            val = (lambda r: r["psnr"]) if measure == "psnr" else (lambda r: r["relmse"])
            for which, style in (("box", "C0-o"), ("best", "C1--s")):
                by = {}
                for f in sc["films"]:
                    by.setdefault(f["spp"], []).append(f)
                pts = []
                for spp in sorted(by):
                    rows = by[spp]
                    r = next(x for x in rows if x["filter"] == "box") if which == "box" else max(rows, key=lambda x: _q(x, measure))
                    pts.append((c * r["samples"], val(r), spp))
                ax.plot([p[0] for p in pts], [p[1] for p in pts], style, ms=4,
                        label="Mitsuba box film" if which == "box" else "best Mitsuba filter")
                if which == "box":
                    for t, v, spp in pts:
                        ax.annotate(str(spp), (t, v), fontsize=6, textcoords="offset points", xytext=(2, -8))
            op = [o for o in sc["oidn"] if "error" not in o]
            ax.plot([c * o["samples"] + o[f"oidn_{clock}_s"] for o in op], [val(o) for o in op], "C2-^", ms=4,
                    label="OIDN on the box film")
            pp = sc["plan"]
            ax.plot([p[f"rkwave_{clock}_s"] + c * p["samples"] for p in pp], [val(p) for p in pp], "C3-D", ms=5,
                    label="rkwave plan (rkwave + renderer)")
            for p in pp:
                ax.annotate(str(p["spp"]), (p[f"rkwave_{clock}_s"] + c * p["samples"], val(p)), fontsize=6,
                            color="C3", textcoords="offset points", xytext=(3, 3))
            ax.set_xscale("log")
            if measure == "relmse":
                ax.set_yscale("log")
            ax.set_title(f"{name} ({sc['half']}), c = {c * 1e6:.2g} µs" if i == 0 else "", fontsize=9)
            ax.set_xlabel(f"total {clock} time (s)", fontsize=8)
            ax.set_ylabel("PSNR, clipped (dB)" if measure == "psnr" else "relMSE (HDR)", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="lower right")
    fig.suptitle(f"Quality against total time, {data['resolution'][0]}², Mitsuba {data['variant']} "
                 f"({clock} time; numbers: spp)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    # The break-even as a function of c: plan time / best film's time of equal quality.
    be = os.path.splitext(path)[0] + "-breakeven.png"
    rows = breakeven_rows(data, clock)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), squeeze=False)
    cs = np.logspace(-7, -3, 200)
    for i, measure in enumerate(MEASURES):
        ax = axes[0][i]
        for k, r in enumerate([r for r in rows if r["measure"] == measure]):
            b = r["best"]
            if b["kind"] == "never":
                continue
            ratio = (r["t_rk"] + cs * r["samples"]) / (cs * b["n_eq"])
            col = "C0" if r["half"] == "tuning" else "C1"
            ax.plot(cs * 1e6, ratio, color=col, lw=0.8, alpha=0.8, ls="-" if b["status"] == "ok" else ":")
            ax.plot(r["c"] * 1e6, (r["t_rk"] + r["c"] * r["samples"]) / (r["c"] * b["n_eq"]), "o", color=col, ms=3)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("renderer cost per sample c (µs)", fontsize=8)
        ax.set_ylabel("plan time / best film's time at equal quality", fontsize=8)
        ax.set_title(f"equal {'PSNR' if measure == 'psnr' else 'relMSE'}: below 1 the plan pays\n"
                     f"(dots: measured c; dotted: film never reached it by 64 spp, a bound)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
        from matplotlib.lines import Line2D

        ax.legend(handles=[Line2D([], [], color="C0", lw=1, label="tuning scenes"),
                           Line2D([], [], color="C1", lw=1, label="validation scenes"),
                           Line2D([], [], color="k", lw=1, ls=":", label="film > 64 spp (bound)")], fontsize=7)
    fig.tight_layout()
    fig.savefig(be, dpi=90)
    plt.close(fig)
    return path, be


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="render films, OIDN and the plan; write the points")
    r.add_argument("--rkwave", required=True)
    r.add_argument("--cache", default=DEFAULT_CACHE)
    r.add_argument("--resolution", type=int, default=128)
    r.add_argument("--scenes", nargs="+", required=True)
    r.add_argument("--film-spp", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    r.add_argument("--plan-spp", type=int, nargs="+", default=[4, 8, 16, 32])
    r.add_argument("--json", required=True)
    r.add_argument("--resume", action="store_true", help="keep the scenes already complete in --json")
    r.add_argument("--workdir", default=f"/tmp/rkwave-curve-{os.getpid()}")
    r.add_argument("--seed", type=int, default=1, help="the plan's seed")
    r.add_argument("--extra", default="", help="flags for the plan's first call")
    p = sub.add_parser("report", help="tables, break-even and figure from the JSON (no rendering)")
    p.add_argument("--json", required=True)
    p.add_argument("--figure", help="PNG path (a second PNG, NAME-breakeven.png, is written beside it)")
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall", help="the figure's clock")
    p.add_argument("--figure-scenes", nargs="+", help="the scenes of the curves figure (default: the first four)")
    args = ap.parse_args()
    if args.cmd == "run":
        data = run(args)
    else:
        data = json.load(open(args.json))
    print_report(data)
    print_condensed(data, getattr(args, "clock", "wall"))
    if getattr(args, "figure", None):
        print("\nfigures:", *figure(data, args.figure, args.clock, args.figure_scenes))


if __name__ == "__main__":
    main()
