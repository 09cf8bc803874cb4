"""VLN-CE's baselines through navbench.evaluate on an R2R-CE file written here from the published schema: the
reference-path oracle reaches SR 100 with nDTW >= 0.8, VLN-CE's random and hand-crafted agents run, the records
and summary carry VLN-CE's measures with intervals and `navbench table` prints TL/NE/OS/SR/SPL/nDTW/SDTW."""

import gzip
import json

import numpy as np
import pytest

import navbench
from navbench.agents.vlnce import VLNForwardAgent, VLNRandomAgent
from navbench.cli import main
from navbench.env.config import EnvConfig
from navbench.episodes.io import load_dataset
from navbench.episodes.types import Episode
from navbench.paths import SCENES_DIR
from navbench.scene.cache import load_scene_and_navgrid

pytest.importorskip("fastdtw", reason="fastdtw is a navbench dependency (the reference's nDTW library)")

MEASURES = ("distance_to_goal", "success", "oracle_success", "spl", "path_length", "steps_taken", "ndtw", "sdtw")


def geodesic_trace(grid, start, goal, step=0.25):
    """Points every ``step`` metres along the geodesic from start to goal (what an oracle rollout records): a
    descent over the grid's cells on the distance field's values, resampled by arc length."""
    field = grid.distance_field(np.asarray(goal, float).reshape(1, 3))
    on = grid.snap_point(np.asarray(start, float))  # a start a little off the grid, as the env snaps it
    ij = tuple(int(v) for v in grid.world_to_grid(on.reshape(1, 3))[0])
    cells = [ij]
    while field.values[ij] > 0.2 and len(cells) < 5000:
        i, j = ij
        nbrs = [(i + a, j + b) for a in (-1, 0, 1) for b in (-1, 0, 1) if (a, b) != (0, 0)
                and 0 <= i + a < field.values.shape[0] and 0 <= j + b < field.values.shape[1]]
        nxt = min(nbrs, key=lambda c: field.values[c])
        if field.values[nxt] >= field.values[ij]:
            break
        ij = nxt
        cells.append(ij)
    pts = grid.grid_to_world(np.asarray(cells))
    pts = np.column_stack([pts[:, 0], np.full(len(pts), float(start[1])), pts[:, -1]])
    pts[0] = start
    out, walked = [list(map(float, start))], 0.0
    for a, b in zip(pts[:-1], pts[1:]):
        walked += float(np.linalg.norm(b - a))
        if walked >= step:
            out.append([float(v) for v in b])
            walked = 0.0
    return out


@pytest.fixture(scope="module")
def r2r_file(tmp_path_factory, pointnav_file):
    d = tmp_path_factory.mktemp("r2r") / "val_seen"
    d.mkdir()
    eps, gt = [], {}
    src = load_dataset(pointnav_file).episodes
    grid = load_scene_and_navgrid(SCENES_DIR / src[0].scene_id, EnvConfig.load("r2r-ce").nav_grid_config())[1]
    for i, e in enumerate(src):
        locs = geodesic_trace(grid, e.start_position, e.goals[0].position)
        eps.append({"episode_id": i, "trajectory_id": i, "scene_id": e.scene_id,
                    "start_position": e.start_position, "start_rotation": e.start_rotation,
                    "info": {"geodesic_distance": e.info["geodesic_distance"]},
                    "goals": [{"position": e.goals[0].position, "radius": 3.0}],
                    "reference_path": [locs[0], *locs[8:-1:8], e.goals[0].position],
                    "instruction": {"instruction_text": "Go to the goal.", "instruction_tokens": [1, 2, 0]}})
        gt[str(i)] = {"actions": [], "forward_steps": len(locs) - 1, "locations": locs}
    path = d / "val_seen.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": eps,
                                               "instruction_vocab": {"word_list": ["<PAD>", "go", "goal"]}}).encode()))
    (d / "val_seen_gt.json.gz").write_bytes(gzip.compress(json.dumps(gt).encode()))
    return path


def test_oracle_follows_the_reference_path(r2r_file, tmp_path, capsys):
    s = navbench.evaluate("vln_oracle", task="r2r_ce", episodes=r2r_file, env_config="navbench-r2r-ce",
                          out=tmp_path / "oracle")
    assert s["num_episodes"] == 6 and s["num_failed"] == 0
    assert s["success"] == 1.0 and s["spl"] > 0.5 and s["ndtw"] >= 0.8 and s["sdtw"] == s["ndtw"]
    assert all(m in s and m in s["ci95"] for m in MEASURES)
    recs = [json.loads(line) for line in (tmp_path / "oracle" / "episodes.jsonl").read_text().splitlines()]
    assert all(set(MEASURES) <= set(r) and r["vlnce_path"]["stop"][-1] for r in recs)
    assert main(["table", str(tmp_path / "oracle")]) == 0
    header = capsys.readouterr().out.splitlines()[0]
    cols = [c.strip() for c in header.strip("|").split("|")]
    assert [c for c in cols if c in ("TL", "NE", "OS", "SR", "SPL", "nDTW", "SDTW")] == \
        ["TL", "NE", "OS", "SR", "SPL", "nDTW", "SDTW"]


def test_random_and_forward_baselines_run_under_vlnce_sensors(r2r_file, tmp_path):
    for agent in ("vln_random", "vln_forward"):
        s = navbench.evaluate(agent, task="r2r_ce", episodes=r2r_file, out=tmp_path / agent,
                              options={}, seed=1)
        assert s["num_episodes"] == 6 and s["num_failed"] == 0
        assert 0 <= s["ndtw"] <= 1 and s["steps_taken"] >= 1


def test_forward_agent_is_vlnces_handcrafted_agent():
    ep = Episode("1", "s", [0, 0, 0], [0, 0, 0, 1])
    a = VLNForwardAgent(seed=3)
    a.reset(ep)
    turns = a.turns
    acts = [a.act({}) for _ in range(turns + 38)]
    assert 0 <= turns <= 24 and acts == [3] * turns + [1] * 37 + [0]
    r = VLNRandomAgent(seed=3)
    r.reset(ep)
    draws = [r.act({}) for _ in range(4000)]
    assert abs(draws.count(1) / 4000 - 0.68) < 0.03 and abs(draws.count(0) / 4000 - 0.02) < 0.01


def test_export_r2r_and_rxr_leaderboard_files(r2r_file, tmp_path, capsys):
    navbench.evaluate("vln_forward", task="r2r_ce", episodes=r2r_file, out=tmp_path / "fwd")
    assert main(["export", str(tmp_path / "fwd"), "--format", "r2r-ce", "-o", str(tmp_path / "p.json")]) == 0
    pred = json.loads((tmp_path / "p.json").read_text())
    recs = {json.loads(x)["episode_id"]: json.loads(x) for x in (tmp_path / "fwd" / "episodes.jsonl").open()}
    assert sorted(pred) == sorted(recs)
    for eid, steps in pred.items():
        assert len(steps) == recs[eid]["steps_taken"] + 1  # the start state, then one entry per action
        assert [s["stop"] for s in steps] == [False] * (len(steps) - 1) + [True]
        assert set(steps[0]) == {"position", "heading", "stop"} and len(steps[0]["position"]) == 3
    # an R2R run has no instruction ids: no RxR file, one line, exit 2
    assert main(["export", str(tmp_path / "fwd"), "--format", "rxr-ce"]) == 2
    assert "instruction_id" in capsys.readouterr().err
    # a run of part of the split: refused in one line naming what it covers; --partial writes it and says so
    navbench.evaluate("vln_forward", task="r2r_ce", episodes=r2r_file, out=tmp_path / "two", limit=2)
    assert main(["export", str(tmp_path / "two"), "--format", "r2r-ce"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "covers 2 of the 6 episodes" in err[0] and "--partial" in err[0]
    assert not (tmp_path / "two" / "predictions.json").exists()
    assert main(["export", str(tmp_path / "two"), "--format", "r2r-ce", "--partial"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "covers 2 of the 6 episodes" in err[0]
    assert len(json.loads((tmp_path / "two" / "predictions.json").read_text())) == 2

    # an RxR guide file of the same episodes, goal-less as test_challenge is: it runs unscored and exports
    src = json.loads(gzip.decompress(r2r_file.read_bytes()))
    d = tmp_path / "RxR_VLNCE_v0" / "test_challenge"
    d.mkdir(parents=True)
    eps = []
    for i, e in enumerate(src["episodes"]):
        e = dict(e, episode_id=str(i), trajectory_id=str(i), goals=None, info={"role": "guide"})
        e["instruction"] = {"instruction_id": str(50 - i), "instruction_text": "Walk ahead.", "language": "en-US",
                            "annotator_id": "1", "edit_distance": 0.0, "timed_instruction": []}
        eps.append(e)
    rxr = d / "test_challenge_guide.json.gz"
    rxr.write_bytes(gzip.compress(json.dumps({"episodes": eps}).encode()))
    s = navbench.evaluate("vln_forward", task="rxr_ce", episodes=rxr, out=tmp_path / "rxr")
    assert s["num_episodes"] == 6  # nothing to score against: no means, and no intervals of them
    assert all(s[m] is None for m in MEASURES if m not in ("steps_taken", "path_length")) and s["steps_taken"] >= 1
    assert main(["table", str(tmp_path / "rxr")]) == 0
    capsys.readouterr()
    out = tmp_path / "rxr" / "predictions.jsonl"
    assert main(["export", str(tmp_path / "rxr"), "--format", "rxr-ce"]) == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert [x["instruction_id"] for x in lines] == sorted(50 - i for i in range(6))
    for x in lines:
        assert all(a != b for a, b in zip(x["path"], x["path"][1:]))  # consecutive repeats dropped


def test_instruction_goal_is_the_last_landmark_in_the_room_the_route_enters():
    from navbench.agents.vlnce import instruction_goal
    text = ("Leave the bedroom and go through the hallway. Walk past the grey sofa. Enter the kitchen. Stop next to "
            "the plant.")
    assert instruction_goal(text) == "the plant in the kitchen"
    assert instruction_goal(text, "last") == "the plant"  # the ablation: the last sentence alone
    assert instruction_goal("Leave the bedroom, walk past the grey sofa and stop next to the plant in the "
                            "kitchen.") == "the plant in the kitchen"
    assert instruction_goal("Exit the office and wait by the tv stand in the living room") == \
        "the tv stand in the living room"
    assert instruction_goal("Walk out of the office. Stop in front of the sink.") == "the sink"  # a room left
    assert instruction_goal("Walk to the door.") == "the door" and instruction_goal("Go.") == ""
    with pytest.raises(ValueError, match="unknown instruction scope 'first'"):
        instruction_goal(text, "first")


def test_vln_memory_runs_under_vlnces_own_configurations_and_names_the_ablation():
    from navbench.agents.odometry import DepthOdometry
    from navbench.agents.registry import agent_options, check_conditions, run_label
    from navbench.agents.vlnce import InstructionMemoryAgent

    for name in ("r2r-ce", "rxr-ce"):
        env = EnvConfig.load(name)
        assert not env.gps_compass
        check_conditions("vln_memory", "r2r_ce" if name == "r2r-ce" else "rxr_ce", env)  # no GPS+compass needed
        inner = type("Inner", (), {"sensors": ("depth",)})()
        agent = InstructionMemoryAgent(inner, env)
        assert isinstance(agent.odometry, DepthOdometry) and inner._pose is agent.odometry  # read each step
    assert InstructionMemoryAgent(object(), EnvConfig.load("navbench-r2r-ce")).odometry is None  # GPS given: read
    assert run_label("vln_memory", agent_options("vln_memory")) == "vln_memory"
    assert run_label("vln_memory", agent_options("vln_memory", instruction="last")) == "vln_memory-instruction_last"
    with pytest.raises(ValueError, match="unknown instruction 'first'"):
        agent_options("vln_memory", instruction="first")


def test_depth_odometry_follows_a_walk_that_collides_and_slides():
    """Seeded random actions from a bundled R2R-CE start under r2r-ce (sliding), into walls and along them: the
    pose from actions and depth stays within a metre of the true one, where counting every forward step as a full
    step drifts several times as far."""
    import math

    from navbench.agents.odometry import DepthOdometry
    from navbench.env.base import NavEnv
    from navbench.scene.pose import heading_vector

    cfg = EnvConfig.load("r2r-ce")
    env = NavEnv(task="r2r_ce", config=cfg)
    odo = DepthOdometry(cfg)
    rng = np.random.default_rng(0)
    obs, _ = env.reset(options={"episode": 0})
    odo.reset(env.episode)
    odo(obs)
    reckoned, yaw = np.asarray(env.episode.start_position, float), odo.yaw
    for _ in range(60):
        a = int(rng.choice([1, 2, 3], p=[0.7, 0.15, 0.15]))
        obs = env.step(a)[0]
        odo.note(a)
        position, odo_yaw = odo(obs)
        if a == 1:
            reckoned = reckoned + 0.25 * heading_vector(yaw)
        else:
            yaw += math.radians(15.0) * (1 if a == 2 else -1)
    true = env.agent_position
    assert abs(math.remainder(odo_yaw - env.agent_yaw, 2 * math.pi)) < 1e-6  # turns are exact
    odometry_error, reckoning_error = (math.hypot(*(p - true)[[0, 2]]) for p in (position, reckoned))
    assert odometry_error < 1.0 and reckoning_error > 4 * odometry_error, (odometry_error, reckoning_error)


@pytest.mark.slow
def test_memory_over_maps_follows_an_instruction_on_the_bundled_split(tmp_path):
    # the pre-scan memory and the PointNav policy: ~40 s on 2 cores; VLN-CE's own configuration (no GPS+compass)
    s = navbench.evaluate("vln_memory", task="r2r_ce", split="val", limit=2, out=tmp_path / "mem")
    assert s["num_episodes"] == 2 and s["num_failed"] == 0 and s["success"] > 0


@pytest.mark.slow
def test_the_route_is_what_tells_the_final_landmark_from_its_twins(tmp_path):
    # two bundled episodes (one in each of two houses) whose last sentence's landmark has a twin nearer the start:
    # the whole instruction reaches the goal, its last sentence alone stops by the twin (~2 min on 2 cores)
    from navbench.paths import split_file

    src = split_file("r2r_ce", "val")
    data = json.loads(gzip.decompress(src.read_bytes()))
    gt = json.loads(gzip.decompress((src.parent / "val_gt.json.gz").read_bytes()))
    keep = ("5", "204")
    data["episodes"] = [e for e in data["episodes"] if str(e["episode_id"]) in keep]
    d = tmp_path / "val"
    d.mkdir()
    (d / "val.json.gz").write_bytes(gzip.compress(json.dumps(data).encode()))
    (d / "val_gt.json.gz").write_bytes(gzip.compress(json.dumps({k: gt[k] for k in keep}).encode()))
    full = navbench.evaluate("vln_memory", task="r2r_ce", episodes=d / "val.json.gz", out=tmp_path / "full")
    last = navbench.evaluate("vln_memory", task="r2r_ce", episodes=d / "val.json.gz", out=tmp_path / "last",
                             options={"instruction": "last"})
    assert full["num_episodes"] == last["num_episodes"] == 2
    assert full["success"] == 1.0 and last["success"] == 0.0


class HabitatInstructionAgent:
    """A habitat-lab ``Agent`` as VLN-CE's are written: reset() without arguments, act(observations) returning
    {"action": ...}, reading the instruction and the depth image."""

    seen: list = []

    def reset(self):
        self.steps = 0

    def act(self, observations):
        ins = observations["instruction"]
        assert isinstance(ins["text"], str) and observations["depth"].shape == (224, 224, 1)
        HabitatInstructionAgent.seen.append((ins["text"], list(ins["tokens"][:3])))
        self.steps += 1
        return {"action": "move_forward"} if self.steps < 4 else {"action": "STOP"}


def test_a_habitat_agent_reading_the_instruction_runs_unchanged(r2r_file, tmp_path):
    HabitatInstructionAgent.seen.clear()
    s = navbench.evaluate(f"{__name__}:HabitatInstructionAgent", task="r2r_ce", episodes=r2r_file, limit=2,
                          out=tmp_path / "habitat")
    assert s["num_failed"] == 0 and s["steps_taken"] == 4.0
    assert HabitatInstructionAgent.seen[0] == ("Go to the goal.", [1, 2, 0])


def test_gt_given_with_the_flag(r2r_file, tmp_path, capsys):
    import shutil
    alone = tmp_path / "alone" / "val_seen.json.gz"
    alone.parent.mkdir()
    shutil.copy(r2r_file, alone)  # no gt file beside it: nDTW is not measured
    s = navbench.evaluate("vln_forward", task="r2r_ce", episodes=alone, out=tmp_path / "nogt")
    assert s["ndtw"] is None and s["sdtw"] is None and s["success"] is not None
    gt = tmp_path / "elsewhere_gt.json.gz"
    shutil.copy(r2r_file.parent / "val_seen_gt.json.gz", gt)
    assert main(["run", "--task", "r2r_ce", "--episodes", str(alone), "--gt", str(gt), "--agent", "vln_forward",
                 "--out", str(tmp_path / "gt"), "-q"]) == 0
    capsys.readouterr()
    assert json.loads((tmp_path / "gt" / "config.json").read_text())["gt"] == str(gt)
    assert 0 < json.loads((tmp_path / "gt" / "summary.json").read_text())["ndtw"] <= 1
    assert "gt" not in json.loads((tmp_path / "nogt" / "config.json").read_text())
    assert main(["run", "--task", "pointnav", "--split", "val", "--gt", str(gt), "--agent", "oracle", "--limit", "1",
                 "--out", str(tmp_path / "pn")]) == 2
    assert "--gt applies to the VLN-CE tasks" in capsys.readouterr().err
