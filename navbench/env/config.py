"""Environment configuration: the agent, its sensors and the episode limits (HM3D ObjectNav defaults)."""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import TYPE_CHECKING, Any

from navbench.paths import CONFIGS_DIR
from navbench.tasks import TASKS
from navbench.tasks.base import NAV_ACTIONS
from navbench.tasks.objectnav import OVON_SUCCESS_DISTANCE

if TYPE_CHECKING:
    from navbench.scene.navigability import NavGridConfig

# Habitat's action ids (habitat-lab habitat/sims/habitat_simulator/actions.py, HabitatSimActions).
STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, LOOK_UP, LOOK_DOWN = 0, 1, 2, 3, 4, 5
ACTION_NAMES = NAV_ACTIONS  # the default action list: STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT
# Every action the env can take, by name and in Habitat's id order; an EnvConfig's ``actions`` are the first
# four or more of them, so that an action's name and its id agree in every configuration.
KNOWN_ACTIONS = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP", "LOOK_DOWN")


class Action(IntEnum):
    """Habitat's action ids, as an agent's ``act`` may return them (a plain int works too). LOOK_UP and
    LOOK_DOWN exist only under an EnvConfig whose ``actions`` list them (``habitat-objectnav-hm3d``).

    >>> Action.MOVE_FORWARD == 1, Action(3).name
    (True, 'TURN_RIGHT')
    """
    STOP = STOP
    MOVE_FORWARD = MOVE_FORWARD
    TURN_LEFT = TURN_LEFT
    TURN_RIGHT = TURN_RIGHT
    LOOK_UP = LOOK_UP
    LOOK_DOWN = LOOK_DOWN


# Success distances by task as the task registry (navbench.tasks) defines them; "ovon": HM3D-OVON's.
SUCCESS_DISTANCE = {**{name: t.success_distance for name, t in TASKS.items()}, "ovon": OVON_SUCCESS_DISTANCE}

# The noise models navbench.env.noise samples: habitat-sim's PyRobot robots and controllers, its depth and RGB models.
ACTUATION_NOISE = tuple(f"{robot}-{controller}" for robot in ("LoCoBot", "LoCoBot-Lite")
                        for controller in ("ILQR", "Proportional", "Movebase"))
DEPTH_NOISE = ("redwood",)
RGB_NOISE = ("gaussian", "speckle", "poisson", "salt_and_pepper")
# Knobs of Habitat's realistic conditions (navbench.env.noise; docs/realistic.md), with the values that
# leave a noiseless, level-camera run. A run's protocol lists them only when they differ from these.
CONDITIONS = {"actuation_noise": None, "actuation_noise_multiplier": 1.0, "depth_noise": None,
              "depth_noise_multiplier": 1.0, "rgb_noise": None, "rgb_noise_intensity": 0.2,
              "camera_pitch_deg": 0.0, "gps_compass": True}


@dataclass(frozen=True)
class EnvConfig:
    # sensors
    width: int = 224
    height: int = 224
    hfov_deg: float = 79.0
    min_depth: float = 0.5
    max_depth: float = 5.0
    normalize_depth: bool = True
    rgb: bool = True
    depth: bool = True
    semantic: bool = False  # per-pixel instance ids (Habitat's "semantic" sensor), -1 for structure
    # agent
    agent_height: float = 0.88  # camera height above the floor, and the clearance the agent needs
    agent_radius: float = 0.18
    max_climb: float = 0.2
    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    # The action list, by Habitat's ids (names from KNOWN_ACTIONS); None: the task's (STOP, MOVE_FORWARD,
    # TURN_LEFT, TURN_RIGHT). LOOK_UP / LOOK_DOWN tilt the camera by tilt_angle_deg about its x axis with no
    # limit, as habitat-lab's LookUpAction / LookDownAction do (habitat/tasks/nav/nav.py; its default 15).
    actions: tuple[str, ...] | None = None
    tilt_angle_deg: float = 15.0
    allow_sliding: bool = False  # HM3D ObjectNav: no sliding along walls
    # episode
    max_steps: int = 500
    success_distance: float | None = None  # None: the task's default (SUCCESS_DISTANCE)
    # An episode start up to this far from the navigable grid is snapped onto it: real datasets were made
    # on habitat-sim's navmesh, whose boundary differs from our grid by a cell or two.
    start_snap_tolerance: float = 0.25
    # infrastructure
    cell_size: float = 0.05
    # "auto": EGL when a GPU is present, else OSMesa (navbench.render.gl_platform); or "osmesa", "egl"
    gl_platform: str = "auto"
    # realistic conditions (navbench.env.noise; docs/realistic.md): habitat-sim's PyRobot actuation noise as
    # "<robot>-<controller>" ("LoCoBot-Proportional", "LoCoBot-Lite-ILQR", ...), Redwood depth noise ("redwood"),
    # RGB noise ("gaussian" with habitat-sim's intensity_constant; also "speckle", "poisson", "salt_and_pepper"),
    # the camera's pitch (Habitat's sensor orientation about x, negative looks down) and whether GPS+compass
    # are sensed (without: PointNav's goal is the static `pointgoal`, polar from the start, as Habitat's
    # PointNav challenges give it)
    actuation_noise: str | None = None
    actuation_noise_multiplier: float = 1.0
    depth_noise: str | None = None
    depth_noise_multiplier: float = 1.0
    rgb_noise: str | None = None
    rgb_noise_intensity: float = 0.2
    camera_pitch_deg: float = 0.0
    gps_compass: bool = True

    def __post_init__(self) -> None:
        if self.actions is not None:
            if isinstance(self.actions, str) or not all(isinstance(a, str) for a in self.actions):
                raise ValueError(f"actions must be a list of action names, got {self.actions!r}"[:200])
            names = tuple(a.upper() for a in self.actions)
            unknown = [a for a in names if a not in KNOWN_ACTIONS]
            if unknown:
                raise ValueError(f"actions: unknown {', '.join(unknown)}; choose from {', '.join(KNOWN_ACTIONS)}")
            if names != KNOWN_ACTIONS[:len(names)] or len(names) < len(NAV_ACTIONS):
                raise ValueError(f"actions must be Habitat's, in its id order ({', '.join(KNOWN_ACTIONS)}; the first "
                                 f"{len(NAV_ACTIONS)} at least), got {', '.join(names)}")
            object.__setattr__(self, "actions", names)
        if not (isinstance(self.tilt_angle_deg, (int, float)) and 0 < self.tilt_angle_deg <= 180):
            raise ValueError(f"tilt_angle_deg must be within (0, 180], got {self.tilt_angle_deg!r}")
        for name, value, known in (("actuation_noise", self.actuation_noise, ACTUATION_NOISE),
                                   ("depth_noise", self.depth_noise, DEPTH_NOISE),
                                   ("rgb_noise", self.rgb_noise, RGB_NOISE)):
            if value is not None and value not in known:
                raise ValueError(f"{name} {value!r}: choose one of {', '.join(known)} (or none)")
        for name in ("actuation_noise_multiplier", "depth_noise_multiplier", "rgb_noise_intensity"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v < float("inf")):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if not -90.0 < self.camera_pitch_deg < 90.0:
            raise ValueError(f"camera_pitch_deg must be within (-90, 90), got {self.camera_pitch_deg!r}")

    @property
    def noisy(self) -> bool:
        """Whether any of actuation, depth or RGB noise is on."""
        return bool(self.actuation_noise or self.depth_noise or self.rgb_noise)

    def conditions(self) -> dict[str, Any]:
        """The realistic-condition knobs that differ from a noiseless, level, GPS+compass run."""
        return {k: getattr(self, k) for k, v in CONDITIONS.items() if getattr(self, k) != v}

    def overrides(self) -> dict[str, Any]:
        """The fields that differ from ``EnvConfig()``, as a run's config.json records them (``env``); which
        images are rendered and the success distance are the run's, not the configuration's."""
        base = EnvConfig()
        return {f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v  # as JSON holds it
                for f in dataclasses.fields(self) if f.name not in ("rgb", "depth", "semantic", "success_distance")
                and getattr(self, f.name) != getattr(base, f.name)}

    @classmethod
    def load(cls, name_or_path: str | Path) -> EnvConfig:
        """A named configuration (``configs/env/NAME.toml``: see :func:`env_config_names`) or a TOML file of
        EnvConfig fields. A missing file, an unknown field or a bad value is a one-line ValueError."""
        path = env_config_path(name_or_path)
        try:
            data = tomllib.loads(path.read_text())
        except OSError as exc:
            raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: not valid TOML ({exc})") from None
        data.pop("tasks", None)  # the tasks it is made for: env_config_tasks
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"{path}: unknown EnvConfig field(s) {', '.join(unknown)}")
        try:
            return cls(**data)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{path}: {exc}") from None

    def nav_grid_config(self) -> NavGridConfig:
        """The navigability grid this body moves on: its height, radius and climb, at ``cell_size``."""
        # imported here: this module is read by the CLI at start-up, the grid's module pulls trimesh and cv2
        from navbench.scene.navigability import NavGridConfig
        return NavGridConfig(agent_height=self.agent_height, agent_radius=self.agent_radius,
                             max_climb=self.max_climb, cell_size=self.cell_size)


def env_config_tasks(name_or_path: str | Path) -> tuple[str, ...]:
    """The tasks a configuration is made for: its ``tasks = [...]`` (task names), or () when it names none and
    fits every task (navbench's own conditions). A bad ``tasks`` is a one-line ValueError naming the file."""
    path = env_config_path(name_or_path)
    try:
        tasks = tomllib.loads(path.read_text()).get("tasks", [])
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return ()  # EnvConfig.load names what is wrong with the file
    if not isinstance(tasks, list) or not all(isinstance(t, str) and t in TASKS for t in tasks):
        raise ValueError(f"{path}: tasks must be a list of task names ({', '.join(TASKS)}), got {tasks!r}"[:300])
    return tuple(tasks)


# How a configuration's change of each field is written (config_changes): a label and a unit.
_CHANGE_LABELS = {"max_steps": ("steps", ""), "forward_step": ("forward step", " m"),
                  "turn_angle_deg": ("turns", " deg"), "tilt_angle_deg": ("tilts", " deg"),
                  "hfov_deg": ("hfov", " deg"),
                  "agent_height": ("camera and body height", " m"), "agent_radius": ("radius", " m"),
                  "max_climb": ("climb", " m"), "allow_sliding": ("sliding", ""), "gps_compass": ("GPS+compass", ""),
                  "camera_pitch_deg": ("camera pitch", " deg")}


def config_changes(config: EnvConfig, base: EnvConfig, task: str, success_distance: float) -> list[str]:
    """What ``config`` changes from a task's own conditions ``base`` (whose success distance is
    ``success_distance``), in words: ``["actions +LOOK_UP, LOOK_DOWN", "success 0.25 -> 0.1 m", ...]``."""
    def num(v: Any) -> str:
        return f"{v:g}" if isinstance(v, float) else str(v)

    out: list[str] = []
    t = TASKS[task]
    a, b = t.env_actions(base), t.env_actions(config)
    looks, looked = any(x.startswith("LOOK_") for x in b), any(x.startswith("LOOK_") for x in a)
    if a != b:
        out.append("actions " + ", ".join([*(f"+{x}" for x in b if x not in a), *(f"-{x}" for x in a if x not in b)])
                   + (f" (tilts of {num(config.tilt_angle_deg)} deg)" if looks and not looked else ""))
    sd = config.success_distance if config.success_distance is not None else success_distance
    if sd != success_distance:
        out.append(f"success {num(success_distance)} -> {num(sd)} m")
    if (base.width, base.height) != (config.width, config.height):
        out.append(f"camera {base.width}x{base.height} -> {config.width}x{config.height}")
    if (base.min_depth, base.max_depth, base.normalize_depth) != (config.min_depth, config.max_depth,
                                                                  config.normalize_depth):
        out.append(f"depth {num(base.min_depth)}-{num(base.max_depth)} m -> {num(config.min_depth)}-"
                   f"{num(config.max_depth)} m" + ("" if config.normalize_depth else ", not normalised"))
    said = {"actions", "success_distance", "width", "height", "min_depth", "max_depth", "normalize_depth", "rgb",
            "depth", "semantic", "gl_platform"}
    for f in dataclasses.fields(config):
        old, new = getattr(base, f.name), getattr(config, f.name)
        if f.name in said or old == new or (f.name == "tilt_angle_deg" and not (looks and looked)):
            continue
        label, unit = _CHANGE_LABELS.get(f.name, (f.name, ""))
        if isinstance(new, bool):
            out.append(f"{label} {'on' if new else 'off'}")
        else:
            out.append(f"{label} {num(old) if old is not None else 'none'} -> {num(new)}{unit}")
    return out


def env_config_names() -> list[str]:
    """The named configurations ``EnvConfig.load`` and ``navbench run --env-config`` take."""
    return sorted(p.stem for p in (CONFIGS_DIR / "env").glob("*.toml"))


def env_config_path(name_or_path: str | Path) -> Path:
    """The file of a named configuration, or the path given when it is a file (ValueError, naming the
    known names, when it is neither)."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    named = CONFIGS_DIR / "env" / f"{name_or_path}.toml"
    if "/" not in str(name_or_path) and named.is_file():
        return named
    raise ValueError(f"env config {str(name_or_path)!r}: no such file, nor a named configuration "
                     f"({', '.join(env_config_names())})")


def env_config_name(name_or_path: str | Path) -> str:
    """How a run records and labels a configuration: its name, or a file's name without ``.toml``."""
    p = Path(name_or_path)
    return p.name[:-5] if p.is_file() and p.name.endswith(".toml") else p.name
