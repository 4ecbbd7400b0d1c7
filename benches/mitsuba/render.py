"""Radiance from Mitsuba at film positions, one sample at a time (variant `scalar_rgb`).

Every sample follows the steps of Mitsuba's `SamplingIntegrator::render_sample`: a 2D
sample for the film position, a 2D sample for the aperture (thin lens only),
`sensor.sample_ray_differential(time, wavelength, film_position / size, aperture)`, the
differentials scaled by `1 / sqrt(spp)`, then `integrator.sample(scene, sampler, ray)`
and the ray weight applied.

Samplers: each pixel's samples come from Mitsuba's `multijitter` sampler with
`sample_count` = the number of samples that pixel gets in this batch, seeded per
(batch seed, pixel). Where the caller gives the film positions (rkwave's plan), the
sampler's film dimension is drawn and discarded so that the aperture and path dimensions
are the same stratified ones a Mitsuba render would use; where it does not (uniform and
the Cycles-style sampler), the film position is `pixel + sampler.next_2d()`, exactly
Mitsuba's own positions.

Positions are in pixel units, x right and y down, pixel (i, j) = [i, i+1) x [j, j+1),
the convention of `rkwave plan` and `rkwave reconstruct --dim 2`.
"""

import math
import time

import mitsuba as mi
import numpy as np


class Renderer:
    """One loaded scene, answering radiance at film positions."""

    def __init__(self, scene):
        self.scene = scene
        self.sensor = scene.sensors()[0]
        self.integrator = scene.integrator()
        self.width, self.height = (int(v) for v in self.sensor.film().size())
        self.needs_aperture = bool(self.sensor.needs_aperture_sample())
        self.sampler = mi.load_dict({"type": "multijitter", "sample_count": 4})
        self.seconds = 0.0  # time spent rendering, summed over calls
        self.samples = 0

    def _one(self, fx, fy, diff_scale):
        s = self.sampler
        ap = s.next_2d() if self.needs_aperture else mi.Point2f(0.5, 0.5)
        ray, weight = self.sensor.sample_ray_differential(
            0.0, 0.0, mi.Point2f(fx / self.width, fy / self.height), ap
        )
        ray.scale_differential(diff_scale)
        L, _, _ = self.integrator.sample(self.scene, s, ray)
        s.advance()
        return (L[0] * weight[0], L[1] * weight[1], L[2] * weight[2])

    def render_pixels(self, counts, seed):
        """`counts[j, i]` samples in pixel (i, j), positions from the sampler.
        Returns an `m x 5` array (x, y, r, g, b)."""
        t0 = time.perf_counter()
        rows = []
        h, w = counts.shape
        for j in range(h):
            for i in range(w):
                n = int(counts[j, i])
                if n == 0:
                    continue
                self._seed(seed, j * w + i, n)
                scale = 1.0 / math.sqrt(n)
                for _ in range(n):
                    p = self.sampler.next_2d()
                    x, y = i + p[0], j + p[1]
                    rows.append((x, y, *self._one(x, y, scale)))
        self.seconds += time.perf_counter() - t0
        self.samples += len(rows)
        return np.asarray(rows, dtype=np.float64).reshape(-1, 5)

    def render_positions(self, positions, seed, spp_hint):
        """Radiance at the given `n x 2` positions; returns `n x 5`, in the given order."""
        t0 = time.perf_counter()
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        out = np.empty((len(pos), 5))
        out[:, :2] = pos
        px = np.clip(np.floor(pos[:, 0]).astype(np.int64), 0, self.width - 1)
        py = np.clip(np.floor(pos[:, 1]).astype(np.int64), 0, self.height - 1)
        pix = py * self.width + px
        order = np.argsort(pix, kind="stable")
        starts = np.flatnonzero(np.r_[True, pix[order][1:] != pix[order][:-1]])
        ends = np.r_[starts[1:], len(order)]
        scale = 1.0 / math.sqrt(max(spp_hint, 1))
        for a, b in zip(starts, ends):
            self._seed(seed, int(pix[order[a]]), int(b - a))
            for k in order[a:b]:
                self.sampler.next_2d()  # the film dimension: the position is given
                out[k, 2:] = self._one(pos[k, 0], pos[k, 1], scale)
        self.seconds += time.perf_counter() - t0
        self.samples += len(pos)
        return out

    def _seed(self, seed, pixel, n):
        self.sampler.set_sample_count(n)
        self.sampler.seed((seed * 1_000_003 + pixel) & 0xFFFFFFFF)
