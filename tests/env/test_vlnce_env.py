"""R2R-CE and RxR-CE on navbench's env: an R2R-CE file written here from the published schema over a bundled
scene, run unchanged; its measures against the reference's measure classes (tests/vlnce_reference.py) on the
env's own positions and geodesics; a goal-less test split; the heading the leaderboard file takes."""

import dataclasses
import gzip
import json
import math

import gymnasium as gym
import numpy as np
import pytest

import navbench  # noqa: F401  (registers navbench/VLNCE-v0)
from navbench.env.config import EnvConfig
from navbench.env.vlnce import habitat_heading
from navbench.episodes.io import load_dataset
from navbench.scene.pose import quat_from_yaw, wrap_angle

pytest.importorskip("fastdtw", reason="fastdtw is a navbench dependency (the reference's nDTW library)")
from tests.vlnce_reference import run_reference  # noqa: E402

WORDS = ["<PAD>", "<UNK>", "walk", "to", "the", "kitchen", "."]


def _line(a, b, step=0.25):
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(1, int(np.linalg.norm(b - a) / step))
    return [(a + (b - a) * i / n).tolist() for i in range(n + 1)]


def write_r2r(directory, pointnav_file, goals=True, split="val_seen"):
    """R2R_VLNCE_v1-3_preprocessed-style files for the episodes of ``pointnav_file`` (positions only)."""
    d = directory / split
    d.mkdir(parents=True, exist_ok=True)
    eps, gt = [], {}
    for i, e in enumerate(load_dataset(pointnav_file).episodes):
        eps.append({"episode_id": i + 1, "trajectory_id": 100 + i, "scene_id": e.scene_id,
                    "start_position": e.start_position, "start_rotation": e.start_rotation,
                    "info": {"geodesic_distance": e.info["geodesic_distance"]},
                    "goals": [{"position": e.goals[0].position, "radius": 3.0}] if goals else None,
                    "reference_path": [e.start_position, e.goals[0].position],
                    "instruction": {"instruction_text": "Walk to the kitchen.",
                                    "instruction_tokens": [2, 3, 4, 5, 6] + [0] * 195}})
        gt[str(i + 1)] = {"actions": [0], "forward_steps": 0,
                          "locations": _line(e.start_position, e.goals[0].position)}
    path = d / f"{split}.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": eps, "instruction_vocab": {"word_list": WORDS}}).encode()))
    if goals:
        (d / f"{split}_gt.json.gz").write_bytes(gzip.compress(json.dumps(gt).encode()))
    return path


@pytest.fixture(scope="module")
def r2r_file(tmp_path_factory, pointnav_file):
    return write_r2r(tmp_path_factory.mktemp("r2r"), pointnav_file)


def blind(name="r2r-ce"):
    return dataclasses.replace(EnvConfig.load(name), rgb=False, depth=False)


def play(env, actions):
    obs, info = env.reset(options={"episode": 0})
    positions = [env.unwrapped.agent_position]
    for a in actions:
        obs, _, term, trunc, info = env.step(a)
        positions.append(env.unwrapped.agent_position)
        if term or trunc:
            break
    return obs, info, positions


@pytest.mark.parametrize("actions", [[0], [1, 1, 2, 1, 3, 3, 1, 1, 1, 0], [1] * 12 + [0], [2, 2, 2, 1, 1]])
def test_measures_match_the_reference_on_the_env(r2r_file, actions):
    env = gym.make("navbench/VLNCE-v0", dataset=r2r_file, config=blind())
    obs, info, positions = play(env, actions)
    u = env.unwrapped
    gt = u.dataset.gt_locations[u.episode.episode_id]
    if not (info["stop_called"] or info["steps_taken"] == 500):  # not over: end it with STOP for the final values
        obs, _, _, _, info = env.step(0)
        positions.append(u.agent_position)
        actions = actions + [0]
    # the simulator's geodesic at each position: the reference sees float32 positions, the env measures at its own
    exact = {tuple(np.asarray(p, np.float32).tolist()): p for p in positions}
    ref = run_reference(positions, actions, lambda p: float(u._field.distance(exact[tuple(p.tolist())])), gt)
    for k, v in ref.items():
        assert info[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
    assert obs["instruction"]["text"] == "Walk to the kitchen." and len(obs["instruction"]["tokens"]) == 200
    assert env.observation_space["instruction"].contains(obs["instruction"])


def test_stop_at_once(r2r_file):
    env = gym.make("navbench/VLNCE-v0", dataset=r2r_file, config=blind())
    _, info, _ = play(env, [0])
    assert info["steps_taken"] == 1 and info["path_length"] == 0 and info["spl"] == info["success"] * 1.0
    assert info["distance_to_goal"] == pytest.approx(info["geodesic_distance"], abs=1e-4)
    assert info["oracle_success"] == float(info["distance_to_goal"] < 3.0)
    assert 0 < info["ndtw"] <= 1 and info["sdtw"] == info["success"] * info["ndtw"]
    path = info["vlnce_path"]
    assert len(path["positions"]) == 2 and path["stop"] == [False, True]


def test_running_values_before_the_end(r2r_file):
    env = gym.make("navbench/VLNCE-v0", dataset=r2r_file, config=blind())
    env.reset(options={"episode": 0})
    _, _, term, _, info = env.step(1)
    assert not term and math.isnan(info["ndtw"]) and info["steps_taken"] == 1 and "vlnce_path" not in info
    assert info["path_length"] > 0


def test_a_split_without_goals_runs_unscored(tmp_path, pointnav_file):
    path = write_r2r(tmp_path, pointnav_file, goals=False, split="test")
    env = gym.make("navbench/VLNCE-v0", dataset=path, config=blind())
    _, info, _ = play(env, [1, 1, 0])
    assert math.isnan(info["distance_to_goal"]) and math.isnan(info["success"]) and math.isnan(info["ndtw"])
    assert info["steps_taken"] == 3 and len(info["vlnce_path"]["positions"]) == 4


def test_rxr_configuration_looks_up_and_down(r2r_file):
    env = gym.make("navbench/VLNCE-v0", dataset=r2r_file, config=blind("rxr-ce"), task="rxr_ce")
    assert env.action_space.n == 6
    env.reset(options={"episode": 0})
    env.step(4)
    assert env.unwrapped.camera_tilt_deg == 30.0


def test_rxr_text_features_are_observed(tmp_path, pointnav_file):
    import io
    src = json.loads(gzip.decompress(write_r2r(tmp_path / "r2r", pointnav_file).read_bytes()))
    d = tmp_path / "RxR_VLNCE_v0" / "val_unseen"
    d.mkdir(parents=True)
    eps = []
    for i, e in enumerate(src["episodes"]):
        e = dict(e, episode_id=str(i), trajectory_id=str(i))
        e["instruction"] = {"instruction_id": str(7 + i), "instruction_text": "Gehen Sie.", "language": "hi-IN"}
        eps.append(e)
    (d / "val_unseen_guide.json.gz").write_bytes(gzip.compress(json.dumps({"episodes": eps}).encode()))
    feats = tmp_path / "RxR_VLNCE_v0" / "text_features" / "rxr_val_unseen"
    feats.mkdir(parents=True)
    for i in range(len(eps)):
        buf = io.BytesIO()
        np.savez_compressed(buf, features=np.full((5, 768), i + 1.0))
        (feats / f"{7 + i:06}_hi_text_features.npz").write_bytes(buf.getvalue())
    env = gym.make("navbench/VLNCE-v0", dataset=d / "val_unseen_guide.json.gz", config=blind("rxr-ce"),
                   task="rxr_ce")
    obs, _ = env.reset(options={"episode": 1})
    assert obs["instruction"]["language"] == "hi-IN" and obs["rxr_instruction"].shape == (512, 768)
    assert (obs["rxr_instruction"][:5] == 2.0).all() and not obs["rxr_instruction"][5:].any()
    assert env.observation_space.contains(obs)


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, 3.0, -3.1])
def test_heading_is_habitats(yaw):
    assert habitat_heading(quat_from_yaw(yaw)) == pytest.approx(wrap_angle(yaw), abs=1e-9)
