"""The uniform image path's speed on one sample file: `reconstruct --dim 2 --pixels auto|fit`
of each binary given, and the Gaussian film splat of the same samples, back to back.

The samples: `--size`² pixels, `--spp` stratified samples per pixel (a jittered `g_x x g_y`
grid in every pixel, as a renderer's), three channels of an analytic scene (`plan_loop.analytic`: a
smooth gradient, two discs with sharp edges, a thin line) plus Gaussian noise of standard deviation `--noise`
(seeded). They are written once as `.npy` (`m x 5`: x, y, r, g, b).

Per run it prints the wall time and the CPU time (user + system of the child process, from
`resource.getrusage`), and from the `--json` report the fit's stages. The splat runs through
the Python module (`rkwave.reconstruct_image(..., filter="gaussian")`, the library's
`image::splat`) when it is importable: CPU time of the call from `time.process_time`; the
module must be built from the same tree (`pip install ./python`). Without the module, or to
compare the splat of two trees, `--probe` (repeatable) runs the example `uniform_fit_probe` of
a tree (`cargo build --release --example uniform_fit_probe`, then
`target/release/examples/uniform_fit_probe`) with `ONLY=none`: it reads the file and times the
Gaussian splat alone (wall, in process).

    python benches/uniform_speed.py --bin target/release/rkwave --size 512 --spp 4
    python benches/uniform_speed.py --bin /old/rkwave --bin target/release/rkwave --repeat 2
    python benches/uniform_speed.py --bin OLD/rkwave --bin target/release/rkwave \
        --probe OLD/uniform_fit_probe --probe target/release/examples/uniform_fit_probe
"""

import argparse
import json
import os
import resource
import subprocess
import tempfile
import time

import numpy as np

from plan_loop import analytic as scene  # the same three-channel scene as the loop's


def strata(spp):
    """`(g_x, g_y)`: `g_x g_y = spp`, `g_x >= g_y`, as square as possible."""
    gy = int(np.sqrt(spp))
    while spp % gy:
        gy -= 1
    return spp // gy, gy


def samples(size, spp, noise, seed):
    """Stratified positions and noisy values, `m x 5`."""
    rng = np.random.default_rng(seed)
    gx, gy = strata(spp)
    px, py, sx, sy = np.meshgrid(
        np.arange(size), np.arange(size), np.arange(gx), np.arange(gy), indexing="ij"
    )
    px, py, sx, sy = (a.ravel() for a in (px, py, sx, sy))
    xs = px + (sx + rng.uniform(size=px.size)) / gx
    ys = py + (sy + rng.uniform(size=py.size)) / gy
    vals = scene(xs, ys, size, size) + noise * rng.standard_normal((xs.size, 3))
    return np.column_stack([xs, ys, vals])


def run(cmd):
    """Wall and CPU seconds of a child process and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, out


def stages(report):
    """The fit's stages from a `--json` report, as text."""
    solve = (report.get("solve") or {}).get("solve") or {}
    timings = solve.get("timings") or {}
    seconds = report.get("time_s") or {}
    parts = [f"{k} {seconds.get(k, 0):.2f}" for k in ("read", "fit", "pixels")]
    parts += [f"{k} {v:.2f}" for k, v in timings.items() if v]
    cg = solve.get("cg")
    if cg:
        parts.append(f"cg iterations {cg['iterations']}")
    pixels = report.get("pixels") or {}
    return f"method {report.get('method')} / {pixels.get('estimate')}; " + ", ".join(parts)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", action="append", required=True)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--pixels", default="auto,fit")
    ap.add_argument("--probe", action="append", default=[],
                    help="a uniform_fit_probe binary: times its Gaussian splat of the samples")
    ap.add_argument("--extra", default="", help="more flags for every reconstruct call")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="uniform_speed_")
    path = os.path.join(work, "samples.npy")
    data = samples(args.size, args.spp, args.noise, args.seed)
    np.save(path, data)
    print(f"{data.shape[0]} samples, {args.size}x{args.size}, load {os.getloadavg()[0]:.1f}")
    try:
        import rkwave
    except ImportError:
        rkwave = None
    for r in range(args.repeat):
        for b, binary in enumerate(args.bin):
            for pixels in args.pixels.split(","):
                out = os.path.join(work, f"out_{b}_{pixels}.npy")
                cmd = [binary, "reconstruct", "--dim", "2", "--input", path, "--resolution",
                       f"{args.size}x{args.size}", "--pixels", pixels, "--output", out,
                       "--force", "--json"] + args.extra.split()
                wall, cpu, text = run(cmd)
                print(f"[{r}] {binary} --pixels {pixels}: wall {wall:.2f} s, CPU {cpu:.2f} s; "
                      f"{stages(json.loads(text))}")
        for probe in args.probe:
            env = dict(os.environ, ONLY="none")
            out = subprocess.run([probe, path, str(args.size)], check=True, capture_output=True,
                                 text=True, env=env).stdout
            splat = next(line for line in out.splitlines() if line.startswith("splat:"))
            print(f"[{r}] gaussian splat ({probe}): {splat.split(':', 1)[1].strip()}")
        if rkwave is not None:
            t, c = time.perf_counter(), time.process_time()
            rkwave.reconstruct_image(data[:, :2], data[:, 2:], (args.size, args.size),
                                     filter="gaussian")
            print(f"[{r}] gaussian splat (python module): wall {time.perf_counter() - t:.2f} s, "
                  f"CPU {time.process_time() - c:.2f} s")
    print(f"load {os.getloadavg()[0]:.1f}; files in {work}")


if __name__ == "__main__":
    main()
