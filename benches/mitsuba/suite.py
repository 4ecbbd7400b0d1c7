#!/usr/bin/env python3
"""The issue-38 scene suite: 16 Mitsuba 3 scenes, a fixed tuning / validation split
(`suite_scenes.TUNING`, `suite_scenes.VALIDATION`), references in two halves with their
noise floor, a sample cache, and scoring entries. See docs/measurements/suite.md.

    suite.py cache --half tuning|validation|both            # render into CACHE (once)
    suite.py score --rkwave BIN --half tuning --spp 4 8 [--extra "FLAGS"] [--json F]
    suite.py plan  --rkwave BIN --scenes glass wires --spp 4 8 [--extra "FLAGS"] [--json F]
    suite.py plan  --rkwave BIN2 --reuse --workdir W ...   # only the final image again, on W's kept states
    suite.py table --rkwave BIN --half both --spp 4 8 16 32 --json F   # the full table
    suite.py fixtures --out data/renders/suite --resolution 48 --spp 4 8   # for cargo test

`score` renders nothing: it runs `BIN reconstruct --dim 2 FLAGS` on the cached uniform
samples. `plan` runs the `rkwave plan` loop with the renderer answering each round.
`table` writes every row (films, box of the same samples, rkwave uniform, the plan, OIDN).
"""

import argparse
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)  # multijitter warns when it rounds 32 up to 35

import suite_cache  # noqa: E402
import suite_scenes as ss  # noqa: E402

TUNING = ss.TUNING
VALIDATION = ss.VALIDATION
DEFAULT_CACHE = os.environ.get("RKWAVE_SUITE_CACHE", "/work/suite-cache")


def half_scenes(half):
    return {"tuning": list(TUNING), "validation": list(VALIDATION), "both": list(TUNING + VALIDATION)}[half]


def common(ap):
    ap.add_argument("--cache", default=DEFAULT_CACHE, help="the sample cache (default %(default)s)")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 8, 16, 32])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("cache", help="render references, films, samples, AOVs into the cache")
    common(c)
    c.add_argument("--half", choices=["tuning", "validation", "both"], default="both")
    c.add_argument("--scenes", nargs="+", choices=ss.SCENES)
    fx = sub.add_parser("fixtures", help="small sample sets + references for cargo test")
    fx.add_argument("--out", default="data/renders/suite")
    fx.add_argument("--resolution", type=int, default=48)
    fx.add_argument("--spp", type=int, nargs="+", default=[4, 8])
    fx.add_argument("--scenes", nargs="+", choices=ss.SCENES, default=["glass", "grazing", "emitter", "wires"])
    for name in ("score", "plan", "table"):
        p = sub.add_parser(name)
        common(p)
        p.add_argument("--rkwave", required=True, help="the rkwave binary")
        p.add_argument("--half", choices=["tuning", "validation", "both"], default="tuning")
        p.add_argument("--scenes", nargs="+", choices=ss.SCENES, help="instead of --half")
        p.add_argument("--extra", default="", help="flags added to reconstruct (score) or plan's first call")
        p.add_argument("--json", help="write every row to this file")
        p.add_argument("--workdir", default=f"/tmp/rkwave-suite-{os.getpid()}")
        p.add_argument("--seed", type=int, default=1, help="the plan's seed")
        if name == "plan":
            p.add_argument("--reuse", action="store_true",
                           help="re-run only the final image (reconstruct --state) on the plan states and samples a "
                                "previous plan run left in --workdir (same positions; --extra goes to reconstruct)")
            p.add_argument("--pixels", help="with --reuse: the final image's output pixels instead of the state's "
                                            "(blend, blend_gated, auto, shrunk, ...)")
        if name == "table":
            p.add_argument("--no-plan-spp", type=int, nargs="*", default=[],
                           help="spp at which the plan loop is skipped (time)")
    args = ap.parse_args()
    w = h = args.resolution
    if args.cmd == "fixtures":
        suite_cache.write_fixtures(args.out, args.scenes, w, h, args.spp, " ".join(["suite.py"] + sys.argv[1:]),
                                   log=lambda m: print(m, flush=True))
        return
    scenes = args.scenes or half_scenes(args.half)
    if args.cmd == "cache":
        for name in scenes:
            suite_cache.cache_scene(name, args.cache, w, h, args.spp, log=lambda m: print(m, flush=True))
        return
    import suite_score

    if args.cmd == "score":
        suite_score.score(args, scenes, w, h)
    elif args.cmd == "plan":
        suite_score.plan(args, scenes, w, h)
    else:
        suite_score.table(args, scenes, w, h)


if __name__ == "__main__":
    main()
