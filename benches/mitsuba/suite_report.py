#!/usr/bin/env python3
"""The write-up's tables and target checks from `suite.py table --json` files (merged).

    python benches/mitsuba/suite_report.py tuning.json validation.json [--cache DIR]

Prints: the noise floors and harness checks, the PSNR and relMSE summaries per half (with
per-half means), then the issue-38 targets per (scene, spp): uniform against the per-pixel
mean of the same samples (−0.1 dB and relMSE), the plan against the best film (+1 dB and
relMSE), the plan against OIDN, OIDN on the plan's samples against OIDN on uniform samples,
and the range of rkwave's images against their samples.
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

from suite_table import floors, full, summary  # noqa: E402


FILMS = ("box", "tent", "gaussian", "mitchell", "lanczos")


def films_table(rows, get):
    """Mitsuba's five films per (scene, spp): PSNR / relMSE, per half with means."""
    for half in ("tuning", "validation"):
        cases = []
        for r in rows:
            if r["half"] == half and (r["scene"], r["spp"]) not in cases:
                cases.append((r["scene"], r["spp"]))
        if not cases:
            continue
        print(f"\nMitsuba's five films, PSNR (dB) / relMSE, {half} half\n")
        print("| scene | spp | " + " | ".join(FILMS) + " |")
        print("|---" * (len(FILMS) + 2) + "|")
        for s, spp in cases:
            cells = [f"{get[(s, spp, 'mitsuba ' + f)]['psnr']:.2f} / {get[(s, spp, 'mitsuba ' + f)]['relmse']:.3g}"
                     for f in FILMS]
            print(f"| {s} | {spp} | " + " | ".join(cells) + " |")
        means = [f"{np.mean([get[(s, p, 'mitsuba ' + f)]['psnr'] for s, p in cases]):.2f} / "
                 f"{np.exp(np.mean([np.log(get[(s, p, 'mitsuba ' + f)]['relmse']) for s, p in cases])):.3g}"
                 for f in FILMS]
        print(f"| **mean, {half}** | | " + " | ".join(means) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("json", nargs="+")
    ap.add_argument("--cache", default="/work/suite-cache")
    ap.add_argument("--full", action="store_true", help="also every row")
    args = ap.parse_args()
    rows, metas = [], []
    for p in args.json:
        d = json.load(open(p))
        rows.extend(d["rows"])
        metas.append(d["meta"])
    scenes = []
    for r in rows:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
    for m in metas:
        print(f"- `{m['command']}`: {m.get('wall_s', float('nan')):.0f} s wall, load average "
              f"{m['load_start'][0]:.1f} at start, {m.get('load_end', [float('nan')])[0]:.1f} at end ({m['machine']})")
    print()
    print(floors(scenes, args.cache))
    print(summary(rows, "psnr"))
    print(summary(rows, "relmse"))
    get = {(r["scene"], r["spp"], r["method"]): r for r in rows}
    films_table(rows, get)
    cases = sorted({(r["scene"], r["spp"]) for r in rows}, key=lambda k: (scenes.index(k[0]), k[1]))
    print("\nTargets per (scene, spp): ✗ = missed\n")
    print("| half | scene | spp | uniform − mean (dB) | uniform relMSE / mean | plan − best film (dB) | plan relMSE / best | "
          "plan − OIDN box (dB) | plan − OIDN box +aux (dB) | OIDN plan − OIDN box (dB) | uniform min (samples min) | "
          "uniform outside local: any / > 1 % (worst −, +) | plan min | plan outside local: any / > 1 % (worst −, +) |")
    print("|---" * 15 + "|")
    for s, spp in cases:
        u = get[(s, spp, "rkwave uniform")]
        p = get.get((s, spp, "rkwave plan"))
        ob, oa = get[(s, spp, "OIDN box")], get[(s, spp, "OIDN box +aux")]
        op = get.get((s, spp, "OIDN plan mean"))
        cells = [u["half"], s, str(spp),
                 f"{u['d_psnr_mean']:+.2f}" + (" ✗" if u["d_psnr_mean"] < -0.1 else ""),
                 f"{u['relmse_ratio_mean']:.3g}" + (" ✗" if u["relmse_ratio_mean"] > 1 else "")]
        if p:
            cells += [f"{p['d_psnr_best']:+.2f}" + (" ✗" if p["d_psnr_best"] < 1 else ""),
                      f"{p['relmse_ratio_best']:.3g}" + (" ✗" if p["relmse_ratio_best"] > 1 else ""),
                      f"{p['psnr'] - ob['psnr']:+.2f}", f"{p['psnr'] - oa['psnr']:+.2f}",
                      f"{op['psnr'] - ob['psnr']:+.2f}" + (" ✗" if op["psnr"] - ob["psnr"] < 1 else "")]
        else:
            cells += ["—"] * 5
        g = u["range"]
        cells += [f"{g['image_min']:.3g} ({g['samples_min']:.3g})", f"{g['outside_local']} / {g.get('outside_local_1pct', '?')} (−{g['worst_below']:.3g}, +{g['worst_above']:.3g})"]
        if p:
            g = p["range"]
            cells += [f"{g['image_min']:.3g}", f"{g['outside_local']} / {g.get('outside_local_1pct', '?')} (−{g['worst_below']:.3g}, +{g['worst_above']:.3g})"]
        else:
            cells += ["—", "—"]
        print("| " + " | ".join(cells) + " |")
    print()
    for half in ("tuning", "validation"):
        for spps in ((4, 8, 16), (4, 8, 16, 32)):
            sel = [(s, spp) for s, spp in cases if get[(s, spp, "rkwave uniform")]["half"] == half and spp in spps]
            ps = [get[(s, spp, "rkwave plan")] for s, spp in sel if (s, spp, "rkwave plan") in get]
            us = [get[(s, spp, "rkwave uniform")] for s, spp in sel]
            opm = [get[(s, spp, "OIDN plan mean")]["psnr"] - get[(s, spp, "OIDN box")]["psnr"]
                   for s, spp in sel if (s, spp, "OIDN plan mean") in get]
            print(f"- {half}, spp {'/'.join(map(str, spps))}: uniform below mean − 0.1 dB on "
                  f"{sum(u['d_psnr_mean'] < -0.1 for u in us)} of {len(us)}, relMSE above the mean's on "
                  f"{sum(u['relmse_ratio_mean'] > 1 for u in us)}; plan below best film + 1 dB on "
                  f"{sum(p['d_psnr_best'] < 1 for p in ps)} of {len(ps)}, relMSE above the best film's on "
                  f"{sum(p['relmse_ratio_best'] > 1 for p in ps)}; mean plan − best film "
                  f"{np.mean([p['d_psnr_best'] for p in ps]) if ps else float('nan'):+.2f} dB; mean OIDN(plan) − OIDN(box) "
                  f"{np.mean(opm) if opm else float('nan'):+.2f} dB")
    if args.full:
        print()
        print(full(rows))


if __name__ == "__main__":
    main()
