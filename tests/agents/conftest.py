"""A user's agent module as a test writes it outside the package, and an installed plug-in's dist-info."""

import os
import sys
import textwrap
from pathlib import Path

import pytest

# A depth-reading agent: heads for the point goal, turns away from near walls, stops near the goal or
# after `stop_after` steps (short episodes keep the tests fast). It refuses observations it did not ask for.
AGENT_MODULE = textwrap.dedent('''
    import time
    import zlib

    import numpy as np

    STOP, FORWARD, LEFT, RIGHT = 0, 1, 2, 3


    class WalkAgent:
        sensors = ("depth",)

        def __init__(self, stop_after=25, turn=0.3, wall=0.03):
            self.stop_after, self.turn, self.wall = stop_after, turn, wall

        def reset(self, episode):
            self.steps, self.crc = 0, 0

        def episode_log(self):
            """A checksum of every observation byte the agent saw: records match only if those did."""
            return {"observations_crc32": self.crc}

        def act(self, observations):
            if "rgb" in observations or "depth" not in observations:
                raise AssertionError(f"observations {sorted(observations)} do not follow sensors={self.sensors}")
            self.steps += 1
            for k in sorted(observations):
                a = np.ascontiguousarray(observations[k])
                self.crc = zlib.crc32(f"{k}{a.dtype.str}{a.shape}".encode() + a.tobytes(), self.crc)
            rho, phi = (float(x) for x in observations["pointgoal_with_gps_compass"])
            if rho < 0.2 or self.steps >= self.stop_after:
                return STOP
            if abs(phi) > self.turn:
                return LEFT if phi > 0 else RIGHT
            d = observations["depth"]
            h, w = d.shape[:2]
            return LEFT if float(d[h // 3:2 * h // 3, w // 3:2 * w // 3].min()) < self.wall else FORWARD


    def make_walker(run_config, stop_after=25):
        """A factory: gets the run config, then its options."""
        assert run_config.task == "pointnav"
        return WalkAgent(stop_after=stop_after)


    class BatchWalkAgent:
        """The same agent stepping num_envs episodes at once; remembers the largest batch it was given."""
        sensors = ("depth",)

        def __init__(self, num_envs=3, stop_after=25):
            self.num_envs = num_envs
            self.slots = [WalkAgent(stop_after=stop_after) for _ in range(num_envs)]
            self.largest_batch = 0

        def reset_env(self, i, episode):
            self.slots[i].reset(episode)

        def act_batch(self, observations):
            self.largest_batch = max(self.largest_batch, len(observations))
            return [None if o is None else a.act(o) for a, o in zip(self.slots, observations)]


    class SlowAgent(WalkAgent):
        def act(self, observations):
            time.sleep(5)
            return STOP


    class RaisingAgent(WalkAgent):
        def act(self, observations):
            raise ZeroDivisionError("the agent's own bug")
''')


def write_agent_module(root: Path, name: str = "walkmod") -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / f"{name}.py").write_text(AGENT_MODULE)
    return root


def write_installed_plugin(root: Path) -> Path:
    """What ``pip install their-agent`` leaves in site-packages: the module and a dist-info whose
    entry_points.txt registers ``walker`` in the ``navbench.agents`` group."""
    write_agent_module(root, "their_agent")
    info = root / "their_agent-1.2.dist-info"
    info.mkdir(parents=True, exist_ok=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: their-agent\nVersion: 1.2\n")
    (info / "entry_points.txt").write_text("[navbench.agents]\nwalker = their_agent:WalkAgent\n"
                                           "walker-factory = their_agent:make_walker\n")
    return root


@pytest.fixture
def agent_module_source() -> str:
    return AGENT_MODULE


@pytest.fixture
def agent_dir(tmp_path, monkeypatch) -> Path:
    """A folder outside the package holding ``walkmod.py``, on sys.path (spawned workers inherit it)."""
    root = write_agent_module(tmp_path / "user")
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    yield root
    for name in ("walkmod", "their_agent"):
        sys.modules.pop(name, None)


@pytest.fixture
def plugin_site(tmp_path, monkeypatch) -> Path:
    """An installed ``their-agent`` distribution (module plus dist-info) on sys.path."""
    root = write_installed_plugin(tmp_path / "site")
    monkeypatch.syspath_prepend(str(root))
    yield root
    sys.modules.pop("their_agent", None)


@pytest.fixture(scope="session")
def pointnav10_file(tmp_path_factory, scene_path) -> Path:
    """Ten short PointNav episodes (1-6 m) in the smoke scene."""
    import numpy as np

    from navbench.episodes.generate import GeneratorConfig, pointnav_episodes
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import EpisodeDataset
    from navbench.paths import SCENES_DIR

    eps = pointnav_episodes(scene_path, SCENES_DIR, 10, np.random.default_rng(11),
                            GeneratorConfig(min_geodesic=1.0, max_geodesic=6.0))
    return save_dataset(EpisodeDataset(episodes=eps), tmp_path_factory.mktemp("pn10") / "ten.json.gz")
