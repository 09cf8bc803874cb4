"""Habitat's realistic conditions: actuation noise as habitat-sim samples it, Redwood depth and Gaussian RGB
noise against a separate reference, seeding, the agent-state calls and the named configurations."""

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import truncnorm

from navbench.env.config import MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, EnvConfig, env_config_names
from navbench.env.noise import ACTUATION_MODELS, gaussian_rgb, redwood_depth, redwood_model, sample_motion
from navbench.env.pointnav import PointNavEnv
from navbench.env.sensors import pointgoal_polar, to_agent_frame

sys.path.insert(0, str(Path(__file__).parent))
from redwood_reference import simulate as redwood_reference  # noqa: E402

STEP, TURN = 0.25, math.radians(30.0)


def expected(model, action, multiplier=1.0):
    """(mean, std) of (forward, right, yaw) after one action, from scipy's truncated normal with upstream's
    bounds: +-3 sigma, forward translation / turn rotation >= -0.95 x commanded; noise signed as commanded."""
    rotational = action != MOVE_FORWARD
    motion = ACTUATION_MODELS[model].rotational if rotational else ACTUATION_MODELS[model].linear
    commanded = (0.0, 0.0, TURN if action == TURN_LEFT else -TURN) if rotational else (STEP, 0.0, 0.0)
    out = []
    for k in range(3):
        mu, sd = motion.mean[k], math.sqrt(motion.var[k])
        lower = -0.95 * STEP if (k == 0 and not rotational) else -0.95 * TURN if (k == 2 and rotational) else None
        if sd == 0:
            m, s = mu, 0.0
        else:
            a = -3.0 if lower is None else max((lower - mu) / sd, -3.0)
            dist = truncnorm(a, 3.0, mu, sd)
            m, s = float(dist.mean()), float(dist.std())
        sign = -1.0 if (k == 2 and action == TURN_RIGHT) else 1.0
        out.append((commanded[k] + sign * multiplier * m, multiplier * s))
    return out


def assert_moments(samples, moments, what):
    n = len(samples)
    for k, (m, s) in enumerate(moments):
        x = samples[:, k]
        # 5 standard errors: a wrong variance-vs-std, sign or bound moves these by far more
        assert abs(x.mean() - m) < 5 * max(s, 1e-9) / math.sqrt(n) + 1e-12, (what, k, x.mean(), m)
        assert abs(x.std() - s) < 5 * max(s, 1e-9) / math.sqrt(2 * n) + 1e-12, (what, k, x.std(), s)


@pytest.mark.parametrize("model", list(ACTUATION_MODELS))
def test_sampled_motions_have_the_truncated_normal_moments_of_each_model(model):
    rng = np.random.default_rng(0)
    for action in (MOVE_FORWARD, TURN_LEFT, TURN_RIGHT):
        fwd, turn = (STEP, 0.0) if action == MOVE_FORWARD else (0.0, TURN if action == TURN_LEFT else -TURN)
        x = np.array([sample_motion(ACTUATION_MODELS[model], fwd, turn, 1.0, rng) for _ in range(3000)])
        assert_moments(x, expected(model, action), (model, action))


def test_forward_and_turn_never_undo_more_than_95_percent():
    # LoCoBot-Lite's Movebase forward noise and Proportional turn noise reach the bound well inside 3 sigma
    rng = np.random.default_rng(1)
    lite_mb, lite_p = ACTUATION_MODELS["LoCoBot-Lite-Movebase"], ACTUATION_MODELS["LoCoBot-Lite-Proportional"]
    fwd = np.array([sample_motion(lite_mb, STEP, 0.0, 1.0, rng)[0] for _ in range(4000)])
    yaw = np.array([sample_motion(lite_p, 0.0, -TURN, 1.0, rng)[2] for _ in range(4000)])
    assert fwd.min() >= 0.05 * STEP - 1e-12 and fwd.min() < 0.2 * STEP
    assert yaw.max() <= -0.05 * TURN + 1e-12 and yaw.max() > -0.2 * TURN


class _OpenSpace:
    """A motion model with nothing to hit, and a distance field that is always 1 m."""

    def try_step(self, start, end, sliding=False):
        return np.asarray(end, np.float64), False

    def distance(self, p):
        return 1.0


def _open_env(pointnav_file, **conditions):
    cfg = EnvConfig(rgb=False, depth=False, max_steps=10**6, **conditions)
    env = PointNavEnv(pointnav_file, config=cfg)
    env.reset(seed=5, options={"episode": 0})
    env._motion = env._field = _OpenSpace()
    return env


@pytest.mark.parametrize("model,multiplier", [("LoCoBot-Proportional", 0.5), ("LoCoBot-Lite-Movebase", 1.0)])
def test_env_moves_as_sampled_in_open_space(pointnav_file, model, multiplier):
    env = _open_env(pointnav_file, actuation_noise=model, actuation_noise_multiplier=multiplier)
    for action in (MOVE_FORWARD, TURN_LEFT, TURN_RIGHT):
        rows = []
        for _ in range(2000):
            p0, y0 = env.agent_position, env.agent_yaw
            env.step(action)
            fwd, right = to_agent_frame(env.agent_position - p0, y0)
            rows.append((fwd, right, math.remainder(env.agent_yaw - y0, 2 * math.pi)))
        assert_moments(np.array(rows), expected(model, action, multiplier), (model, action))
    # a turn translates too, and the path length counts it
    assert env._path_length > 2000 * STEP


def test_noiseless_defaults_move_exactly(pointnav_file):
    env = _open_env(pointnav_file)
    p0, y0 = env.agent_position, env.agent_yaw
    env.step(MOVE_FORWARD)
    env.step(TURN_LEFT)
    assert to_agent_frame(env.agent_position - p0, y0) == pytest.approx((STEP, 0.0))
    assert env.agent_yaw - y0 == pytest.approx(TURN)


def test_redwood_matches_the_reference_in_distribution(pointnav_file):
    """Per depth band, the mean and spread of the noisy depth on rendered views; dropout at >= 10 m."""
    env = PointNavEnv(pointnav_file, config=EnvConfig(width=160, height=120, rgb=False, normalize_depth=False,
                                                      max_depth=10.0, min_depth=0.0))
    env.reset(seed=0, options={"episode": 0})
    views = []
    for _ in range(4):
        views.append(env._renderer.render(*env.camera_pose(), rgb=False, depth=True).depth)
        env.step(TURN_LEFT)
    far = np.full((120, 160), 12.0, np.float32)  # beyond the sensor's range: every pixel dropped
    ours = [redwood_depth(v, 1.0, np.random.default_rng(k)) for k, v in enumerate(views)]
    ref = [redwood_reference(v, redwood_model(), 1.0, np.random.default_rng(100 + k)) for k, v in enumerate(views)]
    assert not redwood_depth(far, 1.0, np.random.default_rng(0)).any()
    assert not redwood_reference(far, redwood_model(), 1.0, np.random.default_rng(0)).any()
    gt, a, b = np.concatenate(views).ravel(), np.concatenate(ours).ravel(), np.concatenate(ref).ravel()
    assert (a != gt).mean() > 0.5  # it is noise
    for lo, hi in ((0.3, 1.0), (1.0, 2.0), (2.0, 3.5), (3.5, 6.0)):
        band = (gt >= lo) & (gt < hi)
        if band.sum() < 500:
            continue
        assert abs((a[band] == 0).mean() - (b[band] == 0).mean()) < 0.02, (lo, hi)
        ka, kb = a[band][a[band] > 0], b[band][b[band] > 0]
        assert abs(ka.mean() - kb.mean()) < 0.02 * (lo + hi), (lo, hi, ka.mean(), kb.mean())
        assert abs(ka.std() - kb.std()) < 0.15 * kb.std() + 0.01, (lo, hi, ka.std(), kb.std())


def test_redwood_agrees_pixel_for_pixel_with_the_same_draws():
    # the reference draws (H, W, 3) normals, ours (3, H, W): given the same numbers they must agree exactly
    depth = np.random.default_rng(2).uniform(0.2, 11.0, (30, 40)).astype(np.float32)
    normals = np.random.default_rng(3).standard_normal((30, 40, 3))

    class Fixed:
        def __init__(self, layout):
            self.layout = layout

        def standard_normal(self, shape):
            return normals.transpose(2, 0, 1) if self.layout == "chw" else normals

    ours = redwood_depth(depth, 1.0, Fixed("chw"))
    ref = redwood_reference(depth, redwood_model(), 1.0, Fixed("hwc"))
    assert np.allclose(ours, ref, rtol=1e-5, atol=1e-6)


def test_gaussian_rgb_noise_as_habitat_draws_it():
    img = np.full((200, 200, 3), 128, np.uint8)
    out = gaussian_rgb(img, 0.1, np.random.default_rng(0)).astype(np.float64)
    # N(0, 1) x 0.1 in [0, 1] units = 25.5 grey levels; truncation to uint8 lowers the mean by ~0.5
    assert out.std() == pytest.approx(25.5, rel=0.03)
    assert out.mean() == pytest.approx(128 - 0.5, abs=0.4)
    white = gaussian_rgb(np.full((50, 50, 3), 255, np.uint8), 0.2, np.random.default_rng(0))
    assert white.max() == 255 and (white == 255).mean() == pytest.approx(0.5, abs=0.05)  # clipped at 1


def test_same_seed_same_noisy_observations_whatever_ran_before(pointnav_file):
    cfg = EnvConfig(actuation_noise="LoCoBot-ILQR", depth_noise="redwood", rgb_noise="gaussian", width=64, height=48)

    def episode_1(env):
        obs, _ = env.reset(options={"episode": 1})
        frames = [obs]
        for a in (MOVE_FORWARD, TURN_LEFT, MOVE_FORWARD):
            frames.append(env.step(a)[0])
        return frames, env.agent_position

    a, b = PointNavEnv(pointnav_file, config=cfg), PointNavEnv(pointnav_file, config=cfg)
    a.reset(seed=3)
    b.reset(seed=3)
    b.reset(options={"episode": 0})
    b.step(MOVE_FORWARD)  # another episode first: episode 1's draws must not depend on it
    (fa, pa), (fb, pb) = episode_1(a), episode_1(b)
    assert np.array_equal(pa, pb)
    for x, y in zip(fa, fb):
        assert np.array_equal(x["depth"], y["depth"]) and np.array_equal(x["rgb"], y["rgb"])
    c = PointNavEnv(pointnav_file, config=cfg)
    c.reset(seed=4)
    assert not np.array_equal(episode_1(c)[0][0]["depth"], fa[0]["depth"])  # another seed, other draws


def test_agent_state_calls_have_habitat_sims_meanings(pointnav_file):
    env = PointNavEnv(pointnav_file, config=EnvConfig(width=64, height=48))
    env.reset(seed=0, options={"episode": 0})
    s = env.get_agent_state()
    assert s.position.shape == (3,) and s.rotation.shape == (4,)
    env.step(TURN_LEFT)
    there = env.get_observations_at(s.position, s.rotation)  # where the episode started: the agent stays
    assert env.get_agent_state().rotation != pytest.approx(s.rotation)
    env.set_agent_state(s.position, s.rotation)
    here = env._observe()
    assert np.array_equal(there["depth"], here["depth"])
    assert np.array_equal(env.get_agent_state().position, s.position)
    with pytest.raises(ValueError, match="position"):
        env.set_agent_state([0.0, 1.0], s.rotation)


def test_without_gps_compass_the_goal_is_static_and_pitch_tilts_the_view(pointnav_file):
    cfg = EnvConfig(gps_compass=False, width=64, height=48)
    env = PointNavEnv(pointnav_file, config=cfg)
    obs, _ = env.reset(seed=0, options={"episode": 0})
    assert "gps" not in obs and "compass" not in obs and "pointgoal_with_gps_compass" not in obs
    assert env.observation_space.contains(obs)
    first = obs["pointgoal"].copy()
    obs = env.step(MOVE_FORWARD)[0]
    assert np.array_equal(obs["pointgoal"], first)
    goal = np.asarray(env.episode.goals[0].position)
    assert np.allclose(first, pointgoal_polar(goal, env._start_position, env._start_yaw))
    level = PointNavEnv(pointnav_file, config=EnvConfig(width=64, height=48))
    down = PointNavEnv(pointnav_file, config=EnvConfig(width=64, height=48, camera_pitch_deg=-20.0))
    dl, dd = (e.reset(seed=0, options={"episode": 0})[0]["depth"] for e in (level, down))
    # looking down, the floor in the lower image is nearer
    assert dd[-8:].mean() < dl[-8:].mean()


def test_dead_reckoning_is_exact_without_noise_or_collisions(pointnav_file):
    from navbench.agents.pointnav import DeadReckoning
    env = _open_env(pointnav_file, gps_compass=False)
    obs = env._observe()
    reckon = DeadReckoning(obs["pointgoal"], STEP, 30.0)
    goal = np.asarray(env.episode.goals[0].position, np.float64)
    for a in (MOVE_FORWARD, TURN_LEFT, MOVE_FORWARD, MOVE_FORWARD, TURN_RIGHT, TURN_RIGHT, MOVE_FORWARD):
        env.step(a)
        reckon.advance(a)
        assert np.allclose(reckon.pointgoal(), pointgoal_polar(goal, env.agent_position, env.agent_yaw), atol=1e-5)


def test_named_configurations_load_and_bad_ones_are_one_line(tmp_path):
    names = env_config_names()
    assert {"navbench", "habitat-challenge-pointnav-2020", "habitat-challenge-pointnav-2021",
            "habitat-challenge-objectnav-2021"} <= set(names)
    assert EnvConfig.load("navbench") == EnvConfig()
    c21 = EnvConfig.load("habitat-challenge-pointnav-2021")
    assert (c21.width, c21.height, c21.hfov_deg, c21.min_depth, c21.max_depth) == (640, 360, 70.0, 0.1, 10.0)
    assert (c21.actuation_noise, c21.actuation_noise_multiplier, c21.camera_pitch_deg) == \
        ("LoCoBot-Proportional", 0.5, -20.0)
    assert dataclasses.replace(c21, camera_pitch_deg=0.0) == EnvConfig.load("habitat-challenge-pointnav-2020")
    bad = tmp_path / "bad.toml"
    bad.write_text('actuation_noise = "LoCoBot-Turbo"\n')
    for arg, needle in ((bad, "LoCoBot-Turbo"), ("no-such-config", "no such file")):
        with pytest.raises(ValueError, match=needle) as exc:
            EnvConfig.load(arg)
        assert "\n" not in str(exc.value)
    bad.write_text("widht = 3\n")
    with pytest.raises(ValueError, match="unknown EnvConfig field"):
        EnvConfig.load(bad)


def test_the_other_rgb_models_as_habitat_draws_them():
    from navbench.env.noise import rgb_noise
    rng = np.random.default_rng(0)
    img = np.full((100, 100, 3), 100, np.uint8)
    speckle = rgb_noise(img, "speckle", 0.2, rng).astype(np.float64)  # x (1 + 0.2 N(0, 1))
    assert speckle.std() == pytest.approx(20.0, rel=0.05)
    grey = np.tile(np.arange(0, 256, 4, dtype=np.uint8), (64, 1))[..., None].repeat(3, axis=2)  # 64 values
    poisson = rgb_noise(grey, "poisson", 0.2, rng).astype(np.float64)
    mid = poisson[:, 32]  # grey 128 = 0.502: Poisson(0.502 x 64) / 64, std 255 x sqrt(0.502 / 64) = 22.6 levels
    assert mid.std() == pytest.approx(22.6, rel=0.15) and abs(mid.mean() - 128 + 0.5) < 3.0
    sp = rgb_noise(img, "salt_and_pepper", 0.2, rng)
    changed = sp != img
    assert set(np.unique(sp[changed])) <= {0, 1}  # upstream writes salt as 1
    assert not changed[-1].any() and not changed[:, -1].any() and not changed[..., 2].any()
    assert changed.sum() == pytest.approx(0.05 * img.size, rel=0.15)  # repeated indices land once


def test_what_is_rendered_never_changes_the_noisy_motion(pointnav_file):
    """Actuation, depth and RGB draw from separate generators: a replay that renders other images (a video)
    retraces the run, and its depth frames are the ones the agent saw."""
    base = dict(actuation_noise="LoCoBot-Proportional", depth_noise="redwood", rgb_noise="gaussian", width=48,
                height=32)
    paths, depths = [], []
    for rgb in (False, True):
        env = PointNavEnv(pointnav_file, config=EnvConfig(rgb=rgb, **base))
        env.reset(seed=1)
        obs, _ = env.reset(options={"episode": 2})
        frames, poses = [obs["depth"]], []
        for a in (MOVE_FORWARD, TURN_RIGHT, MOVE_FORWARD, TURN_LEFT, MOVE_FORWARD):
            frames.append(env.step(a)[0]["depth"])
            poses.append((*env.agent_position, env.agent_yaw))
        paths.append(poses)
        depths.append(frames)
    assert paths[0] == paths[1]
    assert all(np.array_equal(a, b) for a, b in zip(*depths))


def test_vlnce_configurations_are_the_task_yamls():
    # jacobkrantz/VLN-CE habitat_extensions/config/vlnce_task.yaml and rxr_vlnce_english_task.yaml
    r2r, rxr = EnvConfig.load("r2r-ce"), EnvConfig.load("rxr-ce")
    assert (r2r.turn_angle_deg, r2r.allow_sliding, r2r.agent_height, r2r.agent_radius) == (15.0, True, 1.5, 0.1)
    assert (r2r.width, r2r.height, r2r.hfov_deg, r2r.min_depth, r2r.max_depth) == (224, 224, 90.0, 0.0, 10.0)
    assert r2r.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")
    assert (rxr.turn_angle_deg, rxr.tilt_angle_deg, rxr.allow_sliding, rxr.agent_height, rxr.agent_radius) == \
        (30.0, 30.0, False, 0.88, 0.18)
    assert (rxr.width, rxr.height, rxr.hfov_deg, rxr.min_depth, rxr.max_depth) == (640, 480, 79.0, 0.5, 5.0)
    assert rxr.actions[4:] == ("LOOK_UP", "LOOK_DOWN")
    for c in (r2r, rxr):
        assert (c.max_steps, c.forward_step, c.success_distance, c.gps_compass) == (500, 0.25, 3.0, False)
    for name in ("r2r-ce", "rxr-ce"):  # navbench's, for baselines that know their pose: the same plus GPS+compass
        assert EnvConfig.load(f"navbench-{name}") == dataclasses.replace(EnvConfig.load(name), gps_compass=True)
