"""navbench's bundled R2R-CE-style split: instructions written from routes through the procedural houses.

    navbench generate vlnce               # = generate_vlnce_split(seed=0): episodes/r2r_ce/val/

Each episode is a route from a start in one room to a landmark object in another, through a third room's
landmark on some routes, written as VLN-CE's R2R-CE files are (:mod:`navbench.episodes.vlnce`). The final
landmark is always of a kind the house holds more than once, more than ``TWIN_DISTANCE`` from the goal, and the
only one of its kind in rooms of the goal room's type: the last sentence names only the kind ("Stop next to the
chair."), and only the route before it (the room it enters) says which one is meant. A house without such a
landmark gives no routes.

- ``reference_path``: viewpoints every ~2 m along the geodesic route (R2R's viewpoints are ~2 m apart), the
  start and the goal included; the goal is the navigable point nearest the landmark.
- ``{split}_gt.json.gz``: what VLN-CE's gt files are, a shortest-path follower's rollout through the reference
  path at 0.25 m forward steps that stops within 0.5 m of the goal (``actions`` ending in STOP,
  ``forward_steps``, ``locations``: the start and the position after each forward step), run on the
  ``r2r-ce`` configuration's body, steps, 15 degree turns and sliding
  (:class:`navbench.scene.follower.WaypointFollower`).
- ``instruction``: R2R-style sentences naming the rooms the route leaves, passes and enters and the landmarks
  it passes and stops at ("Leave the bedroom and go through the hallway. Walk past the grey sofa. Enter the
  kitchen. Stop next to the plant."); a passed landmark's colour is named when the house has more than one of its
  kind, the final landmark's never. ``instruction_tokens``
  index ``instruction_vocab.word_list`` (``<PAD>`` 0, ``<UNK>`` 1, then the words in sorted order), padded with 0
  to 200.

Deterministic for a seed, and byte-identical on regeneration (gzip without a timestamp).
"""

from __future__ import annotations

import gzip
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from navbench.episodes.generate import _random_yaw_quat, _rel, scene_files
from navbench.episodes.io import _r
from navbench.loop_progress import progress
from navbench.paths import EPISODES_DIR, SCENES_DIR
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.follower import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, WaypointFollower
from navbench.scene.navigability import NavGridConfig
from navbench.scene.pose import heading_vector, quat_from_yaw, wrap_angle, yaw_from_quat

VLNCE_SPLIT_VERSION = 2
TOKENS = 200  # instruction_tokens' padded length
VOCAB_HEAD = ("<PAD>", "<UNK>")
# The r2r-ce configuration's body and motion (configs/env/r2r-ce.toml), as the gt rollout runs it.
BODY = NavGridConfig(agent_height=1.5, agent_radius=0.1, max_climb=0.2, cell_size=0.05)
FORWARD_STEP, TURN_DEG, SLIDING, MAX_STEPS = 0.25, 15.0, True, 500
LANDMARK_REACH = 1.0  # a landmark's goal: the navigable point nearest it, at most this far (xz)
VIEWPOINT_SPACING = 2.0
PASSED = 1.2  # a landmark within this distance (xz) of the route is walked past
# A final landmark's twins (its kind elsewhere in the house): at least one this far (geodesic) from the goal, beyond
# R2R-CE's 3 m success distance, so stopping by the wrong one fails.
TWIN_DISTANCE = 4.0


@dataclass(frozen=True)
class VLNPlan:
    val_per_scene: int = 100
    min_length: float = 5.0  # the reference path's geodesic length, metres (R2R's paths: 5-20 m)
    max_length: float = 20.0
    via_share: float = 0.5  # routes through a third room's landmark
    max_tries: int = 400


def room_label(name: str) -> str:
    """``bedroom_2`` -> ``bedroom``; ``dining_room`` -> ``dining room``."""
    return re.sub(r"_\d+$", "", name).replace("_", " ")


def object_label(category: str) -> str:
    """``coffee_table`` -> ``coffee table``: the words ``navbench localize``'s descriptions use for it."""
    return category.replace("_", " ")


def tokenize(text: str) -> list[str]:
    """Words and punctuation, lowercased (R2R's tokenizer splits the same way)."""
    return re.findall(r"[a-z0-9]+|[^\sa-z0-9]", text.lower())


class HouseRoutes:
    """The rooms, landmarks and navigable space of one house, and routes through them."""

    def __init__(self, scene_path: Path, scene_dir: Path):
        self.asset, self.grid = load_scene_and_navgrid(scene_path, BODY)
        self.scene_id = _rel(scene_path, scene_dir)
        self.rooms = [r for r in self.asset.rooms]
        counts: dict[str, int] = {}
        for o in self.asset.objects.values():
            counts[o.category] = counts.get(o.category, 0) + 1
        self.landmarks = []  # (object, label, navigable goal point)
        for o in sorted(self.asset.objects.values(), key=lambda o: o.id):
            c = o.center
            on = self.grid.snap_point(np.array([c[0], self.grid.floor_height, c[2]]))
            if not np.isfinite(on).all() or math.hypot(on[0] - c[0], on[2] - c[2]) > LANDMARK_REACH:
                continue
            label = object_label(o.category)
            if counts[o.category] > 1 and o.colour:
                label = f"{o.colour} {label}"
            self.landmarks.append((o, label, on))
        self.goals = [lm for lm in self.landmarks if self._needs_route(lm)]

    def _needs_route(self, landmark) -> bool:
        """Whether ``landmark`` can end a route: its kind is elsewhere in the house, once at least TWIN_DISTANCE
        from it, and nowhere else in a room of its room's type (the room then tells it from its twins)."""
        o, _, at = landmark
        if not o.room:
            return False
        twins = [(t, t_at) for t, _, t_at in self.landmarks if t.category == o.category and t.id != o.id]
        if any(room_label(t.room or "") == room_label(o.room) for t, _ in twins):
            return False
        far = [float(self.grid.geodesic_distance(t_at, at.reshape(1, 3))) for _, t_at in twins]
        return any(d > TWIN_DISTANCE for d in far)

    def room_of(self, p) -> str | None:
        for r in self.rooms:
            if r.aabb_min[0] <= p[0] <= r.aabb_max[0] and r.aabb_min[2] <= p[2] <= r.aabb_max[2]:
                return r.name
        return None

    def geodesic_route(self, start: np.ndarray, targets: list[np.ndarray]) -> list[np.ndarray]:
        """Grid points along the geodesic from ``start`` through each target in turn (a descent over cells)."""
        out = [start]
        p = start
        for t in targets:
            field = self.grid.distance_field(t.reshape(1, 3))
            ij = tuple(int(v) for v in self.grid.world_to_grid(self.grid.snap_point(p).reshape(1, 3))[0])
            vals = field.values
            h, w = vals.shape
            cells = []
            while vals[ij] > 0.1 and len(cells) < 20000:
                i, j = ij
                nxt = min(((i + a, j + b) for a in (-1, 0, 1) for b in (-1, 0, 1)
                           if (a or b) and 0 <= i + a < h and 0 <= j + b < w), key=lambda c: vals[c])
                if not vals[nxt] < vals[ij]:
                    break
                ij = nxt
                cells.append(ij)
            if cells:
                pts = self.grid.grid_to_world(np.asarray(cells))
                out += [np.array([q[0], self.grid.floor_height, q[-1]]) for q in pts]
            out.append(t)
            p = t
        return out


def _viewpoints(route: list[np.ndarray]) -> list[np.ndarray]:
    """The route's points every ~VIEWPOINT_SPACING metres of arc, its start and end included."""
    out, walked = [route[0]], 0.0
    for a, b in zip(route[:-1], route[1:]):
        walked += math.hypot(b[0] - a[0], b[2] - a[2])
        if walked >= VIEWPOINT_SPACING:
            out.append(b)
            walked = 0.0
    if walked < VIEWPOINT_SPACING / 2 and len(out) > 1:
        out.pop()  # the end comes soon after: no viewpoint just before it
    out.append(route[-1])
    return out


def gt_rollout(grid, start: np.ndarray, yaw: float, waypoints: list[np.ndarray]) -> dict[str, Any] | None:
    """VLN-CE's gt entry for a route: the follower's actions, forward steps and locations; None if it does not
    end within 0.5 m of the last waypoint."""
    f = WaypointFollower(grid, waypoints, forward_step=FORWARD_STEP, turn_angle_deg=TURN_DEG, sliding=SLIDING)
    p, actions, locations = np.asarray(start, np.float64), [], [np.asarray(start, np.float64)]
    turn = math.radians(TURN_DEG)
    for _ in range(MAX_STEPS):
        a = f.next_action(p, quat_from_yaw(yaw))
        actions.append(a)
        if a == STOP:
            break
        if a == MOVE_FORWARD:
            p, _ = grid.try_step(p, p + FORWARD_STEP * heading_vector(yaw), sliding=SLIDING)
            locations.append(p)
        else:
            yaw = wrap_angle(yaw + (turn if a == TURN_LEFT else -turn if a == TURN_RIGHT else 0.0))
    end = waypoints[-1]
    if actions[-1] != STOP or math.hypot(p[0] - end[0], p[2] - end[2]) > 0.5:
        return None
    return {"actions": actions, "forward_steps": actions.count(MOVE_FORWARD),
            "locations": [[float(v) for v in q] for q in locations]}


def instruction_text(h: HouseRoutes, start_room: str, rooms: list[str], passed: list[str], via: str | None,
                     goal_label: str, goal_room: str, rng: np.random.Generator) -> str:
    """R2R-style sentences (module docstring) from the route's rooms and landmarks; the last names the final
    landmark by its kind only, the one before it the room the route enters."""
    opening = ["Leave the {r}", "Walk out of the {r}", "Exit the {r}", "Head out of the {r}"]
    middle_room = ["go through the {r}", "walk through the {r}", "continue through the {r}"]
    middle_pass = ["Walk past the {o}.", "Go past the {o}.", "Pass the {o}."]
    middle_via = ["go to the {o} in the {r}", "walk to the {o} in the {r}"]
    enter = ["Enter the {g}.", "Go into the {g}.", "Walk into the {g}."]
    ending = ["Stop next to the {o}.", "Wait by the {o}.", "Stop in front of the {o}."]

    def pick(options: list[str]) -> str:
        return options[int(rng.integers(len(options)))]
    first = pick(opening).format(r=room_label(start_room))
    if via is not None:
        first += " and " + pick(middle_via).format(o=via[0], r=room_label(via[1]))
    elif rooms:
        first += " and " + pick(middle_room).format(r=room_label(rooms[0]))
    sentences = [first + "."]
    for o in passed[:1]:
        sentences.append(pick(middle_pass).format(o=o))
    sentences.append(pick(enter).format(g=room_label(goal_room)))
    sentences.append(pick(ending).format(o=goal_label))
    return " ".join(sentences)


def route_episode(h: HouseRoutes, eid: int, rng: np.random.Generator, plan: VLNPlan) -> tuple[dict, dict] | None:
    """One episode and its gt entry, or None when this draw gives no valid route."""
    if len(h.landmarks) < 2 or not h.goals:
        return None
    goal_obj, _, goal = h.goals[int(rng.integers(len(h.goals)))]
    goal_label = object_label(goal_obj.category)  # the kind only: the route says which one
    goal_room = goal_obj.room or None  # the landmark's annotated room (its goal point may stand in a doorway)
    start = h.grid.sample_navigable_point(rng)
    start_room = h.room_of(start)
    if goal_room is None or start_room is None or room_label(start_room) == room_label(goal_room):
        return None
    targets, via = [goal], None
    if rng.random() < plan.via_share:
        others = [lm for lm in h.landmarks if lm[0].room not in ("", start_room, goal_room)
                  and room_label(lm[0].room) not in (room_label(start_room), room_label(goal_room))]
        if others:
            v_obj, v_label, v_at = others[int(rng.integers(len(others)))]
            targets, via = [v_at, goal], (v_label, v_obj.room, v_obj.id)
    route = h.geodesic_route(start, targets)
    length = sum(math.hypot(b[0] - a[0], b[2] - a[2]) for a, b in zip(route[:-1], route[1:]))
    if not (plan.min_length <= length <= plan.max_length) or math.dist(route[-1], goal) > 1e-6:
        return None
    ref = _viewpoints(route)
    rot = _random_yaw_quat(rng)
    gt = gt_rollout(h.grid, start, yaw_from_quat(np.asarray(rot)), ref[1:])
    if gt is None:
        return None
    locs = np.asarray(gt["locations"])
    rooms = [h.room_of(p) for p in locs]
    seq = [r for i, r in enumerate(rooms) if r is not None and (i == 0 or r != rooms[i - 1])]
    between = [r for r in dict.fromkeys(seq) if room_label(r) not in (room_label(start_room), room_label(goal_room))]
    skip = {goal_obj.id, via[2] if via else -1}
    # after the via landmark, if any: the text names what is passed after it
    after = int(np.argmin(np.hypot(locs[:, 0] - targets[0][0], locs[:, 2] - targets[0][2]))) if via else 0
    passed = []
    for o, label, _ in h.landmarks:
        if o.id in skip or o.room == goal_room:
            continue
        d = np.hypot(locs[after:, 0] - o.center[0], locs[after:, 2] - o.center[2])
        if d.min() < PASSED:
            passed.append((int(np.argmin(d)), label))
    passed_labels = [lbl for _, lbl in sorted(passed)]
    text = instruction_text(h, start_room, between, passed_labels, via and via[:2], goal_label, goal_room, rng)
    geo = float(h.grid.geodesic_distance(start, goal.reshape(1, 3)))
    ep = {"episode_id": eid, "trajectory_id": eid, "scene_id": h.scene_id,
          "start_position": [float(v) for v in start], "start_rotation": rot,
          "info": {"geodesic_distance": geo},
          "goals": [{"position": [float(v) for v in goal], "radius": 3.0}],
          "reference_path": [[float(v) for v in p] for p in ref],
          "instruction": {"instruction_text": text}}
    return ep, gt


def vlnce_split(houses: list[HouseRoutes], per_scene: int, rng: np.random.Generator, plan: VLNPlan,
                desc: str = "r2r_ce") -> tuple[dict, dict]:
    """(episode file object, gt file object): ``per_scene`` routes in each house that has a final landmark the
    route must tell from its twins (none in a house without one), tokens over their vocabulary."""
    episodes, gt = [], {}
    for h in progress(houses, desc=desc):
        if not h.goals:
            continue
        made = 0
        for _ in range(plan.max_tries * per_scene):
            if made == per_scene:
                break
            out = route_episode(h, len(episodes), rng, plan)
            if out is not None:
                episodes.append(out[0])
                gt[str(out[0]["episode_id"])] = out[1]
                made += 1
        else:
            raise RuntimeError(f"{h.scene_id}: only {made} of {per_scene} routes after {plan.max_tries * per_scene} "
                               f"draws")
    words = sorted({w for e in episodes for w in tokenize(e["instruction"]["instruction_text"])})
    word_list = [*VOCAB_HEAD, *words]
    index = {w: i for i, w in enumerate(word_list)}
    for e in episodes:
        ids = [index[w] for w in tokenize(e["instruction"]["instruction_text"])][:TOKENS]
        e["instruction"]["instruction_tokens"] = ids + [0] * (TOKENS - len(ids))
    data = {"split_version": VLNCE_SPLIT_VERSION, "episodes": _r(episodes),
            "instruction_vocab": {"word_list": word_list, "num_vocab": len(word_list)}}
    return data, _r(gt)


def _write(path: Path, obj: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(json.dumps(obj, separators=(",", ":")).encode(), mtime=0))


def generate_vlnce_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                         plan: VLNPlan = VLNPlan(), log=print) -> int:
    """Write ``out_dir/r2r_ce/val/val.json.gz`` and ``val_gt.json.gz`` over the bundled val houses."""
    houses = [HouseRoutes(p, scene_dir) for p in scene_files(scene_dir, "val")]
    data, gt = vlnce_split(houses, plan.val_per_scene, np.random.default_rng([seed, 2, 0]), plan)
    d = out_dir / "r2r_ce" / "val"
    _write(d / "val.json.gz", data)
    _write(d / "val_gt.json.gz", gt)
    log(f"r2r_ce/val: {len(data['episodes'])} episodes, {len(data['instruction_vocab']['word_list'])} words")
    return len(data["episodes"])
