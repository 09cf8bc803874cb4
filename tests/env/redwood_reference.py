"""A per-pixel reference of habitat-sim's Redwood depth noise, for tests only: a plain loop written from
habitat-sim ``src_python/habitat_sim/sensors/noise_models/redwood_depth_noise_model.py`` (``_simulate``,
``_undistort``), kept apart from navbench's vectorised version so each checks the other."""

from __future__ import annotations

import numpy as np


def _undistort(x: int, y: int, z: float, model: np.ndarray) -> float:
    i2 = int((z + 1) / 2)
    i1 = i2 - 1
    a = (z - (i1 * 2.0 + 1.0)) / 2.0
    col, row = x // 8, y // 6
    f = (1.0 - a) * model[row, col, min(max(i1, 0), 4)] + a * model[row, col, min(i2, 4)]
    return 0.0 if f < 1e-5 else z / f


def simulate(gt_depth: np.ndarray, model: np.ndarray, multiplier: float, rng: np.random.Generator) -> np.ndarray:
    h, w = gt_depth.shape
    ymax, xmax = h - 1.0, w - 1.0
    rand = rng.standard_normal((h, w, 3)).astype(np.float32)
    out = np.empty_like(gt_depth, dtype=np.float64)
    for j in range(h):
        for i in range(w):
            y = int(min(max(j + rand[j, i, 0] * 0.25 * multiplier, 0.0), ymax) + 0.5)
            x = int(min(max(i + rand[j, i, 1] * 0.25 * multiplier, 0.0), xmax) + 0.5)
            d = float(gt_depth[y - y % 2, x - x % 2])
            if d >= 10.0:
                out[j, i] = 0.0
                continue
            und = _undistort(int(x / xmax * 639.0 + 0.5), int(y / ymax * 479.0 + 0.5), d, model)
            if und == 0.0:
                out[j, i] = 0.0
                continue
            denom = round((35.130 / und + rand[j, i, 2] * 0.027778 * multiplier) * 8.0)
            out[j, i] = 0.0 if denom <= 1e-5 else 35.130 * 8.0 / denom
    return out
