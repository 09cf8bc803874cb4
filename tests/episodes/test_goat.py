"""The GOAT-Bench reader on files written here from goat-bench's published schema (not by navbench)."""

import copy
import gzip
import json

import numpy as np
import pytest

from navbench.episodes.goat import GOAL_TYPES, GoatEpisode, load_goat
from navbench.episodes.types import EpisodeError

SCENE = "hm3d/val//00808-y9hTuugGdiq/y9hTuugGdiq.basis.glb"  # as GOAT's files write it (double slash)
G = "y9hTuugGdiq.basis.glb"


def inst(cat, oid, *vps, desc=None, images=0, children=()):
    g = {"object_category": cat, "object_id": oid, "object_name": oid, "position": [1.0, 0.5, 1.0],
         "view_points": [{"agent_state": {"position": list(p), "rotation": [0, 0, 0, 1]}, "iou": 0.5} for p in vps],
         "children_object_categories": list(children),
         "image_goals": [{"position": [1.0, 1.2, 2.0], "rotation": [0, 0, 0, 1], "hfov": 60 + i,
                          "image_dimensions": [512, 512], "frame_coverage": 0.3, "object_coverage": 0.8}
                         for i in range(images)]}
    if desc is not None:
        g["lang_desc"] = desc
    return g


LONG = " ".join(["word"] * 56)
CONTENT = {
    "goals": {
        f"{G}_chair": [inst("chair", "chair_1", (0, 0, 1), children=["stool"]),
                       inst("chair", "chair_2", (0, 0, 2), desc="the red chair by the window", images=2)],
        f"{G}_stool": [inst("stool", "stool_4", (0, 0, 4))],
        f"{G}_bed": [inst("bed", "bed_3", (0, 0, 3), desc=LONG)],
    },
    "episodes": [
        {"episode_id": "xyz", "scene_id": SCENE, "start_position": [0, 0, 0], "start_rotation": [0, 0, 0, 1],
         "info": {"geodesic_distance": 1.0}, "goals": [], "object_category": None,
         "tasks": [["chair", "object", None], ["chair", "description", "chair_2"], ["chair", "image", "chair_2", 1],
                   ["bed", "description", "bed_3"], ["stool", "object", None]]},
        {"episode_id": "abc", "scene_id": SCENE, "start_position": [0, 0, 0], "start_rotation": [0, 0, 0, 1],
         "info": {}, "goals": [], "tasks": [["bed", "object", None]]},
    ],
}


def _split(tmp_path, content=CONTENT):
    d = tmp_path / "val_seen"
    (d / "content").mkdir(parents=True, exist_ok=True)
    (d / "val_seen.json.gz").write_bytes(gzip.compress(json.dumps({"episodes": []}).encode()))
    (d / "content" / "y9hTuugGdiq.json.gz").write_bytes(gzip.compress(json.dumps(content).encode()))
    return d / "val_seen.json.gz"


def test_reads_the_published_layout(tmp_path):
    ds = load_goat(_split(tmp_path))
    ep, ep2 = ds.episodes
    assert isinstance(ep, GoatEpisode) and ep.task == "goat"
    assert (ep.episode_id, ep2.episode_id) == ("0", "1")  # the index in its file, as goat_dataset.py L144 sets it
    assert [t.type for t in ep.tasks] == ["object", "description", "image", "description", "object"]
    assert [t.current_subtask for t in ep.tasks] == [0, 1, 2, 1, 0] and GOAL_TYPES.index("image") == 2
    # object: the category's instances plus its children's ("stool" is chair's child)
    assert [g.object_id for g in ep.subtask_goals[0]] == ["chair_1", "chair_2", "stool_4"]
    assert ep.subtask_goal_positions(0).tolist() == [[0, 0, 1], [0, 0, 2], [0, 0, 4]]
    assert [g.object_id for g in ep.subtask_goals[1]] == ["chair_2"]
    # raw goals: the description text and the goal image's camera
    assert ep.descriptions[1] == "the red chair by the window"
    assert ep.image_goals[2].hfov_deg == 61.0 and (ep.image_goals[2].height, ep.image_goals[2].width) == (512, 512)


def test_long_description_drops_from_goals_not_from_tasks(tmp_path):
    (ep, _) = load_goat(_split(tmp_path)).episodes
    assert len(ep.tasks) == 5 and ep.num_goals == 4 and ep.dropped_descriptions == 1
    assert ep.descriptions[3] == " ".join(["word"] * 56)  # still given for the task it belongs to
    # goals[3] is now the stool subtask's (tasks[4]): out of step, as goat-bench leaves them
    assert [g.object_id for g in ep.subtask_goals[3]] == ["stool_4"]


def test_fifty_five_words_are_kept(tmp_path):
    content = copy.deepcopy(CONTENT)
    content["goals"][f"{G}_bed"][0]["lang_desc"] = " ".join(["word"] * 55)
    (ep, _) = load_goat(_split(tmp_path, content)).episodes
    assert ep.num_goals == 5 and ep.dropped_descriptions == 0


def test_children_extend_the_list_in_place(tmp_path):
    # goat_dataset.py L205 extends the category's list itself, and an object subtask's goals are that list
    # (L212): what later episodes append reaches an earlier episode's object subtask too
    content = copy.deepcopy(CONTENT)
    content["goals"][f"{G}_stool"][0]["children_object_categories"] = ["bench"]
    content["goals"][f"{G}_bench"] = [inst("bench", "bench_5", (0, 0, 5))]
    content["episodes"][0]["tasks"] = [["chair", "object", None]]
    content["episodes"][1]["tasks"] = [["stool", "object", None], ["chair", "description", "chair_2"]]
    (ep0, ep1) = load_goat(_split(tmp_path, content)).episodes
    assert [g.object_id for g in ep1.subtask_goals[0]] == ["stool_4", "bench_5"]
    assert [g.object_id for g in ep0.subtask_goals[0]] == ["chair_1", "chair_2", "stool_4", "bench_5"]


def _error(tmp_path, mutate):
    content = copy.deepcopy(CONTENT)
    mutate(content)
    with pytest.raises(EpisodeError) as info:
        load_goat(_split(tmp_path, content))
    msg = str(info.value)
    assert "\n" not in msg and "y9hTuugGdiq.json.gz" in msg
    return msg


def test_errors_are_one_line_naming_the_field(tmp_path):
    eps = lambda c: c["episodes"][0]["tasks"]  # noqa: E731
    msg = _error(tmp_path, lambda c: eps(c).__setitem__(1, ["chair", "description", "chair_9"]))
    assert "episode 0: tasks[1]" in msg and "'chair_9'" in msg
    msg = _error(tmp_path, lambda c: eps(c).__setitem__(2, ["chair", "image", "chair_2", 2]))
    assert "tasks[2]: image index 2" in msg and "2 image_goals" in msg
    msg = _error(tmp_path, lambda c: eps(c).__setitem__(2, ["chair", "image", "chair_2"]))
    assert "tasks[2]" in msg and "image index" in msg
    msg = _error(tmp_path, lambda c: eps(c).__setitem__(0, ["table", "object", None]))
    assert "tasks[0]: category 'table': no goal list" in msg
    msg = _error(tmp_path, lambda c: eps(c).__setitem__(0, ["chair", "smell", None]))
    assert "tasks[0]: type must be one of object, description, image" in msg
    msg = _error(tmp_path, lambda c: c["goals"][f"{G}_chair"][1].pop("lang_desc"))
    assert "tasks[1]" in msg and "lang_desc" in msg
    msg = _error(tmp_path, lambda c: c["goals"][f"{G}_chair"][1]["image_goals"][1].update(hfov=500))
    assert f"goals['{G}_chair'][1]: image_goals[1]" in msg and "hfov" in msg
    msg = _error(tmp_path, lambda c: c["goals"].pop(f"{G}_bed") and c["goals"].__setitem__("x_bed", []))
    assert "goals['x_bed']: must be a non-empty list" in msg
    msg = _error(tmp_path, lambda c: c.pop("goals"))
    assert "'goals' must be an object" in msg
    msg = _error(tmp_path, lambda c: c["episodes"][1].pop("tasks"))
    assert "episode 1: tasks must be a list" in msg


def test_subtask_without_view_points(tmp_path):
    def strip(c):
        c["goals"][f"{G}_bed"][0]["view_points"] = []
        c["episodes"][0]["tasks"] = [["bed", "object", None]]
    assert "no view_points" in _error(tmp_path, strip)


def test_oversized_file_is_refused(tmp_path):
    with pytest.raises(EpisodeError):
        load_goat(_split(tmp_path), cap=100)


def test_view_points_are_floats(tmp_path):
    (ep, _) = load_goat(_split(tmp_path)).episodes
    assert ep.subtask_goal_positions(2).dtype == np.float64


def test_progress_sequences_subtasks_from_the_same_pose(tmp_path):
    from navbench.episodes.goat import DONE, GoatProgress

    (ep, _) = load_goat(_split(tmp_path)).episodes  # 5 tasks, 4 goals (the bed's description is dropped)
    p = GoatProgress(ep)
    pos = np.zeros(3)

    def dist(k):  # to the view points of goals[k], from where the agent stands
        return float(np.linalg.norm(ep.subtask_goal_positions(k) - pos, axis=1).min())

    p.reset(pos, dist(0))
    seen = [(p.current_subtask, p.goal()[0], p.goal()[1][:8])]
    for target in ([0, 0, 1], [0, 0, 2], [0, 0, 2], [0, 0, 4]):
        while not np.allclose(pos, target):
            pos = pos + np.array([0, 0, 0.25])
            p.step(1, pos, dist)
        p.step(6, pos, dist)
        seen.append((p.current_subtask, p.goal()[0], p.goal()[1][:8]))
    assert p.over and p.num_steps == 16 + 4  # 16 forward steps to z = 4, four SUBTASK_STOPs
    # habitat's current_subtask follows tasks[k], the dropped description (tasks[3]) included, while the
    # distance is to goals[k]; closing goals' last subtask ends the episode with tasks[4] still announced
    assert seen == [(0, "chair", ""), (1, "chair", "the red "), (2, "chair", ""), (1, "bed", "word wor"),
                    (0, "stool", "")]
    assert p.goal()[2] is None and DONE == 3
    m = p.metrics()
    # goals[3] is the stool's, reached; tasks[3] (the description) takes the success; tasks[4] never closes
    assert m["subtask_success"] == [1.0, 1.0, 1.0, 1.0, 0.0] and m["description_success"] == 1.0
    with pytest.raises(RuntimeError):
        p.step(1, pos, dist)
