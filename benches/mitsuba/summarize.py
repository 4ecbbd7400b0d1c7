#!/usr/bin/env python3
"""Markdown tables from one or more harness JSON files (rows merged in the given order).

    python benches/mitsuba/summarize.py run.json [more.json ...]

Table 1: PSNR (dB) per scene and spp, one column per method, and the adaptive sampler's
margin over the best of Mitsuba's five films. Table 2: every row with relMSE, SSIM and times.
"""

import json
import sys

FILMS = ["box", "tent", "gaussian", "mitchell", "lanczos"]
OURS = ["box of the same samples", "rkwave uniform", "rkwave adaptive (plan)", "cycles-style adaptive"]


def main(paths):
    rows = []
    for p in paths:
        with open(p) as fh:
            rows.extend(json.load(fh)["rows"])
    keys = []
    for r in rows:
        k = (r["scene"], r["spp"])
        if k not in keys:
            keys.append(k)
    get = {(r["scene"], r["spp"], r["method"]): r for r in rows}
    print("| scene | spp | " + " | ".join(f"Mitsuba {f}" for f in FILMS)
          + " | box, same samples | rkwave uniform | rkwave adaptive | Cycles-style | adaptive − best film | uniform − Gaussian |")
    print("|---" * (2 + len(FILMS) + len(OURS) + 2) + "|")
    for scene, spp in keys:
        films = [get[(scene, spp, f"mitsuba {f}")]["psnr"] for f in FILMS]
        best = max(films)
        ours = [get.get((scene, spp, m)) for m in OURS]
        cells = [f"{v:.2f}" + ("*" if v == best else "") for v in films]
        cells += ["—" if o is None else f"{o['psnr']:.2f}" for o in ours]
        ad = get.get((scene, spp, "rkwave adaptive (plan)"))
        un = get[(scene, spp, "rkwave uniform")]
        cells.append("—" if ad is None else f"{ad['psnr'] - best:+.2f}")
        cells.append(f"{un['psnr'] - films[2]:+.2f}")
        print(f"| {scene} | {spp} | " + " | ".join(cells) + " |")
    print()
    print("| scene | spp | method | PSNR (dB) | relMSE | SSIM | render (s) | rkwave (s) | samples |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['spp']} | {r['method']} | {r['psnr']:.2f} | {r['relmse']:.3g} | "
              f"{r['ssim']:.4f} | {r['render_s']:.2f} | {r['rkwave_s']:.2f} | {r['samples']} |")


if __name__ == "__main__":
    main(sys.argv[1:])
