"""``navbench run --backend ray``: the same records as the local backend on a two-node cluster with no
shared cache, an actor killed mid-run costs nothing, an episode whose actor always dies is a failed
record, and the flag errors are one line with exit 2.

    pytest tests/eval/test_ray_backend.py    # all of it, the two-node cluster included (~2.5 min)

The cluster is two raylets on loopback (``ray.cluster_utils.Cluster``, as Ray's own tests start one),
each with its own NAVBENCH_CACHE, as two machines would have: the actors get the files and the memories
the driver built only through Ray's object store.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from navbench.cli import main
from navbench.eval.runner import comparable, read_records

ROOT = Path(__file__).resolve().parents[2]
SELECT = ["--split", "val_unseen", "--agent", "memory", "--per-scene", "5"]  # all four val_unseen houses


def _records(path: Path) -> list[dict]:
    return comparable(read_records(path))


def _env() -> dict[str, str]:
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return {**os.environ, "PYTHONPATH": path}


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(address, the second node's NAVBENCH_CACHE) of a 2-node, 1-CPU-each Ray cluster on 127.0.0.1."""
    pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    caches = [tmp_path_factory.mktemp("node0-cache"), tmp_path_factory.mktemp("node1-cache")]
    saved = dict(os.environ)
    c = None
    try:  # a node's processes (and so its actors) inherit the environment it is started with
        os.environ.update(_env(), NAVBENCH_CACHE=str(caches[0]), PYOPENGL_PLATFORM="osmesa")
        c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "node_ip_address": "127.0.0.1",
                                                          "include_dashboard": False})
        os.environ["NAVBENCH_CACHE"] = str(caches[1])
        c.add_node(num_cpus=1, node_ip_address="127.0.0.1")
        c.wait_for_nodes()
        os.environ.clear()
        os.environ.update(saved)
        yield c.address, caches[1]
    finally:
        os.environ.clear()
        os.environ.update(saved)
        if c is not None:
            c.shutdown()


@pytest.fixture(scope="module")
def local_records(tmp_path_factory) -> list[dict]:
    """The local backend's records of 20 memory-agent episodes over the four val_unseen houses."""
    pytest.importorskip("ray")
    out = tmp_path_factory.mktemp("local") / "run"
    assert main(["run", *SELECT, "--limit", "20", "--workers", "2", "--out", str(out), "-q"]) == 0
    return _records(out / "episodes.jsonl")


def _ray_run(address: str, out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "navbench.cli", "run", *SELECT, *args, "--out", str(out), "-q",
                             "--backend", "ray", "--address", address], env=_env(), cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow  # an end-to-end run (seconds to tens of seconds): make test-slow
def test_ray_records_equal_the_local_backends(cluster, local_records, tmp_path):
    proc = _ray_run(cluster[0], tmp_path / "ray", "--limit", "20")
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr[-2000:]
    assert _records(tmp_path / "ray" / "episodes.jsonl") == local_records
    assert len(local_records) == 20 and len({r["scene_id"] for r in local_records}) == 4


def _actor_pids(cache: Path) -> list[int]:
    """PIDs of the run's actors on the node whose NAVBENCH_CACHE is ``cache`` (read from /proc)."""
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if b"NavbenchWorker" in (proc / "cmdline").read_bytes() and \
                    f"NAVBENCH_CACHE={cache}".encode() in (proc / "environ").read_bytes().split(b"\0"):
                pids.append(int(proc.name))
        except (OSError, ValueError):
            continue
    return pids


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/environ").is_file(), reason="finds the actor's process in /proc")
def test_killed_actor_loses_nothing_and_a_local_run_resumes_on_ray(cluster, local_records, tmp_path):
    out = tmp_path / "run"
    assert main(["run", *SELECT, "--limit", "3", "--workers", "1", "--out", str(out), "-q"]) == 0  # local start
    proc = _ray_run(cluster[0], out, "--limit", "8", "--resume")
    killed = None
    try:
        deadline = time.monotonic() + 300
        while killed is None and proc.poll() is None and time.monotonic() < deadline:
            lines = (out / "episodes.jsonl").read_text().count("\n")
            pids = _actor_pids(cluster[1]) if lines >= 5 else []
            if pids:
                killed = pids[0]
                os.kill(killed, signal.SIGKILL)
            time.sleep(0.2)
        stdout, stderr = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert killed is not None, "no actor of the run found on the second node while it ran"
    assert proc.returncode == 0, stderr[-2000:]
    records = _records(out / "episodes.jsonl")
    keys = [(r["scene_id"], r["episode_id"]) for r in records]
    assert len(keys) == 8 == len(set(keys))
    assert not [r for r in records if r.get("failed")]
    assert records == local_records[:8]  # file order is scene order here: the same first 8 episodes


def test_address_needs_the_ray_backend(tmp_path, capsys):
    assert main(["run", "--agent", "oracle", "--limit", "1", "--address", "auto", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--address" in err and "--backend ray" in err


def test_ray_backend_without_ray_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert main(["run", "--agent", "oracle", "--limit", "1", "--backend", "ray", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install navbench[ray]" in err
    assert not (tmp_path / "r").exists()


def test_scene_files_are_the_mesh_its_side_files_and_the_dataset_config(tmp_path):
    from navbench.eval.ray_backend import scene_files

    for name in ("hm3d.scene_dataset_config.json", "val/00800-TEE/TEE.basis.glb", "val/00800-TEE/TEE.semantic.glb",
                 "val/00800-TEE/TEE.semantic.txt", "val/00800-TEE/TEE_semantic.ply", "val/00800-TEE/OTHER.glb"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"x")
    got = {rel for rel, _ in scene_files("hm3d/val/00800-TEE/TEE.basis.glb", tmp_path)}
    assert got == {"hm3d.scene_dataset_config.json", "val/00800-TEE/TEE.basis.glb", "val/00800-TEE/TEE.semantic.glb",
                   "val/00800-TEE/TEE.semantic.txt", "val/00800-TEE/TEE_semantic.ply"}
    from navbench.paths import SCENES_DIR
    assert {rel for rel, _ in scene_files("houses/val/house_008.glb", SCENES_DIR)} == {
        "houses/val/house_008.glb", "houses/val/house_008.semantic.json"}


def test_warm_scene_is_the_scene_a_new_env_loads():
    from navbench.episodes.io import load_dataset
    from navbench.eval.config import RunConfig
    from navbench.eval.ray_backend import warm_scene
    from navbench.eval.worker import make_env
    from navbench.paths import SCENES_DIR, split_file

    for seed in (0, 3):
        cfg = RunConfig(task="objectnav", split="val_unseen", agent="oracle", scene_dir=str(SCENES_DIR),
                        episodes=str(split_file("objectnav", "val_unseen")), success_distance=1.0, seed=seed)
        env = make_env(cfg, load_dataset(cfg.episodes), ())
        assert env.episode.scene_id == warm_scene(cfg)
        env.close()


CRASHING_AGENT = '''
import os
from navbench.agents.oracle import OracleAgent

class Crashing(OracleAgent):
    """The oracle, but its process dies on the episode named in agent_options["die_on"]."""
    def __init__(self, cfg):
        super().__init__(cfg.scene_dir, cfg.success_distance)
        self.die_on = cfg.agent_options["die_on"]

    def reset(self, episode):
        if episode.episode_id == self.die_on:
            os._exit(1)
        super().reset(episode)

def make(cfg):
    return Crashing(cfg)
'''


@pytest.mark.slow  # three dead actors in a row, each a fresh Ray worker (~20-50 s): make test-slow
def test_an_episode_whose_actor_always_dies_is_recorded_as_failed(tmp_path, monkeypatch, pointnav_file):
    """On a local Ray instance: retried ``retries`` times on fresh actors, then a failed record; the rest run."""
    pytest.importorskip("ray")
    from navbench.episodes.io import load_dataset
    from navbench.eval.runner import Execution, RunConfig, run
    from navbench.paths import SCENES_DIR

    (tmp_path / "crashing_agent.py").write_text(CRASHING_AGENT)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")]))
    import crashing_agent

    ids = [e.episode_id for e in load_dataset(pointnav_file).episodes]
    cfg = RunConfig(task="pointnav", split=None, agent="crashing_agent:make", episodes=str(pointnav_file),
                    scene_dir=str(SCENES_DIR), success_distance=0.2, agent_options={"die_on": ids[1]})
    summary = run(cfg, crashing_agent.make, tmp_path / "run", execution=Execution(workers=1, backend="ray", retries=1))
    lines = (tmp_path / "run" / "episodes.jsonl").read_text().splitlines()
    records = {r["episode_id"]: r for r in map(json.loads, lines)}
    assert sorted(records) == sorted(ids)
    assert records[ids[1]]["failed"] and records[ids[1]]["failure_reason"].startswith("ray worker died (")
    assert summary["num_failed"] == 1 and not any(r.get("failed") for k, r in records.items() if k != ids[1])


def test_a_bad_episode_ends_a_ray_run_naming_the_users_file(tmp_path, pointnav_file, capsys):
    """The PointNav policy agent (its checkpoint shipped to the actor) steps 8 episodes at once: the bad
    third one ends the run with exit 2 naming the driver's episode file; the two in flight are kept."""
    pytest.importorskip("ray")
    from navbench.episodes.io import load_dataset, save_dataset

    ds = load_dataset(pointnav_file)
    ds.episodes[2].start_position = [400.0, 0.0, 400.0]
    path = save_dataset(ds, tmp_path / "eps.json.gz")
    out = tmp_path / "o"
    assert main(["run", "--episodes", str(path), "--out", str(out), "--backend", "ray", "--workers", "1", "-q"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("navbench:")]
    assert len(err) == 1 and str(path) in err[0] and "not navigable" in err[0]
    assert len(read_records(out / "episodes.jsonl")) == 2


CLOSING_AGENT = '''
import os

class Closing:
    """Stops at once; its close() appends its process id to the file ``marker``."""
    def __init__(self, marker):
        self.marker = marker

    def reset(self, episode):
        pass

    def act(self, observations):
        return 0

    def close(self):
        with open(self.marker, "a") as f:
            f.write(f"{os.getpid()}\\n")
'''


@pytest.mark.parametrize("bad", [False, True], ids=["run-ends", "bad-episode-ends-it-early"])
def test_a_ray_actor_closes_its_agent_once_when_the_run_ends(tmp_path, monkeypatch, pointnav_file, bad):
    """As the local pool does: a plug-in agent's close() runs in the actor (a remote agent's POST /close),
    also when a bad second episode ends the run (exit 2)."""
    pytest.importorskip("ray")
    from navbench.episodes.io import load_dataset, save_dataset

    ds = load_dataset(pointnav_file)
    if bad:
        ds.episodes[1].start_position = [400.0, 0.0, 400.0]
    episodes = save_dataset(ds, tmp_path / "eps.json.gz")
    (tmp_path / "closing_agent.py").write_text(CLOSING_AGENT)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")]))
    marker = tmp_path / "closed"
    assert main(["run", "--episodes", str(episodes), "--agent", "closing_agent:Closing", "--agent-opt",
                 f"marker={marker}", "--limit", "2", "--backend", "ray", "--workers", "1",
                 "--out", str(tmp_path / "run"), "-q"]) == (2 if bad else 0)
    assert bad or len(read_records(tmp_path / "run" / "episodes.jsonl")) == 2
    pids = marker.read_text().split()
    assert len(pids) == 1 and int(pids[0]) != os.getpid()  # closed once, in the actor
