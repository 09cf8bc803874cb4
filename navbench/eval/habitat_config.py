"""``navbench run --habitat-config FILE``: Habitat's own configuration, read as it is.

FILE is a resolved habitat-lab configuration (the yaml a habitat-baselines run writes: ``habitat:`` and
``habitat_baselines:`` at the top) or a habitat-baselines checkpoint holding one (``ckpt["config"]``, read
with ``torch.load(weights_only=True)``: nothing in the file is run; OmegaConf's nodes are read back as plain
values). The keys that set the score are used:

- ``habitat.task.type`` (``Nav-v0``: PointNav, ``ObjectNav-v1``: ObjectNav);
- ``habitat.environment.max_episode_steps``;
- ``habitat.task.measurements.success.success_distance`` and ``distance_to_goal.distance_to``;
- ``habitat.task.actions`` (which), ``habitat.simulator.forward_step_size``, ``turn_angle``, ``tilt_angle``;
- ``habitat.simulator.habitat_sim_v0.allow_sliding``;
- ``habitat.simulator.agents.main_agent`` ``height``, ``radius``, ``max_climb``, ``max_slope``;
- each sensor's ``width``, ``height``, ``hfov``, ``position``, ``orientation``, depth range and
  ``noise_model`` (``noise_model_kwargs``), and ``habitat.simulator.action_space_config`` (``pyrobotnoisy``:
  actuation noise, from ``action_space_config_arguments``);
- ``habitat.task.lab_sensors`` (GPS+compass or the static point goal);
- ``habitat.dataset.data_path`` (``{split}`` filled from ``habitat.dataset.split``) and ``scenes_dir``, when
  those files exist (``--split``, ``--episodes`` and ``--scene-dir`` override them).

A key among these whose value navbench cannot honour (an action it does not have, a sensor off the agent's
axis, a camera not at the agent's height, an unknown noise model...) is refused by its full name, in one line:
running anyway would score another benchmark. Every other key (rewards, trainer settings, ``habitat_baselines``)
does not change SR or SPL and is ignored; the run lists them once. What was used, key by key, is recorded in
config.json (``habitat_config``). The mapping is in docs/habitat_configs.md.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from navbench.env.config import EnvConfig
from navbench.safeio import printable, read_input

MAX_CONFIG_BYTES = 16 << 20
TASKS = {"Nav-v0": "pointnav", "ObjectNav-v1": "objectnav"}
ACTIONS = {"stop": "STOP", "move_forward": "MOVE_FORWARD", "turn_left": "TURN_LEFT", "turn_right": "TURN_RIGHT"}
LOOK_ACTIONS = {"look_up": "LOOK_UP", "look_down": "LOOK_DOWN"}
RGB_NOISE = {"GaussianNoiseModel": "gaussian", "SpeckleNoiseModel": "speckle", "PoissonNoiseModel": "poisson",
             "SaltAndPepperNoiseModel": "salt_and_pepper"}
ROBOTS = ("LoCoBot", "LoCoBot-Lite")
CONTROLLERS = ("ILQR", "Proportional", "Movebase")
SENSORS = ("rgb_sensor", "depth_sensor", "semantic_sensor")
GPS_SENSORS = ("pointgoal_with_gps_compass_sensor", "gps_sensor", "compass_sensor")
SIM = "habitat.simulator"
AGENT = f"{SIM}.agents.main_agent"
MEASURES = "habitat.task.measurements"


class HabitatConfigError(ValueError):
    """A configuration navbench cannot run as it is; the message names the file and the key."""


@dataclass
class HabitatSettings:
    """What a Habitat configuration sets: the task, the env, the success distance, the dataset files that exist,
    each value used by its full key, and the keys ignored."""
    path: Path
    sha256: str
    task: str
    env: EnvConfig
    success_distance: float | None
    episodes: Path | None = None
    scene_dir: Path | None = None
    used: dict[str, Any] = field(default_factory=dict)
    ignored: list[str] = field(default_factory=list)

    def record(self) -> dict[str, Any]:
        """config.json's ``habitat_config``: the file, its sha256, each value used, the keys ignored."""
        return {"file": str(self.path), "sha256": self.sha256, "used": dict(self.used), "ignored": list(self.ignored)}

    def ignored_line(self) -> str:
        """The ignored keys, once, grouped by their first two parts: ``ignored 120 keys (habitat_baselines.rl:
        80, ...)``."""
        groups: dict[str, int] = {}
        for k in self.ignored:
            g = ".".join(k.split(".")[:2])
            groups[g] = groups.get(g, 0) + 1
        shown = ", ".join(f"{g}: {n}" for g, n in sorted(groups.items(), key=lambda x: (-x[1], x[0]))[:8])
        more = "" if len(groups) <= 8 else f", and {len(groups) - 8} more groups"
        return f"{self.path}: ignored {len(self.ignored)} keys that do not change the score ({shown}{more})"


def _leaves(node: Any, prefix: str = "") -> dict[str, Any]:
    """Every leaf of a nested mapping by its dotted key (lists are leaves)."""
    if isinstance(node, dict):
        out: dict[str, Any] = {}
        for k, v in node.items():
            out.update(_leaves(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    return {prefix: node}


class _Reader:
    """Reads typed values out of the configuration, recording each one used."""

    def __init__(self, path: Path, doc: dict[str, Any]):
        self.path, self.doc, self.used = path, doc, {}
        self.leaves = _leaves(doc)

    def refuse(self, key: str, why: str) -> HabitatConfigError:
        return HabitatConfigError(printable(f"{self.path}: {key}: {why}; navbench cannot honour it, and running "
                                            f"without it would score another benchmark", 600))

    def node(self, key: str) -> Any:
        cur: Any = self.doc
        for part in key.split("."):
            if not isinstance(cur, dict) or part not in cur:
                return None
            cur = cur[part]
        return cur

    def get(self, key: str, kind: type | tuple[type, ...], default: Any = None) -> Any:
        v = self.node(key)
        if v is None:
            return default
        if isinstance(v, bool) and kind is not bool or not isinstance(v, kind) or \
                isinstance(v, float) and not math.isfinite(v):
            raise HabitatConfigError(printable(f"{self.path}: {key}: expected {getattr(kind, '__name__', kind)}, "
                                               f"got {v!r}", 300))
        self.used[key] = v
        return v

    def number(self, key: str, default: float | None = None) -> float | None:
        v = self.get(key, (int, float))
        return default if v is None else float(v)

    def vector(self, key: str) -> list[float] | None:
        v = self.node(key)
        if v is None:
            return None
        if not isinstance(v, list) or len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                             for x in v):
            raise HabitatConfigError(printable(f"{self.path}: {key}: expected [x, y, z], got {v!r}", 300))
        self.used[key] = v
        return [float(x) for x in v]


def _load(path: Path) -> dict[str, Any]:
    """The configuration as plain data: a yaml file's, or a checkpoint's ``config``."""
    if path.suffix in (".pth", ".pt", ".ckpt"):
        from navbench.policy.checkpoint import CheckpointError, read_checkpoint_config
        try:
            doc = read_checkpoint_config(path)
        except CheckpointError as exc:
            raise HabitatConfigError(str(exc)) from None
    else:
        import yaml
        try:
            doc = yaml.safe_load(read_input(path, MAX_CONFIG_BYTES, gunzip=False))
        except (OSError, ValueError, yaml.YAMLError) as exc:  # size and UTF-8 errors are ValueErrors
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise HabitatConfigError(printable(f"{path}: not a readable yaml configuration ({first})", 300)) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("habitat"), dict):
        raise HabitatConfigError(f"{path}: no 'habitat' section: not a resolved habitat-lab configuration")
    return doc


def read_habitat_config(path: str | Path) -> HabitatSettings:
    """The settings a Habitat configuration file (yaml, or a checkpoint holding one) sets (module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise HabitatConfigError(f"{path}: no such file")
    doc = _load(path)
    r = _Reader(path, doc)
    env: dict[str, Any] = {}

    task_type = r.get("habitat.task.type", str)
    if task_type not in TASKS:
        raise r.refuse("habitat.task.type", f"{task_type!r} (navbench runs {', '.join(TASKS)})")
    task = TASKS[task_type]
    if (steps := r.get("habitat.environment.max_episode_steps", int)) is not None:
        env["max_steps"] = steps
    sd = r.number(f"{MEASURES}.success.success_distance")
    distance_to = r.get(f"{MEASURES}.distance_to_goal.distance_to", str)
    if distance_to is not None and distance_to != ("POINT" if task == "pointnav" else "VIEW_POINTS"):
        raise r.refuse(f"{MEASURES}.distance_to_goal.distance_to",
                       f"{distance_to!r} (navbench measures {task} to "
                       f"{'the goal point' if task == 'pointnav' else 'the goals view points'})")

    _actions(r, env)
    for key, name in (("forward_step_size", "forward_step"), ("turn_angle", "turn_angle_deg")):
        if (v := r.number(f"{SIM}.{key}")) is not None:
            env[name] = v
    if (sliding := r.get(f"{SIM}.habitat_sim_v0.allow_sliding", bool)) is not None:
        env["allow_sliding"] = sliding
    for key, name in (("height", "agent_height"), ("radius", "agent_radius"), ("max_climb", "max_climb")):
        if (v := r.number(f"{AGENT}.{key}")) is not None:
            env[name] = v
    if (slope := r.number(f"{AGENT}.max_slope")) is not None and slope != 45.0:
        raise r.refuse(f"{AGENT}.max_slope", f"{slope:g} deg (navbench walks slopes up to 45 deg)")
    _sensors(r, env)
    _actuation(r, env)
    _lab_sensors(r, env, task)

    try:
        cfg = EnvConfig(**env)
    except (TypeError, ValueError) as exc:
        raise HabitatConfigError(printable(f"{path}: {exc}", 300)) from None
    episodes, scene_dir = _dataset(r)
    used = set(r.used)
    ignored = sorted(k for k in r.leaves if k not in used and not any(k.startswith(u + ".") for u in used))
    return HabitatSettings(path=path, sha256=hashlib.sha256(path.read_bytes()).hexdigest(), task=task, env=cfg,
                           success_distance=sd, episodes=episodes, scene_dir=scene_dir, used=dict(r.used),
                           ignored=ignored)


def _actions(r: _Reader, env: dict[str, Any]) -> None:
    actions = r.node("habitat.task.actions")
    if actions is None:
        return
    if not isinstance(actions, dict) or not actions:
        raise HabitatConfigError(printable(f"{r.path}: habitat.task.actions: expected a mapping of actions, "
                                           f"got {actions!r}", 300))
    known = dict(ACTIONS)
    has_actions = "actions" in {f.name for f in dataclasses.fields(EnvConfig)}
    if has_actions:  # an EnvConfig that takes an action list takes the camera's tilts too
        known.update(LOOK_ACTIONS)
    names = []
    for name in actions:
        if name not in known:
            raise r.refuse(f"habitat.task.actions.{name}", f"navbench's actions are {', '.join(known)}")
        names.append(known[name])
    r.used["habitat.task.actions"] = list(actions)
    if names != list(ACTIONS.values()):
        if not has_actions:  # the four in another order would renumber the action ids
            raise r.refuse("habitat.task.actions", f"{list(actions)} (navbench's ids are {', '.join(ACTIONS)} "
                                                   f"in this order)")
        env["actions"] = tuple(names)
        if any(n in LOOK_ACTIONS.values() for n in names) and (tilt := r.number(f"{SIM}.tilt_angle")) is not None:
            env["tilt_angle_deg"] = tilt


def _sensors(r: _Reader, env: dict[str, Any]) -> None:
    sensors = r.node(f"{AGENT}.sim_sensors")
    if sensors is None:
        return
    if not isinstance(sensors, dict):
        raise HabitatConfigError(printable(f"{r.path}: {AGENT}.sim_sensors: expected a mapping", 300))
    geometry: dict[str, tuple[str, Any]] = {}  # navbench's one value per field, and the key that set it

    def agree(name: str, key: str, value: Any) -> None:
        if name in geometry and geometry[name][1] != value:
            raise r.refuse(key, f"{value!r}, while {geometry[name][0]} is {geometry[name][1]!r} (navbench's "
                                f"sensors share one {name})")
        geometry[name] = (key, value)
        env[name] = value

    height = env.get("agent_height", EnvConfig.agent_height)
    for sensor in sensors:
        base = f"{AGENT}.sim_sensors.{sensor}"
        if sensor not in SENSORS:
            raise r.refuse(base, f"navbench renders {', '.join(SENSORS)}")
        if (sub := r.get(f"{base}.sensor_subtype", str)) is not None and sub.upper() != "PINHOLE":
            raise r.refuse(f"{base}.sensor_subtype", f"{sub!r} (navbench's cameras are pinhole)")
        for key, name in (("width", "width"), ("height", "height")):
            if (v := r.get(f"{base}.{key}", int)) is not None:
                agree(name, f"{base}.{key}", v)
        if (v := r.number(f"{base}.hfov")) is not None:
            agree("hfov_deg", f"{base}.hfov", v)
        if (pos := r.vector(f"{base}.position")) is not None:
            if pos[0] != 0.0 or pos[2] != 0.0:
                raise r.refuse(f"{base}.position", f"{pos} (navbench's camera is on the agent's axis)")
            if not math.isclose(pos[1], height, abs_tol=1e-6):
                raise r.refuse(f"{base}.position", f"a camera {pos[1]:g} m high on an agent {height:g} m tall "
                                                   f"(navbench's camera is at the agent's height)")
        if (ori := r.vector(f"{base}.orientation")) is not None:
            if ori[1] != 0.0 or ori[2] != 0.0:
                raise r.refuse(f"{base}.orientation", f"{ori} (navbench's camera only pitches)")
            agree("camera_pitch_deg", f"{base}.orientation", round(math.degrees(ori[0]), 4))
        if sensor == "depth_sensor":
            for key in ("min_depth", "max_depth"):
                if (v := r.number(f"{base}.{key}")) is not None:
                    env[key] = v
            if (v := r.get(f"{base}.normalize_depth", bool)) is not None:
                env["normalize_depth"] = v
        _noise(r, base, sensor, env)


def _noise(r: _Reader, base: str, sensor: str, env: dict[str, Any]) -> None:
    model = r.get(f"{base}.noise_model", str)
    kwargs = r.node(f"{base}.noise_model_kwargs") or {}
    if model in (None, "None"):
        if kwargs:
            raise r.refuse(f"{base}.noise_model_kwargs", "set without a noise model")
        return
    if not isinstance(kwargs, dict):
        raise HabitatConfigError(printable(f"{r.path}: {base}.noise_model_kwargs: expected a mapping", 300))
    if sensor == "rgb_sensor" and model in RGB_NOISE:
        env["rgb_noise"] = RGB_NOISE[model]
        allowed = {"intensity_constant": "rgb_noise_intensity"}
    elif sensor == "depth_sensor" and model == "RedwoodDepthNoiseModel":
        env["depth_noise"] = "redwood"
        allowed = {"noise_multiplier": "depth_noise_multiplier"}
    else:
        raise r.refuse(f"{base}.noise_model", f"{model!r} on the {sensor} (navbench models "
                       f"{', '.join(RGB_NOISE)} on RGB and RedwoodDepthNoiseModel on depth)")
    for k in kwargs:
        if k not in allowed:
            raise r.refuse(f"{base}.noise_model_kwargs.{k}", f"navbench's {model} takes {', '.join(allowed)}")
        env[allowed[k]] = r.number(f"{base}.noise_model_kwargs.{k}")


def _actuation(r: _Reader, env: dict[str, Any]) -> None:
    space = r.get(f"{SIM}.action_space_config", str)
    if space in (None, "v0", "v1"):
        return
    if space != "pyrobotnoisy":
        raise r.refuse(f"{SIM}.action_space_config", f"{space!r} (navbench has v0, v1 and pyrobotnoisy)")
    base = f"{SIM}.action_space_config_arguments"
    robot = r.get(f"{base}.robot", str, "LoCoBot")
    controller = r.get(f"{base}.controller", str, "ILQR")
    if robot not in ROBOTS:
        raise r.refuse(f"{base}.robot", f"{robot!r} (navbench's robots: {', '.join(ROBOTS)})")
    if controller not in CONTROLLERS:
        raise r.refuse(f"{base}.controller", f"{controller!r} (navbench's controllers: {', '.join(CONTROLLERS)})")
    env["actuation_noise"] = f"{robot}-{controller}"
    if (m := r.number(f"{base}.noise_multiplier")) is not None:
        env["actuation_noise_multiplier"] = m


def _lab_sensors(r: _Reader, env: dict[str, Any], task: str) -> None:
    sensors = r.node("habitat.task.lab_sensors")
    if not isinstance(sensors, dict):
        return
    r.used["habitat.task.lab_sensors"] = sorted(sensors)
    gps = any(s in sensors for s in GPS_SENSORS)
    if task == "pointnav" and not gps and "pointgoal_sensor" not in sensors:
        raise r.refuse("habitat.task.lab_sensors", f"{sorted(sensors)}: no point goal sensor")
    env["gps_compass"] = gps


def _dataset(r: _Reader) -> tuple[Path | None, Path | None]:
    """The episode file and scene directory the dataset keys name, where they exist."""
    data_path = r.node("habitat.dataset.data_path")
    split = r.node("habitat.dataset.split")
    episodes = None
    if isinstance(data_path, str):
        p = Path(data_path.replace("{split}", str(split)) if isinstance(split, str) else data_path)
        if p.is_file():
            episodes = p
            r.used["habitat.dataset.data_path"] = data_path
            if isinstance(split, str):
                r.used["habitat.dataset.split"] = split
    scenes = r.node("habitat.dataset.scenes_dir")
    scene_dir = Path(scenes) if isinstance(scenes, str) and Path(scenes).is_dir() else None
    if scene_dir is not None:
        r.used["habitat.dataset.scenes_dir"] = scenes
    return episodes, scene_dir


def run_arguments(settings: HabitatSettings, task: str | None, split: str | None, episodes: Any, scene_dir: Any,
                  success_distance: float | None) -> tuple[str, Any, Any, float | None]:
    """``(task, episodes, scene_dir, success_distance)`` of a run under ``settings``: the configuration's,
    except what the flags give (``--split`` or ``--episodes`` over the dataset's file, ``--scene-dir``,
    ``--success-distance``); a ``--task`` other than the configuration's is refused. A dataset key the flags
    override moves from ``used`` to ``ignored``."""
    if task is not None and task != settings.task:
        raise HabitatConfigError(f"{settings.path}: habitat.task.type is {settings.task}'s, not {task}'s (--task)")

    def unused(*keys: str) -> None:
        for k in keys:
            if settings.used.pop(k, None) is not None:
                settings.ignored.append(k)

    if split is None and episodes is None and settings.episodes is not None:
        episodes = settings.episodes
    else:
        unused("habitat.dataset.data_path", "habitat.dataset.split")
    if scene_dir is None and settings.scene_dir is not None:
        scene_dir = settings.scene_dir
    else:
        unused("habitat.dataset.scenes_dir")
    if success_distance is not None:
        unused(f"{MEASURES}.success.success_distance")
    sd = success_distance if success_distance is not None else settings.success_distance
    settings.ignored.sort()
    return settings.task, episodes, scene_dir, sd
