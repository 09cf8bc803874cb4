"""``habitat_sim.Simulator`` over navbench: the scene from :mod:`navbench.scene`, the path finder over its
navigability grid, the agents and their sensors rendered by :mod:`navbench.render`.

Semantics follow habitat-sim's ``src_python/habitat_sim/simulator.py``: each agent starts at a random navigable
point with a random yaw (drawn from the simulator's generator, seeded by ``sim_cfg.random_seed`` and :meth:`seed`);
:meth:`reset` returns the agents to that state; :meth:`step` acts, filters body moves through the path finder
(``try_step``, or ``try_step_no_sliding`` without ``allow_sliding``) and returns the observations with
``"collided"``; :meth:`reconfigure` reloads only what a changed configuration changes. ``semantic_scene`` and the
SEMANTIC sensor's ids follow habitat-sim's loaders for HM3D and MP3D (:mod:`navbench.habitat_sim._semantic`).
Physics, the batch renderer and object templates are refused in one line.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from navbench.habitat_sim import _semantic
from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.agent.agent import Agent, AgentState
from navbench.habitat_sim.agent.controls import ObjectControls
from navbench.habitat_sim.config import Configuration, SensorSubType, SensorType
from navbench.habitat_sim.nav import GreedyGeodesicFollower, PathFinder, nav_grid_config
from navbench.habitat_sim.scene import SceneNode, SemanticScene
from navbench.habitat_sim.sensor import COVERAGE, Sensor, apply_noise, check_spec
from navbench.habitat_sim.utils.common import quat_from_angle_axis

__all__ = ["Simulator"]


class _ObjectTemplateManager:
    """Object templates are for physics and rearrangement; navigation loads none."""

    def load_configs(self, path: str, *args, **kwargs) -> list[int]:
        raise NotImplementedError(f"object templates ({path!r}): {COVERAGE} (no objects beside the scene)")


class Simulator:
    """habitat-sim's simulator over a navbench scene; ``config`` is a :class:`Configuration`."""

    def __init__(self, config: Configuration) -> None:
        self.config: Configuration | None = None
        self.agents: list[Agent] = []
        self.pathfinder = PathFinder()
        self.semantic_scene = SemanticScene()
        self.random = np.random.default_rng(0)
        self._nb_scene_key: tuple | None = None
        self._nb_asset = None
        self._nb_render_asset = None  # the asset with the SEMANTIC sensor's per-face ids (habitat-sim's)
        self._nb_renderers: dict[Any, Any] = {}
        self._nb_closed = False
        self._nb_noise_rng = np.random.default_rng([0, 1])
        self._nb_configure(config)  # not reconfigure: subclasses (habitat-lab's HabitatSim) override it

    # ------------------------------------------------------------------ configuration
    def reconfigure(self, config: Configuration) -> None:
        """Apply ``config``; the scene is reloaded only when it (or the navmesh settings) changed."""
        self._nb_configure(config)

    def _nb_configure(self, config: Configuration) -> None:
        if self.config is not None and config == self.config and not self._nb_closed:
            return
        sim_cfg = config.sim_cfg
        if config.enable_batch_renderer:
            raise NotImplementedError(f"enable_batch_renderer: {COVERAGE} (no batch renderer)")
        if sim_cfg.enable_physics:
            raise NotImplementedError(f"enable_physics: {COVERAGE} (no physics)")
        if len(config.agents) != 1:
            raise NotImplementedError(f"{len(config.agents)} agents: navbench's habitat_sim runs one agent")
        for agent_cfg in config.agents:
            for spec in agent_cfg.sensor_specifications:
                check_spec(spec)
        key = (str(sim_cfg.scene_id), repr(sim_cfg.navmesh_settings))
        if key != self._nb_scene_key or self._nb_closed:
            self._nb_load_scene(sim_cfg)
            self._nb_scene_key = key
        self._nb_closed = False
        self.config = config
        self.seed(int(sim_cfg.random_seed))
        self.agents = []
        for agent_id, agent_cfg in enumerate(config.agents):
            agent = Agent(SceneNode(), agent_cfg, ObjectControls(self.step_filter))
            self.agents.append(agent)
            for spec in agent_cfg.sensor_specifications:
                agent._sensors[spec.uuid] = Sensor(spec, agent.scene_node, self)
            self.initialize_agent(agent_id)

    def _nb_load_scene(self, sim_cfg) -> None:
        from navbench.scene.cache import load_scene_and_navgrid

        path = Path(str(sim_cfg.scene_id))
        if not path.is_file():
            raise FileNotFoundError(f"{path}: scene file not found (SimulatorConfiguration.scene_id)")
        self._nb_close_renderers()
        self._nb_asset, grid = load_scene_and_navgrid(path, nav_grid_config(sim_cfg.navmesh_settings))
        self.pathfinder.load_grid(grid, sim_cfg.navmesh_settings, self._nb_asset)
        self.semantic_scene, face_ids = _semantic.load_semantics(self._nb_asset)
        self._nb_render_asset = _semantic.render_asset(self._nb_asset, face_ids)

    @property
    def _default_agent_id(self) -> int:
        assert self.config is not None
        return int(self.config.sim_cfg.default_agent_id)

    def get_agent(self, agent_id: int) -> Agent:
        return self.agents[agent_id]

    def initialize_agent(self, agent_id: int, initial_state: AgentState | None = None) -> Agent:
        agent = self.get_agent(agent_id)
        if initial_state is None:
            initial_state = AgentState()
            if self.pathfinder.is_loaded:
                initial_state.position = np.asarray(self.pathfinder.get_random_navigable_point(), np.float32)
                initial_state.rotation = quat_from_angle_axis(float(self.random.uniform(0.0, 2.0 * math.pi)),
                                                              np.array([0.0, 1.0, 0.0]))
        agent.set_state(initial_state, is_initial=True)
        return agent

    def seed(self, new_seed: int) -> None:
        """Seeds the agents' random starts, the path finder's random points and the sensors' noise."""
        self.random = np.random.default_rng(int(new_seed))
        self.pathfinder.seed(int(new_seed))
        self._nb_noise_rng = np.random.default_rng([int(new_seed), 1])  # a stream of its own: renders draw here

    def get_object_template_manager(self) -> _ObjectTemplateManager:
        return _ObjectTemplateManager()

    # ------------------------------------------------------------------ sensors
    @property
    def sensors(self) -> dict[str, Sensor]:
        """The default agent's sensors by uuid (habitat-sim's ``sim.sensors``; ``_sensors`` is the older name)."""
        return self.get_agent(self._default_agent_id)._sensors

    @property
    def _sensors(self) -> dict[str, Sensor]:
        return self.sensors

    def get_sensor(self, uuid: str) -> Sensor:
        for agent in self.agents:
            if uuid in agent._sensors:
                return agent._sensors[uuid]
        raise KeyError(f"no sensor {uuid!r}")

    def add_sensor(self, sensor_spec, agent_id: int | None = None) -> None:
        agent = self.get_agent(self._default_agent_id if agent_id is None else agent_id)
        if sensor_spec.uuid in agent._sensors:
            raise ValueError(f"sensor {sensor_spec.uuid!r} already exists")
        agent._sensors[sensor_spec.uuid] = Sensor(sensor_spec, agent.scene_node, self)
        agent.agent_config.sensor_specifications.append(sensor_spec)

    def remove_sensor(self, uuid: str, agent_id: int | None = None) -> None:
        agent = self.get_agent(self._default_agent_id if agent_id is None else agent_id)
        sensor = agent._sensors.pop(uuid)
        specs = agent.agent_config.sensor_specifications
        agent.agent_config.sensor_specifications = [s for s in specs if s is not sensor.specification()]

    def _nb_renderer(self, spec):
        from navbench.render.camera import CameraConfig
        from navbench.render.renderer import Renderer

        h, w = (int(v) for v in np.asarray(spec.resolution).reshape(2))
        ortho = float(spec.ortho_scale) if spec.sensor_subtype == SensorSubType.ORTHOGRAPHIC else None
        camera = CameraConfig(width=w, height=h, hfov_deg=float(spec.hfov), znear=float(spec.near),
                              zfar=float(spec.far), ortho_scale=ortho)
        if camera not in self._nb_renderers:
            self._nb_renderers[camera] = Renderer(self._nb_render_asset, camera)
        return self._nb_renderers[camera]

    def _nb_render(self, sensors: list[Sensor]) -> dict[str, np.ndarray]:
        """Each sensor's observation; sensors with the same camera and pose share one frame."""
        groups: dict[tuple, list[Sensor]] = {}
        poses: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        for s in sensors:
            pos, rot = s.world_pose()
            spec = s.specification()
            ortho = float(spec.ortho_scale) if spec.sensor_subtype == SensorSubType.ORTHOGRAPHIC else None
            key = (tuple(np.asarray(spec.resolution).reshape(2).tolist()), float(spec.hfov), float(spec.near),
                   float(spec.far), ortho, pos.tobytes(), rot.tobytes())
            groups.setdefault(key, []).append(s)
            poses[key] = pos, rot
        out: dict[str, np.ndarray] = {}
        for key, members in groups.items():
            kinds = {m.specification().sensor_type for m in members}
            pos, rot = poses[key]
            frame = self._nb_renderer(members[0].specification()).render(
                pos, rot, rgb=SensorType.COLOR in kinds, depth=SensorType.DEPTH in kinds,
                ids=SensorType.SEMANTIC in kinds, rgba=True)
            taken: set = set()  # the frame's arrays are the renderer's fresh ones: the first sensor of a kind keeps it
            for m in members:
                kind = m.specification().sensor_type
                if kind == SensorType.COLOR:
                    obs = frame.rgb.copy() if kind in taken else frame.rgb
                elif kind == SensorType.DEPTH:
                    obs = np.asarray(frame.depth, np.float32)
                    obs = obs.copy() if kind in taken else obs
                else:  # navbench's instance ids; structure and background (-1) are 0
                    obs = np.maximum(np.asarray(frame.ids, np.int64), 0).astype(np.uint32)
                taken.add(kind)
                out[m.uuid] = apply_noise(m.specification(), obs, self._nb_noise_rng)
        return out

    def get_sensor_observations(self, agent_ids: int | list[int] = 0):
        """``{uuid: observation}`` of one agent, or ``{agent_id: {uuid: observation}}`` for a list."""
        ids = [agent_ids] if isinstance(agent_ids, (int, np.integer)) else list(agent_ids)
        result = {}
        for agent_id in ids:
            sensors = list(self.get_agent(agent_id)._sensors.values())
            obs = self._nb_render(sensors) if sensors else {}
            for s in sensors:
                s._obs = obs[s.uuid]
            result[agent_id] = obs
        return result[ids[0]] if isinstance(agent_ids, (int, np.integer)) else result

    # ------------------------------------------------------------------ acting
    def step_filter(self, start, end) -> mn.Vector3:
        """The move filter of body actions: the path finder's ``try_step`` (``try_step_no_sliding`` when
        ``allow_sliding`` is off), or ``end`` without navigability."""
        if not self.pathfinder.is_loaded:
            return mn.Vector3(end)
        assert self.config is not None
        if self.config.sim_cfg.allow_sliding:
            return self.pathfinder.try_step(start, end)
        return self.pathfinder.try_step_no_sliding(start, end)

    def reset(self, agent_ids: int | list[int] | None = None):
        ids = [self._default_agent_id] if agent_ids is None else (
            [agent_ids] if isinstance(agent_ids, (int, np.integer)) else list(agent_ids))
        for agent_id in ids:
            agent = self.get_agent(agent_id)
            if agent.initial_state is None:
                raise RuntimeError("reset called before agent was given an initial state")
            self.initialize_agent(agent_id, agent.initial_state)
        obs = self.get_sensor_observations(agent_ids=ids)
        return obs[ids[0]] if agent_ids is None or isinstance(agent_ids, (int, np.integer)) else obs

    def step(self, action, dt: float = 1.0 / 60.0):
        single = not isinstance(action, dict)
        actions = {self._default_agent_id: action} if single else action
        collided = {}
        for agent_id, act in actions.items():
            agent = self.get_agent(agent_id)
            collided[agent_id] = agent.act(act)
        self.step_world(dt)
        obs = self.get_sensor_observations(agent_ids=list(actions))
        for agent_id, o in obs.items():
            o["collided"] = collided[agent_id]
        return obs[self._default_agent_id] if single else obs

    def step_world(self, dt: float = 1.0 / 60.0) -> None:
        """Advances physics; a no-op without physics."""

    def step_physics(self, dt: float = 1.0 / 60.0) -> None:
        """Advances physics; a no-op without physics."""

    def make_greedy_follower(self, agent_id: int = 0, goal_radius: float | None = None, *, stop_key=None,
                             forward_key=None, left_key=None, right_key=None, fix_thrashing: bool = True,
                             thrashing_threshold: int = 16) -> GreedyGeodesicFollower:
        return GreedyGeodesicFollower(self.pathfinder, self.get_agent(agent_id), goal_radius, stop_key=stop_key,
                                      forward_key=forward_key, left_key=left_key, right_key=right_key,
                                      fix_thrashing=fix_thrashing, thrashing_threshold=thrashing_threshold)

    # ------------------------------------------------------------------ lifetime
    def _nb_close_renderers(self) -> None:
        for renderer in self._nb_renderers.values():
            renderer.close()
        self._nb_renderers = {}

    def close(self, destroy: bool = True) -> None:
        self._nb_close_renderers()
        for agent in self.agents:
            agent.close()
        self._nb_closed = True
        if destroy:
            self.agents = []
            self.config = None
            self._nb_scene_key = None

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self._nb_close_renderers()
        except Exception:  # interpreter teardown: the GL library may be gone
            pass
