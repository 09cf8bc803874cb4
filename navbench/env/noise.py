"""Habitat's realistic conditions: PyRobot actuation noise, Redwood depth noise and Gaussian RGB noise.

Each is sampled as habitat-sim samples it, from a generator the env seeds per episode:

- actuation: habitat-sim ``src_python/habitat_sim/agent/controls/pyrobot_noisy_controls.py`` (models
  contributed from PyRobot, https://pyrobot.org; please cite PyRobot when you use them);
- depth: habitat-sim ``src_python/habitat_sim/sensors/noise_models/redwood_depth_noise_model.py`` with its
  ``data/redwood-depth-dist-model.npy`` (vendored under ``configs/noise/``, MIT, with its attribution);
- RGB: habitat-sim ``src_python/habitat_sim/sensors/noise_models/gaussian_noise_model.py`` (and
  ``speckle_noise_model.py``, ``poisson_noise_model.py``, ``salt_and_pepper_noise_model.py``).

    >>> m = ACTUATION_MODELS["LoCoBot-ILQR"]
    >>> m.linear.mean, m.linear.var
    ((0.014, 0.009, 0.008), (0.006, 0.005, 0.004))
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.special import ndtr, ndtri

from navbench.env.config import ACTUATION_NOISE
from navbench.paths import CONFIGS_DIR

REDWOOD_MODEL = CONFIGS_DIR / "noise" / "redwood-depth-dist-model.npy"


@dataclass(frozen=True)
class MotionNoise:
    """One motion's noise: means and variances of (forward, lateral, yaw) in metres and radians. Upstream
    lists a (translation) and a (rotation) Gaussian per motion, each with means then variances."""
    mean: tuple[float, float, float]
    var: tuple[float, float, float]


@dataclass(frozen=True)
class ActuationModel:
    linear: MotionNoise  # MOVE_FORWARD
    rotational: MotionNoise  # TURN_LEFT / TURN_RIGHT


def _model(lin: tuple[float, ...], rot: tuple[float, ...]) -> ActuationModel:
    """Upstream's numbers in its order: (fwd mean, lat mean, fwd var, lat var, yaw mean, yaw var)."""
    return ActuationModel(MotionNoise((lin[0], lin[1], lin[4]), (lin[2], lin[3], lin[5])),
                          MotionNoise((rot[0], rot[1], rot[4]), (rot[2], rot[3], rot[5])))


# pyrobot_noise_models of pyrobot_noisy_controls.py, keyed "<robot>-<controller>".
ACTUATION_MODELS: dict[str, ActuationModel] = {
    "LoCoBot-ILQR": _model((0.014, 0.009, 0.006, 0.005, 0.008, 0.004), (0.003, 0.003, 0.002, 0.003, 0.023, 0.012)),
    "LoCoBot-Proportional": _model((0.017, 0.042, 0.007, 0.023, 0.031, 0.026),
                                   (0.001, 0.005, 0.001, 0.004, 0.043, 0.017)),
    "LoCoBot-Movebase": _model((0.074, 0.036, 0.019, 0.033, 0.189, 0.038), (0.002, 0.003, 0.0, 0.002, 0.219, 0.019)),
    "LoCoBot-Lite-ILQR": _model((0.142, 0.023, 0.008, 0.008, 0.031, 0.028), (0.002, 0.002, 0.001, 0.002, 0.122, 0.03)),
    "LoCoBot-Lite-Proportional": _model((0.135, 0.043, 0.007, 0.009, 0.049, 0.009),
                                        (0.002, 0.002, 0.002, 0.001, 0.054, 0.061)),
    "LoCoBot-Lite-Movebase": _model((0.192, 0.117, 0.055, 0.144, 0.128, 0.143),
                                    (0.002, 0.001, 0.001, 0.001, 0.173, 0.025)),
}

assert tuple(ACTUATION_MODELS) == ACTUATION_NOISE

SIGMAS = 3.0  # every draw is truncated at +-3 standard deviations
FLOOR = 0.95  # forward translation and turn rotation never undo more than 95% of the commanded amount


def truncation(mean: float, std: float, lower: float | None = None) -> tuple[float, float]:
    """The standardised bounds (a, b) of a draw: +-3 sigma, the lower one raised to ``lower`` if given."""
    a, b = -SIGMAS, SIGMAS
    if lower is not None and std > 0:
        a = max((lower - mean) / std, a)
    return a, b


def truncated_normal(rng: np.random.Generator, mean: float, std: float, lower: float | None = None) -> float:
    """One draw of N(mean, std^2) truncated to ``truncation`` (inverse CDF; a zero std gives the mean)."""
    if std <= 0:
        return float(mean)
    a, b = truncation(mean, std, lower)
    pa, pb = float(ndtr(a)), float(ndtr(b))
    return float(mean + std * ndtri(pa + rng.random() * (pb - pa)))


def sample_motion(model: ActuationModel, forward: float, turn: float, multiplier: float,
                  rng: np.random.Generator) -> tuple[float, float, float]:
    """The motion one noisy action makes, in the agent's frame before it: (forward m, right m, yaw rad, left
    positive). ``forward`` is the commanded translation (0 for a turn), ``turn`` the commanded rotation in
    radians (0 for a forward step), as upstream's ``_noisy_action_impl`` takes them."""
    rotational = turn != 0.0
    motion = model.rotational if rotational else model.linear
    std = [math.sqrt(v) for v in motion.var]  # upstream lists variances
    # translation: forward bounded below by -0.95 x the commanded amount (a forward step always moves)
    lower = None if rotational else -FLOOR * abs(forward)
    fwd = multiplier * truncated_normal(rng, motion.mean[0], std[0], lower)
    lat = multiplier * truncated_normal(rng, motion.mean[1], std[1])
    sign = 1.0 if forward + 1e-8 >= 0 else -1.0  # np.sign(x + 1e-8): noise overshoots in the commanded direction
    fwd, lat = sign * fwd, sign * lat
    # rotation: bounded below by -0.95 x the commanded turn (a turn always turns)
    yaw = multiplier * truncated_normal(rng, motion.mean[2], std[2], -FLOOR * abs(turn) if rotational else None)
    yaw *= 1.0 if turn + 1e-8 >= 0 else -1.0
    return forward + fwd, lat, turn + yaw


# ------------------------------------------------------------------------------------------- sensors
@lru_cache(maxsize=1)
def redwood_model() -> np.ndarray:
    """The Redwood depth distortion model, (80, 80, 5) float32: a multiplicative factor per image cell
    (80 rows of 6 pixels by 80 columns of 8 pixels of a 640x480 sensor) at depths 1, 3, 5, 7, 9 m."""
    return np.load(REDWOOD_MODEL).reshape(80, 80, 5)


def redwood_depth(depth_m: np.ndarray, multiplier: float, rng: np.random.Generator) -> np.ndarray:
    """Redwood depth noise on an (H, W) depth image in metres; a dropped pixel (10 m and beyond, or a
    disparity of zero) is 0. Each pixel reads a jittered, 2x-downsampled neighbour, distorted by the model
    at its place and depth, then quantised in disparity (8 steps per unit of 35.130 / depth)."""
    model = redwood_model()
    h, w = depth_m.shape
    ymax, xmax = h - 1.0, w - 1.0
    # upstream draws float64 normals, keeps them as float32 and computes with them in float64
    r = rng.standard_normal((3, h, w)).astype(np.float32).astype(np.float64)
    j, i = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    y = (np.clip(j + r[0] * 0.25 * multiplier, 0.0, ymax) + 0.5).astype(np.int64)
    x = (np.clip(i + r[1] * 0.25 * multiplier, 0.0, xmax) + 0.5).astype(np.int64)
    d = depth_m[y - y % 2, x - x % 2].astype(np.float64)
    # distortion, indexed as if the sensor were 640x480 (the model's own)
    mx = (x / xmax * 639.0 + 0.5).astype(np.int64) // 8
    my = (y / ymax * 479.0 + 0.5).astype(np.int64) // 6
    i2 = ((d + 1.0) / 2.0).astype(np.int64)
    i1 = i2 - 1
    a = (d - (i1 * 2.0 + 1.0)) / 2.0
    f = (1.0 - a) * model[my, mx, np.clip(i1, 0, 4)] + a * model[my, mx, np.minimum(i2, 4)]
    with np.errstate(divide="ignore", invalid="ignore"):
        undistorted = np.where(f < 1e-5, 0.0, d / np.where(f < 1e-5, 1.0, f))
        denom = np.rint((35.130 / np.where(undistorted == 0.0, 1.0, undistorted) + r[2] * 0.027778 * multiplier)
                        * 8.0)
        noisy = np.where(denom <= 1e-5, 0.0, 35.130 * 8.0 / np.where(denom <= 1e-5, 1.0, denom))
    noisy[(undistorted == 0.0) | (d >= 10.0)] = 0.0
    return noisy.astype(np.float32)


def gaussian_rgb(rgb: np.ndarray, intensity: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise on a uint8 image: N(0, 1) x ``intensity`` per channel in [0, 1] units, clipped,
    truncated back to uint8 (habitat-sim's intensity_constant, mean 0, sigma 1)."""
    noise = rng.standard_normal(rgb.shape) * intensity
    return (np.clip(rgb / 255.0 + noise, 0.0, 1.0) * 255.0).astype(np.uint8)


def speckle_rgb(rgb: np.ndarray, intensity: float, rng: np.random.Generator) -> np.ndarray:
    """Speckle noise: each channel value in [0, 1] units times (1 + N(0, 1) x ``intensity``), clipped, to uint8."""
    img = rgb / 255.0
    return (np.clip(img + img * rng.standard_normal(rgb.shape) * intensity, 0.0, 1.0) * 255.0).astype(np.uint8)


def poisson_rgb(rgb: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Poisson noise: with V the image's count of distinct values rounded up to a power of two, each value x
    in [0, 1] units becomes Poisson(x V) / V, clipped, to uint8."""
    img = rgb / 255.0
    values = 2.0 ** np.ceil(np.log2(len(np.unique(img))))
    return (np.clip(rng.poisson(img * values) / values, 0.0, 1.0) * 255.0).astype(np.uint8)


def salt_and_pepper_rgb(rgb: np.ndarray, rng: np.random.Generator, amount: float = 0.05,
                        salt_vs_pepper: float = 0.5) -> np.ndarray:
    """Salt-and-pepper noise with upstream's defaults and its quirks kept: ``ceil(amount x size x s)`` salt
    and as many pepper draws, each index drawn in [0, dim - 1) (never the last row, column or channel), and
    salt written as the value 1, as upstream writes it into a uint8 image."""
    out = rgb.copy()
    for count, value in ((math.ceil(amount * rgb.size * salt_vs_pepper), 1),
                         (math.ceil(amount * rgb.size * (1.0 - salt_vs_pepper)), 0)):
        idx = tuple(rng.integers(0, max(n - 1, 1), int(count)) for n in rgb.shape)
        out[idx] = value
    return out


def rgb_noise(rgb: np.ndarray, model: str, intensity: float, rng: np.random.Generator) -> np.ndarray:
    """``rgb`` with EnvConfig's ``rgb_noise`` model applied (``intensity``: gaussian's and speckle's constant)."""
    if model == "gaussian":
        return gaussian_rgb(rgb, intensity, rng)
    if model == "speckle":
        return speckle_rgb(rgb, intensity, rng)
    if model == "poisson":
        return poisson_rgb(rgb, rng)
    return salt_and_pepper_rgb(rgb, rng)


def episode_generator(seed: int, scene_id: str, episode_id: str, stream: int = 0) -> np.random.Generator:
    """Noise generator ``stream`` of one episode: the env's seed and the episode, not the order episodes ran in."""
    import hashlib
    key = int.from_bytes(hashlib.sha256(f"{scene_id}\0{episode_id}".encode()).digest()[:8], "little")
    entropy = [int(seed) & 0xFFFFFFFFFFFFFFFF, key] + ([stream] if stream else [])
    return np.random.default_rng(entropy)
