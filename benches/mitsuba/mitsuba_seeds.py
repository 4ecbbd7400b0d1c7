"""The per-pixel sampler seeds of Mitsuba 3's scalar `SamplingIntegrator::render`, so that the
harness's own one-sample-at-a-time renderer draws exactly the samples of `mi.render`.

Mitsuba (src/render/integrator.cpp, scalar variants) multiplies the user seed by the pixel
count, cuts the film into blocks of `block_size` (32, halved while there are fewer blocks
than threads) visited along a spiral (src/render/spiral.cpp, from block (nx/2, ny/2):
right 1, down 1, left 2, up 2, right 3, ..., skipping positions outside the grid), and in
block number `block_id` seeds the sampler of pixel `morton_decode(i)` with
`seed * W * H + block_id * block_size^2 + i` (uint32 arithmetic), then renders that pixel's
samples in turn. `pixel_seeds` returns that seed for every pixel as an (H, W) array.
"""

import os

import numpy as np


def block_size_for(w, h, threads=None):
    threads = threads or os.cpu_count() or 1
    b = 32
    while b > 1 and ((w + b - 1) // b) * ((h + b - 1) // b) < threads:
        b //= 2
    return b


def spiral_blocks(nx, ny):
    """Block positions (bx, by) in Mitsuba's spiral order."""
    pos = [nx // 2, ny // 2]
    out = [tuple(pos)]
    direction, steps_left, size = 0, 1, 1  # 0 right, 1 down, 2 left, 3 up
    while len(out) < nx * ny:
        while True:
            if direction == 0:
                pos[0] += 1
            elif direction == 1:
                pos[1] += 1
            elif direction == 2:
                pos[0] -= 1
            else:
                pos[1] -= 1
            steps_left -= 1
            if steps_left == 0:
                direction = (direction + 1) % 4
                if direction in (0, 2):
                    size += 1
                steps_left = size
            if 0 <= pos[0] < nx and 0 <= pos[1] < ny:
                break
        out.append(tuple(pos))
    return out


def _compact_bits(v):
    """The even bits of v, packed (Morton decoding of one coordinate)."""
    r = 0
    for k in range(16):
        r |= ((v >> (2 * k)) & 1) << k
    return r


def pixel_seeds(w, h, seed, threads=None):
    b = block_size_for(w, h, threads)
    nx, ny = (w + b - 1) // b, (h + b - 1) // b
    base = (seed * w * h) & 0xFFFFFFFF
    out = np.full((h, w), -1, dtype=np.int64)
    for block_id, (bx, by) in enumerate(spiral_blocks(nx, ny)):
        for i in range(b * b):
            x, y = _compact_bits(i), _compact_bits(i >> 1)
            px, py = bx * b + x, by * b + y
            if px < w and py < h:
                out[py, px] = (base + block_id * b * b + i) & 0xFFFFFFFF
    assert (out >= 0).all()
    return out
