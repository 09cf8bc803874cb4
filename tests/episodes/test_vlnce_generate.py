"""The bundled R2R-CE-style split: byte-identical regeneration, gt paths by VLN-CE's rules, instructions that
name the route's rooms and landmarks, and a file VLN-CE's reader rules accept."""

import gzip
import json
import math

import numpy as np
import pytest

from navbench.env.config import EnvConfig
from navbench.episodes.generate import scene_files
from navbench.episodes.vlnce import read_vlnce
from navbench.episodes.vlnce_generate import (
    BODY,
    TOKENS,
    HouseRoutes,
    VLNPlan,
    generate_vlnce_split,
    object_label,
    room_label,
    tokenize,
)
from navbench.paths import SCENES_DIR, split_file

PLAN = VLNPlan(val_per_scene=3)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("vl")
    generate_vlnce_split(out, SCENES_DIR, seed=5, plan=PLAN, log=lambda *_: None)
    return out / "r2r_ce" / "val"


def test_the_gt_rollout_runs_on_the_r2r_ce_body():
    c = EnvConfig.load("r2r-ce")
    assert BODY == c.nav_grid_config() and (c.forward_step, c.turn_angle_deg, c.allow_sliding) == (0.25, 15.0, True)


@pytest.mark.slow  # an end-to-end run (seconds to tens of seconds): make test-slow
def test_regeneration_is_byte_identical(small, tmp_path):
    generate_vlnce_split(tmp_path, SCENES_DIR, seed=5, plan=PLAN, log=lambda *_: None)
    for name in ("val.json.gz", "val_gt.json.gz"):
        assert (tmp_path / "r2r_ce" / "val" / name).read_bytes() == (small / name).read_bytes()


def test_gt_and_episodes_follow_vlnce(small):
    ds = read_vlnce(small / "val.json.gz")  # finds val_gt.json.gz beside it, as the reference does
    gt = json.loads(gzip.decompress((small / "val_gt.json.gz").read_bytes()))
    assert len(ds.episodes) == 3 * 3  # house_011 has no landmark whose twins only the route tells apart
    for ep in ds.episodes:
        g = gt[ep.episode_id]
        assert g["actions"][-1] == 0 and g["forward_steps"] == g["actions"].count(1)
        assert len(g["locations"]) == g["forward_steps"] + 1 and g["locations"][0] == ep.start_position
        goal = ep.goals[0].position
        assert math.dist(g["locations"][-1], goal) < 0.5 + 1e-4  # the follower's goal radius
        ref = ep.extra["reference_path"]
        assert ref[0] == ep.start_position and ref[-1] == goal
        assert all(math.dist(a, b) <= 3.0 + 1e-6 for a, b in zip(ref, ref[1:]))  # ~2 m viewpoints (3 m at the end)
        # the route (through a via landmark on some) is 5-20 m; the start's geodesic to the goal at most that
        assert 0 < ep.info["geodesic_distance"] <= 20.0 + 1e-6 and g["forward_steps"] * 0.25 >= 4.0
        tokens = ep.extra["instruction"]["instruction_tokens"]
        words = tokenize(ep.extra["instruction"]["instruction_text"])
        assert len(tokens) == TOKENS and [ds.word_list[t] for t in tokens[:len(words)]] == words
        assert not any(tokens[len(words):])
    assert ds.word_list[:2] == ["<PAD>", "<UNK>"] and ds.word_list[2:] == sorted(ds.word_list[2:])


@pytest.mark.slow  # an end-to-end run (seconds to tens of seconds): make test-slow
def test_instructions_name_the_goal_room_and_then_the_landmark_by_its_kind():
    h = HouseRoutes(scene_files(SCENES_DIR, "val")[0], SCENES_DIR)
    from navbench.episodes.vlnce_generate import route_episode
    rng = np.random.default_rng(1)
    made = [e for e in (route_episode(h, i, rng, PLAN) for i in range(60)) if e is not None]
    assert len(made) >= 5
    for ep, _ in made:
        text = ep["instruction"]["instruction_text"]
        goal = np.asarray(ep["goals"][0]["position"])
        obj, _, at = min(h.landmarks, key=lambda lm: float(np.linalg.norm(lm[2] - goal)))
        assert np.allclose(at, goal, atol=1e-4)
        *route, enter, last = text.rstrip(".").split(". ")
        assert route and text[0].isupper()
        assert enter.endswith(f" the {room_label(obj.room)}") and last.endswith(f" the {object_label(obj.category)}")


def test_the_bundled_split_reads():
    path = split_file("r2r_ce", "val")
    ds = read_vlnce(path)
    assert ds.extra["split_version"] == 2
    assert len(ds.episodes) == 300 and ds.gt_locations is not None and len(ds.gt_locations) == 300


def test_only_the_whole_instruction_grounds_the_final_landmark(small):
    # memory over maps for instructions localises "the <landmark> in the <room>": the generator writes words the
    # localiser's descriptions know; the whole instruction grounds to the landmark the episode ends at alone, its
    # last sentence to it and a twin of its kind beyond the success distance
    from navbench.agents.vlnce import instruction_goal
    from navbench.localize.describe import ground, parse

    ds = read_vlnce(small / "val.json.gz")
    houses = {}
    for ep in ds.episodes:
        h = houses.setdefault(ep.scene_id, HouseRoutes(SCENES_DIR / ep.scene_id, SCENES_DIR))
        goal = np.asarray(ep.goals[0].position)
        (landmark,) = [o for o, _, at in h.landmarks if np.allclose(at, goal, atol=1e-4)]
        text = ep.extra["instruction"]["instruction_text"]
        desc = parse(instruction_goal(text))
        assert desc is not None and desc.room is not None and desc.category == landmark.category
        assert ground(desc, h.asset.objects) == [landmark.id]
        last = ground(instruction_goal(text, "last"), h.asset.objects)
        assert landmark.id in last and len(last) >= 2
        twins = [at for o, _, at in h.landmarks if o.id in last and o.id != landmark.id]
        assert max(float(h.grid.geodesic_distance(at, goal.reshape(1, 3))) for at in twins) > 4.0
