#!/usr/bin/env python3
"""The rows of `pixel_allocation.py --json` (one seed, one `a0`) in the shape of `suite.py plan --json`
rows, so that `suite_seeds.py --candidate` judges them against main's seeds; the best film of each row
is taken from a `suite.py plan --json` file of the same half (any seed: the films do not change).

    PY=/work/venv-mitsuba/bin/python
    $PY benches/mitsuba/prototypes/proto_rows.py benches/mitsuba/results/suite-128-proto-pixelalloc-tuning.json \
        benches/mitsuba/results/suite-128-plan-s15merged-tuning.json --seed 1 --a0 1 > cand.json
    $PY benches/mitsuba/suite_seeds.py --baseline B1.json B2.json B3.json --candidate cand.json
"""

import argparse
import json


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("prototype")
    ap.add_argument("films", help="a suite.py plan --json file of the same half")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--a0", type=float, default=1.0)
    args = ap.parse_args()
    with open(args.films) as f:
        base = {(r["scene"], r["spp"]): r for r in json.load(f)["rows"]}
    with open(args.prototype) as f:
        proto = json.load(f)["rows"]
    rows = []
    for r in proto:
        if r["a0"] != args.a0 or r["seed"] != args.seed:
            continue
        b = base[(r["scene"], r["spp"])]
        rows.append({"scene": r["scene"], "spp": r["spp"], "method": "rkwave plan (prototype pixel_allocation)",
                     "psnr": r["psnr"], "relmse": r["relmse"], "d_psnr_best": r["psnr"] - b["best_psnr"],
                     "relmse_ratio_best": r["relmse"] / b["best_relmse"], "rounds": 2})
    print(json.dumps({"rows": rows}))


if __name__ == "__main__":
    main()
