#!/usr/bin/env python3
"""Judge a plan's suite rows against the seed spread of a baseline run at several seeds.

    python benches/mitsuba/suite_seeds.py --baseline B1.json B2.json B3.json [--candidate C.json]

Each file is a `suite.py plan --json` output for one half (the rows of one half, same spp list;
the baseline's files differ only in `--seed`). Printed per (scene, spp): the baseline's PSNR at
every seed, their mean and sample standard deviation, its gap to the best Mitsuba film at every
seed and its relMSE ratio to the best film's; with a candidate, its PSNR, its difference to the
baseline's mean and a LOSS / GAIN flag when that difference is beyond the row's seed noise:

    |c - mean(b)| > max(0.3 dB, 2 sqrt(1 + 1/k) s),  s = max(s_row, median_row s at that spp)

`k` baseline seeds, `s_row` the row's own standard deviation over them. The candidate changes
the positions as a new seed does, so its difference to a k-seed mean has standard deviation
`s sqrt(1 + 1/k)` if the change does nothing; two of them flag about 5 % of the rows of a change
that does nothing when `s` is right. A row's own `s` from three seeds has two degrees of freedom
and is often far too small, so it is floored by the median over the rows of that spp (rows'
spreads differ: texture rows move by hundredths of a dB between seeds, an emitter's by 1-2 dB).
The 0.3 dB floor is the issue's "no loss over 0.3 dB".
"""

import argparse
import json
import math
import statistics as st


def load(path):
    """The plan's rows of one `suite.py plan --json` file by (scene, spp)."""
    with open(path) as f:
        rows = json.load(f)["rows"]
    return {(r["scene"], r["spp"]): r for r in rows if "plan" in r["method"]}


def threshold(psnrs, spread_at_spp):
    """The candidate's allowed distance to the baseline's mean for one row (module doc)."""
    k = len(psnrs)
    s = max(st.stdev(psnrs), spread_at_spp)
    return max(0.3, 2.0 * math.sqrt(1.0 + 1.0 / k) * s)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", nargs="+", required=True, help="one file per seed (at least 2)")
    ap.add_argument("--candidate", help="the rows to judge")
    args = ap.parse_args()
    if len(args.baseline) < 2:
        ap.error("--baseline needs the rows of at least two seeds to estimate a spread")
    base = [load(p) for p in args.baseline]
    keys = sorted(set.intersection(*(set(b) for b in base)), key=lambda k: (k[0], k[1]))
    if not keys:
        ap.error("the baseline files share no (scene, spp) row")
    cand = load(args.candidate) if args.candidate else None
    if cand is not None and not all(k in cand for k in keys):
        missing = [f"{s} {p}" for s, p in keys if (s, p) not in cand]
        ap.error(f"the candidate lacks rows the baseline has: {', '.join(missing)}")
    spread = {}
    for spp in sorted({k[1] for k in keys}):
        spread[spp] = st.median(st.stdev([b[k]["psnr"] for b in base]) for k in keys if k[1] == spp)
    print("median row seed sd by spp: " + ", ".join(f"{p}: {s:.3f} dB" for p, s in spread.items()))
    flags = {"LOSS": [], "GAIN": []}
    for k in keys:
        ps = [b[k]["psnr"] for b in base]
        db = " ".join(f"{b[k]['d_psnr_best']:+.2f}" for b in base)
        rr = " ".join(f"{b[k]['relmse_ratio_best']:.2f}" for b in base)
        line = (f"{k[0]:9s}{k[1]:3d} base {' '.join(f'{p:6.2f}' for p in ps)} mean {st.mean(ps):6.2f} "
                f"sd {st.stdev(ps):.2f} | best film gap {db} | relMSE/best {rr}")
        if cand is not None:
            c = cand[k]
            d = c["psnr"] - st.mean(ps)
            thr = threshold(ps, spread[k[1]])
            flag = "LOSS" if d < -thr else ("GAIN" if d > thr else "")
            if flag:
                flags[flag].append(f"{k[0]} {k[1]} ({d:+.2f})")
            line += (f" || cand {c['psnr']:6.2f} d {d:+.2f} (beyond {thr:.2f}) {flag:4s} "
                     f"gap {c['d_psnr_best']:+.2f} relMSE/best {c['relmse_ratio_best']:.2f}")
        print(line)
    n = len(keys)
    for i, b in enumerate(base):
        gaps = [b[k]["d_psnr_best"] for k in keys]
        print(f"baseline {args.baseline[i]}: mean gap to the best film {sum(gaps) / n:+.2f} dB, "
              f"{sum(g < 1 for g in gaps)} of {n} rows below best + 1 dB, "
              f"{sum(b[k]['relmse_ratio_best'] > 1 for k in keys)} with relMSE worse than the best film's")
    if cand is not None:
        gaps = [cand[k]["d_psnr_best"] for k in keys]
        print(f"candidate: mean gap to the best film {sum(gaps) / n:+.2f} dB, "
              f"{sum(g < 1 for g in gaps)} of {n} rows below best + 1 dB, "
              f"{sum(cand[k]['relmse_ratio_best'] > 1 for k in keys)} with relMSE worse; "
              f"rounds {sum(cand[k]['rounds'] for k in keys)} (baseline {sum(base[0][k]['rounds'] for k in keys)})")
        for f, rows in flags.items():
            print(f"{f} beyond the seed spread: {len(rows)}: {', '.join(rows) or '-'}")


if __name__ == "__main__":
    main()
