"""Replay driver of the renderer loop: `rkwave plan` answered by a scene in this process.

No renderer: each round's positions are answered by an analytic scene (a smooth gradient,
two discs with sharp edges and a thin line, three channels, plus Gaussian noise) or by a
stored image (`--reference H x W x C .npy`: the value of the pixel a position falls in, plus
noise). The noise of round `r` is drawn from a generator seeded by `r`, so two binaries that
hand out the same positions get the same answers.

Per call it prints the wall time (process start and files included) and, from the call's
`--json` report, the fit's stages: kernel rows, normal matrix (assembly or update) with the
functions/samples carried over, factor + solve; then the total of the loop (every `plan`
call, the stopping one writing the final image with `--final-image`), the renderer's time
excluded, with the CPU seconds (user + system, system apart) and the peak resident memory of
the largest call (`wait4` of each call). `--psnr` adds the final image's PSNR against the
scene's box pixels; `--solver NAME` starts the plan with `--solver NAME`. With several
`--bin`, the binaries run back to back (alternating over `--repeat`) and the SHA-256 of every
positions file and of the final image are compared between them. `--protocol new` drives the
plan with each round's new samples alone (`--new-samples`, the plan keeping the earlier ones in
its folder) instead of every sample so far (`--protocol all`, the default); given both, each
binary runs both (alternating) and the outputs of every variant are compared.

    python benches/plan_loop.py --bin target/release/rkwave --size 128 --spp 8 --psnr
    python benches/plan_loop.py --bin /tmp/old/rkwave --bin target/release/rkwave --size 128
    python benches/plan_loop.py --bin target/release/rkwave --protocol all --protocol new
"""

import argparse
import hashlib
import json
import os
import subprocess
import tempfile
import time

import numpy as np


def analytic(xs, ys, width, height):
    """Three channels of a scene with smooth parts, edges and a thin feature."""
    u, v = xs / width, ys / height
    smooth = 0.3 + 0.2 * np.sin(3.0 * u) * np.cos(2.0 * v)
    disc1 = ((u - 0.35) ** 2 + (v - 0.4) ** 2 < 0.04).astype(float)
    disc2 = ((u - 0.7) ** 2 + (v - 0.65) ** 2 < 0.015).astype(float)
    line = (np.abs(u + 0.5 * v - 0.9) < 0.004).astype(float)
    return np.stack(
        [smooth + 0.5 * disc1 + line, smooth + 0.4 * disc2, 0.6 * smooth + 0.3 * disc1 * v], axis=1
    )


def answer(positions, round_, args, reference):
    xs, ys = positions[:, 0], positions[:, 1]
    if reference is None:
        vals = analytic(xs, ys, args.size, args.size)
    else:
        h, w = reference.shape[:2]
        ix = np.clip(xs.astype(int), 0, w - 1)
        iy = np.clip(ys.astype(int), 0, h - 1)
        vals = reference[iy, ix].reshape(len(xs), -1)
    rng = np.random.default_rng(1000 + round_)
    vals = vals + args.noise * rng.standard_normal(vals.shape)
    return np.hstack([positions, vals])


def sha(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


CPU = [0.0]
SYS = [0.0]
PEAK = [0]


def run(cmd):
    """Runs `cmd`; its wall seconds (its CPU seconds, user + system, added to CPU[0], its
    peak resident memory folded into PEAK[0])."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(proc.pid, 0)
        dt = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        CPU[0] += usage.ru_utime + usage.ru_stime
        SYS[0] += usage.ru_stime
        PEAK[0] = max(PEAK[0], usage.ru_maxrss * 1024)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err.read()}")
        return out.read(), dt


PHASES = {}


def phases(step, wall):
    """Adds one call's seconds by phase (its `--json`: the round's own timers) to PHASES."""
    log = step.get("log") or {}
    if "times" not in log:
        return  # a binary without the round's timers
    fit, times = log.get("fit") or {}, log.get("times") or {}
    round_s = step.get("round_s", 0.0)
    parts = {
        "fit: single-scale rows and exact diagonal (kernel_s)": fit.get("kernel_s", 0.0),
        "fit: PCG iterations, image and probe channels (solve_s)": fit.get("solve_s", 0.0),
        "fit: probe values, noise test residuals (fit_s - kernel_s - solve_s)":
            times.get("fit_s", 0.0) - fit.get("kernel_s", 0.0) - fit.get("solve_s", 0.0),
        "indicator": times.get("indicator_s", 0.0),
        "stop test, tally, marking": times.get("refine_s", 0.0) - times.get("indicator_s", 0.0),
        "deepening and next positions": times.get("position_s", 0.0),
        "stopping round: fit continued to the solver's tolerance":
            times.get("final_fit_s", 0.0),
        "stopping round: final image's output pixels": step.get("image_s", 0.0),
        "matching the samples to the rounds, the rest of the state machine":
            round_s - times.get("fit_s", 0.0) - times.get("refine_s", 0.0)
            - times.get("position_s", 0.0) - times.get("final_fit_s", 0.0)
            - step.get("image_s", 0.0),
        "outside the state machine: process, loading the state, reading the samples, "
        "committing, JSON (wall - round_s)": wall - round_s,
    }
    for k, v in parts.items():
        PHASES[k] = PHASES.get(k, 0.0) + v


def mitsuba_time(size, spp, repeat):
    """Mitsuba 3 `scalar_rgb` rendering its Cornell box (`mi.cornell_box()`, the film resized to
    `size x size`) at `spp`: one warm-up render at 1 spp, then `repeat` timed ones; prints each
    render's wall and CPU seconds (this process's)."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    scene = mi.cornell_box()
    scene["sensor"]["film"]["width"] = size
    scene["sensor"]["film"]["height"] = size
    scene = mi.load_dict(scene)
    mi.render(scene, spp=1)
    for rep in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        mi.render(scene, spp=spp, seed=rep)
        print(f"mitsuba scalar_rgb cornell box {size}x{size} {spp} spp: wall "
              f"{time.perf_counter() - t0:.3f} s, CPU {time.process_time() - c0:.3f} s, load "
              f"{os.getloadavg()[0]:.2f}")


def truth(size, supersample=8):
    """The analytic scene's box pixels (`size x size x 3`), by `supersample^2` midpoints a
    pixel (exact on the smooth part to O(1/supersample^2); an edge pixel's coverage to
    O(1/supersample))."""
    n = supersample
    offsets = (np.arange(n) + 0.5) / n
    out = np.zeros((size, size, 3))
    for row in range(size):
        ys = row + np.repeat(offsets, n * size)
        xs = np.tile((np.arange(size)[:, None] + offsets[None, :]).reshape(-1), n)
        vals = analytic(xs, ys, size, size).reshape(n, size, n, 3)
        out[row] = vals.mean(axis=(0, 2))
    return out


def psnr(image, reference):
    """`10 log10(1 / MSE)` over every pixel and channel (peak 1, as `rkwave`'s metrics)."""
    mse = np.mean((image.reshape(reference.shape) - reference) ** 2)
    return 10.0 * np.log10(1.0 / mse)


def loop(binary, args, reference, work, protocol="all"):
    """One whole loop, each round given every sample so far (`protocol` "all") or its new
    samples alone ("new"); returns (total wall seconds, CPU seconds, per-call rows, hashes)."""
    cpu0, sys0 = CPU[0], SYS[0]
    PHASES.clear()
    state = os.path.join(work, "state")
    pos = os.path.join(work, "next.npy")
    allp = os.path.join(work, "all.npy")
    newp = os.path.join(work, "new.npy")
    final = os.path.join(work, "final.npy")
    res = f"{args.size}x{args.size}"
    prefix = ["nice", "-n", str(args.nice)] if args.nice else []
    solver = ["--solver", args.solver] if args.solver else []
    out, dt = run(prefix + [binary, "plan", "--state", state, "--resolution", res, "--spp",
                            str(args.spp), "--out", pos, "--force", "--json"] + solver)
    rows = [("start", 0, 0, dt, None)]
    hashes = [sha(pos)]
    samples = None
    round_ = 0
    while True:
        p = np.load(pos).reshape(-1, 2)
        if len(p) == 0:
            break
        round_ += 1
        new = answer(p, round_, args, reference)
        samples = new if samples is None else np.vstack([samples, new])
        if protocol == "new":
            np.save(newp, new)
            given = ["--new-samples", newp]
        else:
            np.save(allp, samples)
            given = ["--samples", allp]
        out, dt = run(prefix + [binary, "plan", "--state", state] + given + [
            "--out", pos, "--final-image", final, "--force", "--json"])
        if args.keep:
            with open(os.path.join(work, f"call{round_}.json"), "w") as f:
                f.write(out)
        step = json.loads(out).get("step") or {}
        fit = (step.get("log") or {}).get("fit") or {}
        phases(step, dt)
        rows.append((f"round {round_}", len(samples), fit.get("functions", 0), dt, fit))
        last = json.loads(out)
        hashes.append(sha(pos))
    if not os.path.exists(final):
        np.save(allp, samples)
        # 0 positions handed out without a stop: the final image by reconstruct --state
        out, dt = run(prefix + [binary, "reconstruct", "--dim", "2", "--state", state, "--input",
                                allp, "--output", final, "--force", "--json"])
        rows.append(("reconstruct --state (0 positions, no stop)", len(samples), 0, dt, None))
    hashes.append(sha(final))
    return sum(r[3] for r in rows), (CPU[0] - cpu0, SYS[0] - sys0), rows, hashes


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", action="append", required=True, help="rkwave binary (repeatable)")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--reference", help="H x W x C .npy image answering the positions")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--nice", type=int, default=0, help="run rkwave under nice -n N")
    ap.add_argument("--keep", help="run in this folder and keep its files (one binary, one repeat)")
    ap.add_argument("--quiet", action="store_true", help="totals only")
    ap.add_argument("--solver", help="pass `--solver NAME` to the plan's first call")
    ap.add_argument("--mitsuba", action="store_true",
                    help="first time Mitsuba 3 (scalar_rgb) rendering its Cornell box at the "
                         "same size and spp, --repeat times (needs the mitsuba module)")
    ap.add_argument("--phases", action="store_true",
                    help="per loop, the seconds by phase from each call's --json (the round's "
                         "own timers; needs a binary that reports them)")
    ap.add_argument("--protocol", action="append", choices=["all", "new"],
                    help="how each round's samples are given: every sample so far (all, the "
                         "default) or the new ones alone (new, --new-samples); repeatable")
    ap.add_argument("--psnr", action="store_true",
                    help="the final image's PSNR against the scene's box pixels (the analytic "
                         "scene supersampled 8 x 8 a pixel, or the --reference image)")
    args = ap.parse_args()
    protocols = args.protocol or ["all"]
    variants = [(b, p) for b in args.bin for p in protocols]
    label = {v: v[0] if len(protocols) == 1 else f"{v[0]} [{v[1]}]" for v in variants}
    reference = None
    if args.reference:
        reference = np.load(args.reference)
        args.size = reference.shape[1]
    print(f"# {args.size}x{args.size}, {args.spp} spp, load {os.getloadavg()[0]:.2f}")
    if args.mitsuba:
        mitsuba_time(args.size, args.spp, args.repeat)
    totals = {label[v]: [] for v in variants}
    cpus = {label[v]: [] for v in variants}
    peaks = {label[v]: [] for v in variants}
    psnrs = {label[v]: [] for v in variants}
    exact = None
    if args.psnr:
        exact = reference if reference is not None else truth(args.size)
    hashes = {}
    for rep in range(args.repeat):
        for v in variants:
            binary, protocol = v
            b = label[v]
            PEAK[0] = 0
            if args.keep:
                os.makedirs(args.keep, exist_ok=True)
                total, cpu, rows, h = loop(binary, args, reference, args.keep, protocol)
                final = np.load(os.path.join(args.keep, "final.npy")) if args.psnr else None
            else:
                with tempfile.TemporaryDirectory() as work:
                    total, cpu, rows, h = loop(binary, args, reference, work, protocol)
                    final = np.load(os.path.join(work, "final.npy")) if args.psnr else None
            if final is not None:
                psnrs[b].append(psnr(final, exact))
            peaks[b].append(PEAK[0])
            totals[b].append(total)
            cpus[b].append(cpu)
            hashes.setdefault(b, h)
            if args.quiet:
                continue
            print(f"## {b} (repeat {rep + 1})")
            print("| call | samples | functions | wall (s) | kernel (s) | normal (s) | kept f/s "
                  "| solve (s) |")
            print("|---|---:|---:|---:|---:|---:|---:|---:|")
            for name, m, p, dt, fit in rows:
                if fit:
                    kept = f"{fit.get('normal_kept_functions', 0)}/{fit.get('normal_kept_samples', 0)}"
                    print(f"| {name} | {m} | {p} | {dt:.2f} | {fit.get('kernel_s', 0):.2f} | "
                          f"{fit.get('normal_s', 0):.2f} | {kept} | {fit.get('solve_s', 0):.2f} |")
                else:
                    print(f"| {name} | | | {dt:.2f} | | | | |")
            print(f"| **total** | | | **{total:.2f}** | | | | |")
            print(f"CPU seconds (user + system, all threads): {cpu[0]:.2f} (system {cpu[1]:.2f})")
            if args.phases and PHASES:
                print("| phase (wall s, summed over the calls) | s | share |")
                print("|---|---:|---:|")
                whole = sum(PHASES.values())
                for k, v in PHASES.items():
                    print(f"| {k} | {v:.3f} | {100 * v / whole:.0f} % |")
    print(f"# load {os.getloadavg()[0]:.2f}")
    names = [label[v] for v in variants]
    for b in names:
        ts = totals[b]
        print(f"total {b}: wall " + ", ".join(f"{t:.2f}" for t in ts) + f" s (min {min(ts):.2f}); "
              "CPU " + ", ".join(f"{t:.2f} (sys {u:.2f})" for t, u in cpus[b]) + " s; peak "
              + ", ".join(f"{m / 1e9:.2f}" for m in peaks[b]) + " GB"
              + ("; final PSNR " + ", ".join(f"{v:.2f}" for v in psnrs[b]) + " dB"
                 if psnrs[b] else ""))
    if len(names) > 1:
        first = hashes[names[0]]
        for b in names[1:]:
            same = hashes[b] == first
            print(f"outputs of {b} {'identical to' if same else 'DIFFER from'} {names[0]} "
                  f"({len(first)} files: positions per call and the final image)")
            if not same:
                positions = hashes[b][:-1] == first[:-1]
                print(f"  positions of every call {'identical' if positions else 'DIFFER'}; "
                      f"final image {'identical' if hashes[b][-1] == first[-1] else 'differs'}")


if __name__ == "__main__":
    main()
