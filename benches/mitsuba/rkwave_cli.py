"""rkwave driven through its command line: `reconstruct --dim 2` and the `plan` loop.

Each call's wall time (process start, reading and writing files included) is summed in
`seconds`; the renderer's time is kept apart by the caller.
"""

import json
import os
import subprocess
import time

import numpy as np


def _npy_image(path):
    img = np.load(path)
    assert img.ndim == 3, f"{path}: expected (H, W, C), got {img.shape}"
    return img


class Rkwave:
    def __init__(self, binary, workdir, nice=True):
        self.binary = binary
        self.workdir = workdir
        self.prefix = ["nice", "-n", "19"] if nice else []
        os.makedirs(workdir, exist_ok=True)

    def _run(self, args):
        t0 = time.perf_counter()
        proc = subprocess.run(self.prefix + [self.binary] + args, capture_output=True, text=True)
        dt = time.perf_counter() - t0
        if proc.returncode != 0:
            raise RuntimeError(f"rkwave {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr}")
        return proc.stdout, dt

    def uniform(self, samples, width, height, tag, pixels=None):
        """`rkwave reconstruct --dim 2` of an `m x 5` sample array (the default pixel estimate,
        or `--pixels PIXELS`); (image, seconds, the estimate used as the report names it)."""
        inp = os.path.join(self.workdir, f"{tag}-samples.npy")
        out = os.path.join(self.workdir, f"{tag}-uniform-{pixels or 'default'}.npy")
        np.save(inp, np.ascontiguousarray(samples, dtype=np.float64))
        extra = ["--pixels", pixels] if pixels else []
        stdout, dt = self._run(
            ["reconstruct", "--dim", "2", "--input", inp, "--resolution", f"{width}x{height}",
             "--output", out, "--force", "--json"] + extra
        )
        used = (json.loads(stdout).get("pixels") or {}).get("estimate", "fit")
        return _npy_image(out), dt, used

    def adaptive(self, render_positions, width, height, spp, tag, seed=1, max_rounds=64,
                 extra=()):
        """The `rkwave plan` loop: plan writes positions, the renderer answers, until plan
        writes 0 rows; the call that stops the plan writes the final image (`--final-image`,
        the stopping round's fit: no `reconstruct --dim 2 --state`, which would fit every
        sample again). `extra`: more flags for the first call (the plan's parameters).
        Returns (image, samples, rkwave seconds, rounds)."""
        state = os.path.join(self.workdir, f"{tag}-plan")
        pos = os.path.join(self.workdir, f"{tag}-positions.npy")
        allp = os.path.join(self.workdir, f"{tag}-all.npy")
        out = os.path.join(self.workdir, f"{tag}-adaptive.npy")
        res = f"{width}x{height}"
        seconds = 0.0
        _, dt = self._run(["plan", "--state", state, "--resolution", res, "--spp", str(spp),
                           "--seed", str(seed), "--out", pos, "--force", *extra])
        seconds += dt
        samples = np.zeros((0, 5))
        rounds = 0
        while True:
            p = np.load(pos).reshape(-1, 2)
            if len(p) == 0:
                break
            rounds += 1
            if rounds > max_rounds:
                raise RuntimeError(f"plan did not stop after {max_rounds} rounds")
            samples = np.vstack([samples, render_positions(p, 1000 + rounds)])
            np.save(allp, samples)
            _, dt = self._run(["plan", "--state", state, "--samples", allp, "--out", pos,
                               "--final-image", out, "--force"])
            seconds += dt
        return _npy_image(out), samples, seconds, rounds
