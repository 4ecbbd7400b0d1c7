"""rkwave's pixel estimates (`reconstruct --dim 2 --pixels ...`) on the harness's real renders.

For every uniform sample set `harness.py` left in its work folders
(`{scene}-{W}x{W}-{spp}-samples.npy`: Mitsuba's multijitter samples, x, y in pixel units, r,
g, b) it runs the rkwave binary once per estimate — `fit` (the least-squares fit, the old
uniform output), `fit-clamped`, `box`, `shrunk` — and prints PSNR (relMSE, SSIM in `--json`)
against the cached 1024-spp reference, beside Mitsuba's own films from the harness's stored
results and the numpy prototype's shrinkage (`prototypes/noise_shrinkage.py`, cyclic shifts)
as an independent check of the Rust one. No renderer runs.

    /work/venv-mitsuba/bin/python benches/mitsuba/pixel_estimates.py \\
        --binary target/release/rkwave \\
        --workdir /tmp/rkwave-mitsuba-work /tmp/rkwave-mitsuba-work-thinlens
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "prototypes"))
from metrics import all_metrics, psnr  # noqa: E402

ESTIMATES = ["auto", "fit", "fit-clamped", "box", "shrunk"]
FILMS = ["box", "tent", "gaussian", "mitchell", "lanczos"]


def films(paths):
    """{(scene, spp): {film: psnr}} from the harness's stored result files."""
    out = {}
    for path in paths:
        with open(path) as f:
            for row in json.load(f)["rows"]:
                if row["method"].startswith("mitsuba "):
                    key = (row["scene"], row["spp"])
                    out.setdefault(key, {})[row["method"].split()[1]] = row["psnr"]
    return out


def run(binary, samples, width, estimate, scratch):
    out = os.path.join(scratch, f"{estimate}.npy")
    t0 = time.perf_counter()
    proc = subprocess.run(
        ["nice", "-n", "15", binary, "reconstruct", "--dim", "2", "--input", samples,
         "--resolution", f"{width}x{width}", "--output", out, "--force", "--json",
         "--pixels", estimate],
        capture_output=True, text=True,
    )
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{samples} --pixels {estimate}: {proc.stderr}")
    return np.load(out), json.loads(proc.stdout), dt


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--binary", default="target/release/rkwave")
    ap.add_argument("--workdir", nargs="+", default=["/tmp/rkwave-mitsuba-work"])
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/rkwave-mitsuba"))
    ap.add_argument("--results", nargs="+", default=sorted(glob.glob(os.path.join(HERE, "results", "128-*.json"))))
    ap.add_argument("--prototype", action="store_true", help="also the numpy prototype's shrinkage")
    ap.add_argument("--json", help="write every row here")
    args = ap.parse_args()
    film = films(args.results)
    rows = []
    cols = ["Mitsuba gaussian", "best film"] + [f"rkwave {e}" for e in ESTIMATES]
    cols += ["numpy prototype"] if args.prototype else []
    cols += ["shrunk − gaussian", "shrunk − best film", "sigma (r, g, b)"]
    print("| scene | spp | " + " | ".join(cols) + " |")
    print("|---" * (len(cols) + 2) + "|")
    # One set per (scene, size, spp); a later folder's copy replaces an earlier one.
    found = {}
    for d in args.workdir:
        for p in glob.glob(os.path.join(d, "*-samples.npy")):
            scene, size, spp = os.path.basename(p).split("-")[:3]
            found[(scene, int(spp), size)] = p
    for (scene, spp, size), path in sorted(found.items()):
        width = int(size.split("x")[0])
        refs = glob.glob(os.path.join(args.cache, f"ref-{scene}-{size}-1024spp-*.npy"))
        if not refs:
            continue
        ref = np.load(refs[0])
        got = {}
        with tempfile.TemporaryDirectory() as scratch:
            for e in ESTIMATES:
                image, report, dt = run(args.binary, path, width, e, scratch)
                m = all_metrics(image, ref)
                got[e] = m["psnr"]
                rows.append({"scene": scene, "spp": spp, "estimate": e, **m, "wall_s": dt,
                             "pixels": report.get("pixels")})
        sigma = rows[-1]["pixels"]["noise_level"]
        f = film.get((scene, spp), {})
        best = max(f.values()) if f else float("nan")
        gauss = f.get("gaussian", float("nan"))
        cells = [f"{gauss:.2f}", f"{best:.2f} ({max(f, key=f.get) if f else '?'})"]
        cells += [f"{got[e]:.2f}" for e in ESTIMATES]
        if args.prototype:
            from noise_shrinkage import box_and_variance, shrink
            box, var = box_and_variance(np.load(path), width)
            cells.append(f"{psnr(shrink(box, var, 'universal'), ref):.2f}")
        cells += [f"{got['shrunk'] - gauss:+.2f}", f"{got['shrunk'] - best:+.2f}",
                  ", ".join(f"{s:.2g}" for s in sigma)]
        print(f"| {scene} | {spp} | " + " | ".join(cells) + " |", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"command": " ".join(sys.argv), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
