"""The navigation env every task runs on: scene switching, the motion model, sensors and running metrics.

What differs between tasks (goal observations, action list, success distance, step limit, the points
distance-to-goal is measured to) comes from the task's definition in :mod:`navbench.tasks`; ``NavEnv(task=NAME)``
runs any registered task. ``pointnav.py`` and ``objectnav.py`` name two of them and document their interface.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from navbench.env.config import EnvConfig
from navbench.env.sensors import AGENT_POSE, compass, gps, normalize_depth
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.metrics import episode_metrics
from navbench.paths import SCENES_DIR
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.asset import SceneAsset
from navbench.scene.cache import layers_for, load_scene_and_navgrid, navgrid_for
from navbench.scene.datasets import resolve_scene
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import heading_vector, quat_from_yaw, vector_length, wrap_angle, yaw_from_quat
from navbench.tasks import get_task


def resolve_scene_path(scene_id: str, scene_dir: Path) -> Path:
    """The mesh an episode's ``scene_id`` names: ``scene_dir / scene_id`` for navbench's own splits; for
    Habitat's HM3D / MP3D episode files, ``scene_dir`` may be ``scene_datasets/`` (see
    :func:`navbench.scene.datasets.resolve_scene`). SceneError, listing where it looked, if missing."""
    return resolve_scene(scene_id, Path(scene_dir))


class AgentState(NamedTuple):
    """habitat-sim's AgentState, as far as navigation reads it: ``position`` (3,), ``rotation`` [x, y, z, w]."""
    position: np.ndarray
    rotation: np.ndarray


def camera_at(position: np.ndarray, yaw: float, config: EnvConfig, tilt_deg: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """The camera's (position, rotation [x, y, z, w]) for an agent at ``position`` facing ``yaw``: the
    agent's height above it, pitched about its x axis by ``camera_pitch_deg`` (Habitat's sensor orientation)
    plus ``tilt_deg`` (what LOOK_UP / LOOK_DOWN have added, positive up)."""
    eye = position + np.array([0.0, config.agent_height, 0.0])
    pitch = config.camera_pitch_deg + tilt_deg
    if pitch == 0.0:
        return eye, quat_from_yaw(yaw)
    # q_yaw * q_pitch (rotation about +y, then about the camera's own x axis)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    half = math.radians(pitch) / 2.0
    cp, sp = math.cos(half), math.sin(half)
    return eye, np.array([cy * sp, sy * cp, -sy * sp, cy * cp])


class NavEnv(gym.Env):
    """The env of any registered task (``task``: a name in :data:`navbench.tasks.TASKS`); see
    :class:`navbench.env.pointnav.PointNavEnv` for the documented interface.

    ``dataset`` defaults to the task's default bundled split, ``config`` to navbench's EnvConfig with the
    task's step limit. The action space is ``Discrete(len(actions))`` over the config's ``actions`` (the task's
    when it sets none); the observations are the sensors plus the task's goal sensors."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    task: str = "pointnav"

    def __init__(self, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
                 config: EnvConfig | None = None, render_mode: str | None = None, task: str | None = None):
        self.task = task or type(self).task
        self.task_def = get_task(self.task)
        if config is None:
            config = EnvConfig.load(self.task_def.env_config) if self.task_def.env_config else \
                EnvConfig(max_steps=self.task_def.max_steps)
        self.config = config
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        if dataset is None:
            if not self.task_def.splits:
                raise ValueError(f"task {self.task} bundles no split: pass dataset= (a file of its episodes)")
            dataset = self.task_def.split_file(self.task_def.default_split)
        self.dataset = dataset if isinstance(dataset, EpisodeDataset) else self.task_def.read_episodes(dataset)
        if not self.dataset.episodes:
            raise EpisodeError(f"{dataset}: dataset has no episodes")
        self.scene_dir = Path(scene_dir) if scene_dir is not None else SCENES_DIR
        self.success_distance = (self.config.success_distance if self.config.success_distance is not None
                                 else self.task_def.success_distance)
        self.nav_config = self.config.nav_grid_config()
        self.camera = CameraConfig(width=self.config.width, height=self.config.height, hfov_deg=self.config.hfov_deg)
        self.actions = self.task_def.env_actions(self.config)
        self.action_space = spaces.Discrete(len(self.actions))
        self.goal_sensors = self.task_def.sensors(self.config)
        self.observation_space = spaces.Dict(self._observation_spaces())
        self._episode_goals: dict[str, np.ndarray] = {}  # the per-episode goal observations of the episode
        self._agent_pose = False  # give_agent_pose(): the simulator's pose, for a privileged agent
        self._tilt = 0.0  # degrees LOOK_UP / LOOK_DOWN have added to the camera's pitch

        self._scene_path: Path | None = None
        self.asset: SceneAsset | None = None
        self.navgrid: NavGrid | None = None
        # The joined walkable surfaces of the scene (storeys, stairs, ramps), built for the first episode
        # with a goal off the start's storey; that episode moves and is measured on them.
        self.layered: LayeredNav | None = None
        self._motion: NavGrid | LayeredNav | None = None
        self._renderer: Renderer | None = None
        self.episode: Episode | None = None
        self._done = True
        self._last_rgb: np.ndarray | None = None
        # Realistic conditions (navbench.env.noise): draws come from a generator seeded by the env's seed
        # and the episode, so a record does not depend on which worker ran it or what ran before.
        self._actuation = None
        if self.config.actuation_noise is not None:
            from navbench.env.noise import ACTUATION_MODELS
            self._actuation = ACTUATION_MODELS[self.config.actuation_noise]
        self._noise_rng: np.random.Generator | None = None  # actuation
        self._depth_rng: np.random.Generator | None = None
        self._rgb_rng: np.random.Generator | None = None

    # ------------------------------------------------------------------ spaces
    def _observation_spaces(self) -> dict[str, spaces.Space]:
        c = self.config
        obs: dict[str, spaces.Space] = {}
        if c.rgb:
            obs["rgb"] = spaces.Box(0, 255, (c.height, c.width, 3), np.uint8)
        if c.depth:
            hi = 1.0 if c.normalize_depth else c.max_depth
            lo = 0.0 if c.normalize_depth else c.min_depth
            obs["depth"] = spaces.Box(lo, hi, (c.height, c.width, 1), np.float32)
        if c.semantic:
            obs["semantic"] = spaces.Box(-1, np.iinfo(np.int32).max, (c.height, c.width, 1), np.int32)
        if c.gps_compass:
            big = np.finfo(np.float32).max  # Habitat's GPS bounds: any finite float32
            obs["gps"] = spaces.Box(-big, big, (2,), np.float32)
            obs["compass"] = spaces.Box(-np.pi, np.pi, (1,), np.float32)
        for sensor in self.goal_sensors:
            obs[sensor.uuid] = sensor.space(self.dataset, c)
        return obs

    def give_agent_pose(self) -> None:
        """Add ``agent_pose`` to the observations from now on: the simulator's pose as [forward, right, heading]
        relative to the episode's start (float32; the values GPS+compass would give), whatever the
        configuration senses. For privileged agents only (the oracles), which read the simulator's pose as
        habitat-lab's ShortestPathFollower reads ``sim.get_agent_state()``; no score depends on it."""
        self._agent_pose = True
        big = np.finfo(np.float32).max
        space = self.observation_space
        assert isinstance(space, spaces.Dict)  # the env's observations are always a Dict
        self.observation_space = spaces.Dict({**space.spaces, AGENT_POSE: spaces.Box(-big, big, (3,), np.float32)})

    # ------------------------------------------------------------------ scene
    def _load_scene(self, scene_id: str, start_y: float | None = None) -> None:
        """Load the episode's scene, and the grid of the floor its start stands on (multi-floor scans)."""
        path = resolve_scene_path(scene_id, self.scene_dir)
        if path == self._scene_path:
            if start_y is not None and self.navgrid is not None and self.asset is not None and \
                    abs(start_y - self.navgrid.floor_height) > self.nav_config.agent_height / 2:
                self.navgrid = navgrid_for(self.asset, self.nav_config, floor_hint=start_y)
            return
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.asset, self.navgrid = load_scene_and_navgrid(path, self.nav_config, floor_hint=start_y)
        self.layered = None
        self._scene_path = path
        if self.config.rgb or self.config.depth or self.config.semantic or self.render_mode == "rgb_array":
            self._renderer = Renderer(self.asset, self.camera, platform=self.config.gl_platform)

    def _scene_renderer(self) -> Renderer:
        """The renderer of the current scene, made when first needed (a goal image under a config that renders
        no sensor)."""
        if self._renderer is None:
            assert self.asset is not None  # loaded with the episode's scene
            self._renderer = Renderer(self.asset, self.camera, platform=self.config.gl_platform)
        return self._renderer

    # ------------------------------------------------------------------ episode selection
    def _select_episode(self, options: dict[str, Any] | None) -> Episode:
        ep = (options or {}).get("episode")
        if ep is None:  # seeded draw, so reset(seed=s) picks the same episode every time
            return self.dataset.episodes[int(self.np_random.integers(len(self.dataset.episodes)))]
        if isinstance(ep, Episode):
            return ep
        if isinstance(ep, (int, np.integer)):
            return self.dataset.episodes[int(ep)]
        for e in self.dataset.episodes:
            if e.episode_id == str(ep):
                return e
        raise EpisodeError(f"episode {ep!r} is not in the dataset")

    def _goal_points(self, episode: Episode) -> np.ndarray:
        return self.task_def.goal_points(episode)

    def _start_field(self) -> Any:
        """The distance field success and SPL are measured with from the start (reset): to the goal points."""
        assert self._motion is not None
        return self._motion.distance_field(self._goals)

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        episode = self._select_episode(options)
        if self.config.noisy:
            from navbench.env.noise import episode_generator
            seed, scene, ep = int(self.np_random_seed), episode.scene_id, episode.episode_id
            # one generator per source, so what is rendered never changes the motion (a replay or a video
            # that renders other images retraces the run); depth takes stream 0 when the motion is exact
            self._noise_rng = episode_generator(seed, scene, ep)
            self._depth_rng = self._noise_rng if self._actuation is None else episode_generator(seed, scene, ep, 1)
            self._rgb_rng = episode_generator(seed, scene, ep, 2)
        self._load_scene(episode.scene_id, float(episode.start_position[1]))
        assert self.navgrid is not None
        start = np.asarray(episode.start_position, np.float64)
        if not np.isfinite(start).all() or not np.isfinite(episode.start_rotation).all():
            raise EpisodeError(f"episode {episode.episode_id}: non-finite start pose {episode.start_position}")
        on_grid = self.navgrid.is_navigable(start)
        if not on_grid:
            snapped = self.navgrid.snap_point(start)
            on_grid = np.isfinite(snapped).all() and \
                vector_length((snapped - start)[[0, 2]]) <= self.config.start_snap_tolerance
            start = snapped if on_grid else start
        self.episode = episode
        self._goals = self._goal_points(episode)
        self._motion = self.navgrid
        self._position = np.array([start[0], self.navgrid.floor_height, start[2]])
        off = ~self.navgrid.on_storey(self._goals)
        if off.any() or not on_grid:
            # A start off the grid's storey (on a flight or a ramp), or a goal on another storey that stairs or a
            # ramp join to the start's: the episode runs on the joined surfaces instead (goals on storeys
            # nothing joins never count, on either engine).
            if self.layered is None:
                assert self.asset is not None  # loaded with the episode's scene
                self.layered = layers_for(self.asset, self.nav_config)
            declared = np.asarray(episode.start_position, np.float64)
            on = self.layered.snap_point(declared, self.config.start_snap_tolerance)
            if not on_grid and not np.isfinite(on).all():
                raise EpisodeError(f"episode {episode.episode_id} ({episode.scene_id}): start position "
                                   f"{[round(v, 3) for v in declared]} is not navigable")
            if not on_grid or self.layered.reaches_any(on, self._goals[off]):
                self._motion, self._position = self.layered, on
        self._yaw = yaw_from_quat(np.asarray(episode.start_rotation, np.float64))
        # GPS is measured from the episode's declared start (not the snapped one), so agents that add
        # GPS to the declared start pose recover their true world position.
        declared = np.asarray(episode.start_position, np.float64)
        self._start_position = np.array([declared[0], self._position[1], declared[2]])
        self._start_yaw = self._yaw
        self._field = self._start_field()
        self._d0 = float(self._field.distance(self._position))
        self._num_steps = 0
        self._collisions = 0
        self._path_length = 0.0
        self._stop_called = False
        self._done = False
        self._tilt = 0.0
        # per-episode goal observations (goal images) are computed once, here, at the start pose
        self._episode_goals = {s.uuid: s.observe(self) for s in self.goal_sensors if s.per_episode}
        return self._observe(), self._info()

    def step(self, action):
        if self._done:
            raise RuntimeError("episode is over: call reset() before step()")
        n = len(self.actions)
        if not self.action_space.contains(action):
            try:
                a = int(action)
            except (TypeError, ValueError):
                raise ValueError(f"action must be an int in 0..{n - 1}, got {action!r}") from None
            if not 0 <= a < n or a != action:
                raise ValueError(f"action must be an int in 0..{n - 1} ({', '.join(self.actions)}), "
                                 f"got {action!r}")
        name = self.actions[int(action)]
        self._num_steps += 1
        if name == "STOP":
            self._stop_called = True
        elif name in ("LOOK_UP", "LOOK_DOWN"):
            # habitat-lab's LookUpAction / LookDownAction rotate the sensors about their x axis, no limit
            tilt = self._tilt + (self.config.tilt_angle_deg if name == "LOOK_UP" else -self.config.tilt_angle_deg)
            self._tilt = (tilt + 180.0) % 360.0 - 180.0
        elif self._actuation is not None:
            self._noisy_move(name)
        elif name == "MOVE_FORWARD":
            fwd = heading_vector(self._yaw)
            assert self._motion is not None  # set by reset()
            new, collided = self._motion.try_step(self._position, self._position + self.config.forward_step * fwd,
                                                  sliding=self.config.allow_sliding)
            # Habitat's path length sums 3-D displacements (y changes on stairs and ramps only).
            step = new - self._position if self._motion is self.layered else (new - self._position)[[0, 2]]
            self._path_length += vector_length(step)
            self._position = np.asarray(new, np.float64)
            self._collisions += int(collided)
        elif name in ("TURN_LEFT", "TURN_RIGHT"):
            sign = 1.0 if name == "TURN_LEFT" else -1.0
            self._yaw = wrap_angle(self._yaw + sign * math.radians(self.config.turn_angle_deg))
        terminated = self._stop_called
        truncated = not terminated and self._num_steps >= self.config.max_steps
        self._done = terminated or truncated
        return self._observe(), 0.0, terminated, truncated, self._info()

    def _noisy_move(self, action: str) -> None:
        """One MOVE_FORWARD or turn as habitat-sim's PyRobot noisy controls make it: the sampled translation
        (a turn's too), through the same collision rule as a noiseless step, then the sampled rotation."""
        from navbench.env.noise import sample_motion
        from navbench.env.sensors import from_agent_frame
        assert self._actuation is not None and self._noise_rng is not None and self._motion is not None
        c = self.config
        turn = 0.0 if action == "MOVE_FORWARD" else \
            (1.0 if action == "TURN_LEFT" else -1.0) * math.radians(c.turn_angle_deg)
        fwd, right, dyaw = sample_motion(self._actuation, c.forward_step if action == "MOVE_FORWARD" else 0.0, turn,
                                         c.actuation_noise_multiplier, self._noise_rng)
        target = self._position + from_agent_frame(fwd, right, self._yaw)
        new, collided = self._motion.try_step(self._position, target, sliding=c.allow_sliding)
        step = new - self._position if self._motion is self.layered else (new - self._position)[[0, 2]]
        self._path_length += vector_length(step)
        self._position = np.asarray(new, np.float64)
        self._collisions += int(collided)
        self._yaw = wrap_angle(self._yaw + dyaw)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._last_rgb is None:
            assert self._renderer is not None
            out = self._renderer.render(*self.camera_pose(), rgb=True, depth=False, ids=False)
            self._last_rgb = out.rgb
        return self._last_rgb

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._scene_path = None

    # ------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict[str, Any]:
        """The episode in progress and the env's random stream as plain data (JSON-able), so that a training
        run saved between steps continues exactly where it stopped (:meth:`restore`)."""
        assert self.episode is not None  # set by reset()
        return {"episode_id": self.episode.episode_id,
                "start_position": [float(v) for v in self.episode.start_position],
                "start_rotation": [float(v) for v in self.episode.start_rotation],
                "position": [float(v) for v in self._position], "yaw": float(self._yaw),
                "num_steps": self._num_steps, "collisions": self._collisions, "path_length": self._path_length,
                "stop_called": self._stop_called, "done": self._done, "rng": self.np_random.bit_generator.state,
                **({"tilt": self._tilt} if self._tilt else {})}

    def restore(self, snap: dict[str, Any]) -> dict[str, np.ndarray]:
        """Continue the episode :meth:`snapshot` described (an episode of this env's dataset, possibly with
        another start pose under an id suffixed to the dataset's); returns its current observation."""
        eid = snap["episode_id"]
        base = next((e for e in self.dataset.episodes if e.episode_id == eid), None) or next(
            (e for e in self.dataset.episodes if eid.startswith(f"{e.episode_id}-")), None)
        if base is None:
            raise ValueError(f"episode {eid!r} is not in this env's dataset")
        ep = dataclasses.replace(base, episode_id=eid, start_position=list(snap["start_position"]),
                                 start_rotation=list(snap["start_rotation"]))
        self.reset(options={"episode": ep})
        self._position = np.asarray(snap["position"], np.float64)
        self._yaw = float(snap["yaw"])
        self._num_steps, self._collisions = int(snap["num_steps"]), int(snap["collisions"])
        self._path_length, self._stop_called = float(snap["path_length"]), bool(snap["stop_called"])
        self._done = bool(snap["done"])
        self._tilt = float(snap.get("tilt", 0.0))
        self.np_random.bit_generator.state = snap["rng"]
        return self._observe()

    # ------------------------------------------------------------------ state
    @property
    def agent_position(self) -> np.ndarray:
        return self._position.copy()

    @property
    def agent_rotation(self) -> np.ndarray:
        return quat_from_yaw(self._yaw)

    @property
    def agent_yaw(self) -> float:
        return self._yaw

    @property
    def goal_points(self) -> np.ndarray:
        return self._goals

    @property
    def crosses_storeys(self) -> bool:
        """Whether the episode runs on the joined surfaces of several storeys (a goal on another one)."""
        return self._motion is not None and self._motion is self.layered

    @property
    def start_position(self) -> np.ndarray:
        """The episode's declared start on the floor the episode runs on (what GPS is measured from)."""
        return self._start_position.copy()

    @property
    def start_yaw(self) -> float:
        return self._start_yaw

    @property
    def camera_tilt_deg(self) -> float:
        """Degrees LOOK_UP / LOOK_DOWN have pitched the camera (positive up), on top of ``camera_pitch_deg``."""
        return self._tilt

    def camera_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return camera_at(self._position, self._yaw, self.config, self._tilt)

    def render_rgb(self, position, rotation) -> np.ndarray:
        """The RGB sensor's image (its size, hfov, height and mounting pitch, no look tilt, no noise) for an
        agent standing at ``position`` with ``rotation`` [x, y, z, w]: what goal images are rendered with."""
        p = np.asarray(position, np.float64).reshape(-1)
        out = self._scene_renderer().render(*camera_at(p, yaw_from_quat(rotation), self.config), rgb=True,
                                            depth=False, ids=False)
        assert out.rgb is not None  # rendered when asked for
        return out.rgb

    # ------------------------------------------------------------------ habitat-sim's agent state
    def get_agent_state(self) -> AgentState:
        """The agent's state as habitat-sim's ``Agent.get_state()`` gives it: ``position`` (3,) on the floor,
        ``rotation`` [x, y, z, w] (a rotation about +y)."""
        return AgentState(self.agent_position, self.agent_rotation)

    def set_agent_state(self, position, rotation) -> None:
        """Place the agent as habitat-sim's ``set_agent_state`` does (no collision check); the episode goes
        on from there, its measures (distance to goal) read at the new place."""
        if self.episode is None:
            raise RuntimeError("call reset() before set_agent_state()")
        p = np.asarray(position, np.float64).reshape(-1)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ValueError(f"position must be 3 finite numbers, got {np.asarray(position).tolist()}")
        self._position, self._yaw = p.copy(), yaw_from_quat(rotation)

    def get_observations_at(self, position=None, rotation=None) -> dict[str, np.ndarray]:
        """The observations at ``position`` / ``rotation`` (the agent's own if None), noise included, as
        habitat-sim's ``get_observations_at``; the agent is left where it was."""
        saved = self._position, self._yaw
        try:
            if position is not None or rotation is not None:
                self.set_agent_state(saved[0] if position is None else position,
                                     quat_from_yaw(saved[1]) if rotation is None else rotation)
            return self._observe()
        finally:
            self._position, self._yaw = saved

    def distance_to_goal(self) -> float:
        return float(self._field.distance(self._position))

    # ------------------------------------------------------------------ sensors
    def _observe(self) -> dict[str, np.ndarray]:
        c = self.config
        obs: dict[str, np.ndarray] = {}
        self._last_rgb = None
        if self._renderer is not None and (c.rgb or c.depth or c.semantic):
            out = self._renderer.render(*self.camera_pose(), rgb=c.rgb, depth=c.depth, ids=c.semantic)
            if c.rgb:
                assert out.rgb is not None  # rendered when asked for
                obs["rgb"] = out.rgb
                self._last_rgb = out.rgb
                if c.rgb_noise is not None:
                    from navbench.env.noise import rgb_noise
                    assert self._rgb_rng is not None
                    obs["rgb"] = rgb_noise(out.rgb, c.rgb_noise, c.rgb_noise_intensity, self._rgb_rng)
            if c.depth:
                assert out.depth is not None
                depth = out.depth
                if c.depth_noise is not None:  # on metres, before the clip (a dropped pixel, 0, clips to min)
                    from navbench.env.noise import redwood_depth
                    assert self._depth_rng is not None
                    depth = redwood_depth(depth, c.depth_noise_multiplier, self._depth_rng)
                obs["depth"] = normalize_depth(depth, c.min_depth, c.max_depth, c.normalize_depth)
            if c.semantic:
                assert out.ids is not None
                obs["semantic"] = out.ids.astype(np.int32)[..., None]
        if c.gps_compass:
            obs["gps"] = gps(self._position, self._start_position, self._start_yaw)
            obs["compass"] = compass(self._yaw, self._start_yaw)
        if self._agent_pose:
            obs[AGENT_POSE] = np.concatenate([gps(self._position, self._start_position, self._start_yaw),
                                              compass(self._yaw, self._start_yaw)])
        obs.update(self._goal_observation())
        return obs

    def _goal_observation(self) -> dict[str, np.ndarray]:
        """The task's goal observations: per-episode ones as computed at reset (a copy: what a caller is given is
        its own), the others now."""
        return {s.uuid: self._episode_goals[s.uuid].copy() if s.per_episode else s.observe(self)
                for s in self.goal_sensors}

    def _info(self) -> dict[str, Any]:
        d = self.distance_to_goal()
        m = episode_metrics(self._stop_called, d, self._d0, self._path_length, self.success_distance)
        assert self.episode is not None  # set by reset()
        info = {
            "episode_id": self.episode.episode_id,
            "scene_id": self.episode.scene_id,
            "distance_to_goal": d,
            "success": m["success"],
            "spl": m["spl"],
            "soft_spl": m["soft_spl"],
            "num_steps": self._num_steps,
            "collisions": self._collisions,
            "path_length": self._path_length,
            "stop_called": self._stop_called,
            "geodesic_distance": self._d0,
        }
        if self.task_def.extra_info is not None:
            info.update(self.task_def.extra_info(self, info))
        return info
