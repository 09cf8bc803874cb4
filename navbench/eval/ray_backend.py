"""The evaluation runner on a Ray cluster: ``navbench run ... --backend ray``.

    ray start --head --port 6379                   # on one machine
    ray start --address HEAD:6379                  # on each of the others
    navbench run --split val_unseen --backend ray --address HEAD:6379

Without ``--address`` a local Ray instance with ``--workers`` CPUs is started for the run. The driver
(the machine running ``navbench run``) keeps the run directory: it hands tasks (lists of episode keys, in
scene order) to one actor per CPU of the cluster; each actor sends every record through a Ray queue as
its episode ends and the driver appends it to ``episodes.jsonl``, so ``--resume`` works as with the local
backend, either way round: the records are the same.

No shared file system is needed: the driver puts the episode file, the files of the scenes the run
needs (the mesh and its same-name side files, and the nearest ``*.scene_dataset_config.json``) and the
files the agent's spec names (the PointNav checkpoint of the policy agents; the keyframe memories the
memory agent built before the run) into Ray's object store once. Each actor copies what its tasks need into
``$NAVBENCH_CACHE/ray/DIGEST`` on its machine (DIGEST names the files' contents, so the copy is shared by
the actors of a machine and reused by later runs) and runs there. Shipping the driver's memories means no
two actors ever build one, and the records equal a local run's, whose memory statistics they quote.
Every machine needs the same navbench (checked) and the agent's code; model directories
(``--siglip2``...) and absolute ``scene_id`` paths must exist on every machine.

An actor that dies (killed, out of memory, its machine lost) keeps the records it sent; the other
episodes of its task are retried on a fresh actor up to ``retries`` times and then recorded as failed
("ray worker died (ActorDiedError)"). An agent call slower than ``step_timeout`` fails its episode when
it returns; a call that never returns is not killed on this backend. When the run ends (also early) the
driver has each actor close its worker, hence the agent (a remote agent ends its session), then stops it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import os
import pickle
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench._version import __version__
from navbench.episodes.types import EpisodeError
from navbench.eval.config import RunConfig
from navbench.eval.rundir import RunError
from navbench.eval.worker import (
    AgentFactory,
    Clock,
    EpisodeWorker,
    Key,
    Msg,
    RetryLedger,
    Tracker,
    base_record,
    failed_record,
    failure_reason,
    run_dataset,
    start_distance,
    task_size,
)
from navbench.scene.asset import SceneError

File = tuple[str, str, Any]  # (path under the actor's copy, sha1 of the bytes, ObjectRef of the bytes)

EXTRA = "pip install navbench[ray]"
_POLL_S = 0.2  # how often the driver takes the records that actors sent while their tasks run
_CLOSE_S = 5.0  # how long the driver waits for its actors to close their agents at the end of a run


def require_ray():
    """The ``ray`` module; an ImportError naming the extra when it is not installed."""
    try:
        import ray
    except ImportError:
        raise ImportError(f"--backend ray needs Ray: {EXTRA}") from None
    return ray


# ------------------------------------------------------------------------------------------ shipping
def scene_files(scene_id: str, scene_dir: Path) -> list[tuple[str, Path]]:
    """(path under the copy's ``scenes/``, file) of what loading ``scene_id`` reads: the mesh, the files
    beside it named after it (``X.semantic.json``, HM3D's ``X.semantic.txt``, MP3D's ``X_semantic.ply``
    and ``X.house``) and the nearest scene dataset config. Empty for an absolute ``scene_id``, which
    every machine must then have."""
    from navbench.env.base import resolve_scene_path
    from navbench.scene.datasets import find_config

    if Path(scene_id).is_absolute():
        return []
    mesh = resolve_scene_path(scene_id, scene_dir)
    base = scene_dir.resolve()
    # Keep the mesh where resolve_scene found it relative to scene_dir, so it resolves the same way there.
    rel = Path(os.path.relpath(mesh.resolve(), base)) if mesh.resolve().is_relative_to(base) else Path(scene_id)
    stem = mesh.name.split(".")[0]
    out = [(str(rel.parent / f.name), f) for f in sorted(mesh.parent.iterdir())
           if f.is_file() and (f.name.split(".")[0] == stem or f.name.startswith(stem + "_"))]
    config = find_config(mesh)
    if config is not None and config.resolve().is_relative_to(base):
        out.append((os.path.relpath(config.resolve(), base), config))
    return out


class _Shipper:
    """Puts each file into the object store once; ``digest`` then names the whole set of contents."""

    def __init__(self, ray) -> None:
        self.ray, self.names = ray, set()

    def put(self, rel: str, path: Path) -> File:
        data = Path(path).read_bytes()
        sha = hashlib.sha1(data).hexdigest()
        self.names.add((rel, sha))
        return rel, sha, self.ray.put(data)

    def digest(self) -> str:
        return hashlib.sha1(repr(sorted(self.names)).encode()).hexdigest()[:16]


@dataclasses.dataclass
class Shipment:
    """What an actor needs to run tasks away from the driver's disk."""
    digest: str
    base: list[File]  # the episode file and the agent's run-wide files
    scenes: dict[str, list[File]]  # scene_id -> its scene files and the agent's files of the scene
    episodes: str  # path of the episode file under the copy
    # agent option -> path under the copy it names there (a run-wide file, or the directory of per-scene files)
    options: dict[str, str] = dataclasses.field(default_factory=dict)


def ship(ray, cfg: RunConfig, scene_ids: list[str]) -> Shipment:
    """Put the run's files into the object store: the episode file, the scenes of ``scene_ids`` and what
    the agent's spec says it reads (:class:`~navbench.agents.registry.AgentSpec` ``run_files`` and
    ``scene_files``; a plug-in agent ships nothing)."""
    from navbench.agents.registry import AGENTS
    from navbench.env.base import resolve_scene_path

    spec = AGENTS.get(cfg.agent)
    s = _Shipper(ray)
    episodes = f"episodes/{Path(cfg.episodes).name}"
    base = [s.put(episodes, Path(cfg.episodes))]
    options: dict[str, str] = {}
    for option, src in (spec.run_files(cfg) if spec is not None and spec.run_files else {}).items():
        options[option] = f"{option}/{src.name}"
        base.append(s.put(options[option], src))
    per_scene = spec.scene_files if spec is not None and spec.scene_option else None
    if per_scene is not None:
        options[spec.scene_option] = spec.scene_option
    scene_dir = Path(cfg.scene_dir)
    scenes: dict[str, list[File]] = {}
    for scene_id in dict.fromkeys(scene_ids):
        files = [s.put(f"scenes/{rel}", p) for rel, p in scene_files(scene_id, scene_dir)]
        if per_scene is not None:
            mesh = resolve_scene_path(scene_id, scene_dir)
            files += [s.put(f"{spec.scene_option}/{rel}", p) for rel, p in per_scene(cfg, mesh)]
        scenes[scene_id] = files
    return Shipment(s.digest(), base, scenes, episodes, options)


def worker_config(cfg: RunConfig, root: Path, shipment: Shipment) -> RunConfig:
    """``cfg`` reading the actor's copy under ``root``: the episode file, the scenes and the agent's files."""
    options = {**cfg.agent_options, **{k: str(root / rel) for k, rel in shipment.options.items()}}
    return dataclasses.replace(cfg, episodes=str(root / shipment.episodes), scene_dir=str(root / "scenes"),
                               agent_options=options)


def materialize(ray, root: Path, files: list[File]) -> None:
    """Write the files missing under ``root``; each appears whole (renamed into place) or not at all."""
    for rel, _, ref in files:
        dest = root / rel
        if dest.is_file():
            continue
        data = ray.get(ref)
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp = dest.with_name(f".{dest.name}.{os.getpid()}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, dest)


# ------------------------------------------------------------------------------------------- actors
def warm_scene(cfg: RunConfig) -> str:
    """The scene a new env loads when ``make_env`` resets it with the run's seed: the episode that
    ``NavEnv.reset`` draws without one (gymnasium's seeded generator)."""
    from gymnasium.utils import seeding

    episodes = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard, cfg.task, cfg.gt).episodes
    rng, _ = seeding.np_random(cfg.seed)
    return episodes[int(rng.integers(len(episodes)))].scene_id


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling to the driver, else a RunError with its one line."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return RunError(f"ray worker: {failure_reason(exc)}")


class _QueueTracker(Tracker):
    """Tells the driver, through the run's record queue, which episodes begin (so a dead actor's retries
    are charged only to those)."""

    def __init__(self, queue: Any) -> None:
        self.queue = queue

    def begin(self, slot: int, record: dict[str, Any], d0: float) -> None:
        self.queue.put((Msg.BEGIN, (record["scene_id"], record["episode_id"])))


class NavbenchWorker:
    """A Ray actor: an :class:`~navbench.eval.worker.EpisodeWorker` over the actor's copy of the files.
    Errors come back as values so the driver raises them as the local backend would."""

    def __init__(self, cfg: RunConfig, make_agent: AgentFactory, shipment: Shipment,
                 step_timeout: float | None) -> None:
        import ray

        from navbench.paths import cache_dir

        self.error: BaseException | None = None
        self.shipment, self.clock = shipment, Clock(step_timeout)
        self.root = cache_dir("ray", shipment.digest)
        self.have: set[str] = set()
        self.episodes = ("", "")
        self.worker: EpisodeWorker | None = None
        try:
            materialize(ray, self.root, shipment.base)
            local = worker_config(cfg, self.root, shipment)
            self.episodes = (local.episodes, cfg.episodes)  # (this copy's, the driver's) episode file
            self._fetch([warm_scene(local)])
            try:
                self.worker = EpisodeWorker(local, make_agent, single_thread=True)
            except SceneError:  # the envs warmed up on another scene than expected: fetch them all
                self._fetch(shipment.scenes)
                self.worker = EpisodeWorker(local, make_agent, single_thread=True)
        except Exception as exc:
            self.error = _portable(exc)

    def _fetch(self, scene_ids) -> None:
        import ray
        for scene_id in dict.fromkeys(scene_ids):
            if scene_id not in self.have:
                materialize(ray, self.root, self.shipment.scenes.get(scene_id, []))
                self.have.add(scene_id)

    def ready(self) -> tuple[str, int, BaseException | None]:
        return __version__, os.getpid(), self.error

    def run(self, keys: list[Key], queue: Any) -> tuple[list[dict[str, Any]], BaseException | None]:
        """Run ``keys``, putting where each episode begins and its record into the driver's ``queue`` as it
        ends (so an actor that dies mid-task loses only its episodes in flight); returns the records too."""
        records: list[dict[str, Any]] = []

        def finish(rec: dict[str, Any]) -> None:
            queue.put((Msg.RECORD, rec))
            records.append(rec)
        try:
            self._fetch(k[0] for k in keys)
            assert self.worker is not None, "run() on an actor that did not start"
            self.worker.run(keys, finish, self.clock, _QueueTracker(queue))
        except (EpisodeError, SceneError) as exc:  # bad input ends the run; name the user's file, not the copy
            return records, type(exc)(str(exc).replace(*self.episodes))
        except Exception as exc:  # a bug: ends the run
            return records, _portable(exc)
        return records, None

    def close(self) -> None:
        """Close the worker: its envs, then the agent's ``close()`` (a remote agent ends its session on the
        server), as a local pool worker does when it stops. Only the first call closes anything."""
        worker, self.worker = self.worker, None
        if worker is not None:
            worker.close()


# ------------------------------------------------------------------------------------------- driver
def _death_errors(ray) -> tuple[type[BaseException], ...]:
    ex = ray.exceptions
    return tuple(getattr(ex, n) for n in ("RayActorError", "WorkerCrashedError", "NodeDiedError",
                                          "LocalRayletDiedError", "OwnerDiedError") if hasattr(ex, n))


def connect(ray, address: str | None, workers: int) -> None:
    """Join the cluster at ``address``, or start a local instance with ``workers`` CPUs."""
    try:
        if address is None and not os.environ.get("RAY_ADDRESS"):
            # "local": a new instance for this run, never a cluster that happens to run on this machine
            ray.init(address="local", num_cpus=workers, include_dashboard=False, logging_level=logging.WARNING)
        else:
            host = (address or "").rpartition(":")[0]
            local: dict[str, Any] = {}
            if host in ("127.0.0.1", "localhost"):  # a cluster started with --node-ip-address=127.0.0.1
                # Ray swaps a loopback address for the machine's own, where such a cluster does not listen,
                # unless it takes the machine for a single-node one.
                from ray._private import ray_constants
                ray_constants.ENABLE_RAY_CLUSTER = False
                local = {"_node_ip_address": "127.0.0.1"}
            ray.init(address=address, logging_level=logging.WARNING, **local)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise RunError(f"--address {address}: cannot join the Ray cluster ({first})") from None


def _kill(ray, handle) -> None:
    try:
        ray.kill(handle)
    except Exception:  # already gone, or the cluster with it: nothing left to stop
        pass


class _Slot:
    def __init__(self, handle, ready_ref) -> None:
        self.handle, self.ready_ref = handle, ready_ref
        self.ready = False
        self.task: list[Key] | None = None
        self.task_started = 0.0


def run_ray(cfg: RunConfig, make_agent: AgentFactory, keys: list[Key],
            finish: Callable[[dict[str, Any]], None], address: str | None = None, retries: int = 2,
            step_timeout: float | None = None, workers: int = 1) -> None:
    """Run the episodes ``keys`` on Ray actors, handing every record (run or failed) to ``finish`` as its
    episode ends; the contract of :func:`navbench.eval.pool.run_pool`, with tasks sized
    (:func:`~navbench.eval.worker.task_size`) for the cluster's CPUs and ``cfg.envs_per_worker`` slots.
    Without ``address`` a local Ray instance with ``workers`` CPUs is started for the run."""
    ray = require_ray()
    if not keys:
        return
    started = not ray.is_initialized()
    if started:
        connect(ray, address, workers)
    from ray.util.queue import Empty
    from ray.util.queue import Queue as RayQueue

    dying = _death_errors(ray)
    selected = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard, cfg.task, cfg.gt).episodes
    by_key = {(e.scene_id, e.episode_id): e for e in selected}
    slots: list[_Slot] = []
    try:
        shipment = ship(ray, cfg, [warm_scene(cfg)] + [k[0] for k in keys])
        Actor = ray.remote(num_cpus=1, max_restarts=0)(NavbenchWorker)
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        size = task_size(len(keys), cpus, cfg.envs_per_worker)
        tasks = [keys[i:i + size] for i in range(0, len(keys), size)]
        n_actors = min(cpus, len(tasks))
        queue: deque[list[Key]] = deque(tasks)
        # (Msg.BEGIN, key) as an episode begins, (Msg.RECORD, record) as it ends, from any actor
        records = RayQueue(actor_options={"num_cpus": 0})
        finished: set[Key] = set()
        began: set[Key] = set()  # began and not finished (an actor's retry of an episode begins it again)

        def take(rec: dict[str, Any]) -> None:
            key = (rec["scene_id"], rec["episode_id"])
            began.discard(key)
            if key not in finished:  # an episode a dead actor sent and its retry ran again counts once
                finished.add(key)
                finish(rec)

        def drain() -> None:
            while True:
                try:
                    kind, value = records.get_nowait()
                except Empty:
                    return
                if kind is Msg.BEGIN:
                    began.add(value)
                else:
                    take(value)

        ledger = RetryLedger(retries, cfg.episodes)
        pending: dict[Any, _Slot] = {}  # ObjectRef of a ready() or run() call -> its actor

        def spawn() -> _Slot:
            handle = Actor.remote(cfg, make_agent, shipment, step_timeout)
            slot = _Slot(handle, handle.ready.remote())
            pending[slot.ready_ref] = slot
            return slot

        def lost(slot: _Slot, exc: BaseException) -> None:
            """``slot``'s actor is gone: retry or fail the episodes of its task, requeue the retried."""
            reason = f"ray worker died ({type(exc).__name__})"
            _kill(ray, slot.handle)
            if not slot.ready:
                ledger.startup_death(reason, "a Ray worker")
            drain()  # records the actor sent before it died are kept
            task = slot.task or []
            rest, failed = ledger.settle(task, finished, began & set(task))
            began.difference_update(task)  # a retried episode is charged again only if it begins again
            for key in failed:
                ep = by_key[key]
                finished.add(key)
                began.discard(key)
                finish(failed_record(base_record(ep, cfg), reason, start_distance(ep), None, 0,
                                     time.monotonic() - slot.task_started))
            if rest:
                queue.appendleft(rest)
            if queue:
                slots[slots.index(slot)] = spawn()
            else:
                slots.remove(slot)

        slots.extend(spawn() for _ in range(n_actors))
        while queue or any(s.task is not None for s in slots):
            for s in slots:
                if s.ready and s.task is None and queue:
                    s.task, s.task_started = queue.popleft(), time.monotonic()
                    pending[s.handle.run.remote(s.task, records)] = s
            done: list = []
            while not done:
                done, _ = ray.wait(list(pending), num_returns=1, timeout=_POLL_S)
                drain()
            slot = pending.pop(done[0])
            if slot not in slots:  # a replaced actor's late answer
                continue
            try:
                value = ray.get(done[0])
            except dying as exc:
                lost(slot, exc)
                continue
            if done[0] == slot.ready_ref:
                version, _, error = value
                if error is not None:
                    raise error
                if version != __version__:
                    raise RunError(f"a Ray worker has navbench {version}, this machine {__version__}: install "
                                   f"the same version on every machine")
                slot.ready = True
                continue
            sent, error = value
            for rec in sent:  # normally all drained already; the queue's last puts may still be in transit
                take(rec)
            slot.task = None
            if error is not None:
                raise error
    finally:
        _close_actors(ray, [s.handle for s in slots])
        if started:
            ray.shutdown()


def _close_actors(ray, handles: list, wait_s: float = _CLOSE_S) -> None:
    """Close each actor's worker (so its agent's ``close()`` runs), then kill the actors. An actor still
    running a task (the run ended early) closes once the task returns; one that does not within
    ``wait_s`` seconds (for all of them) is killed without, as a busy local pool worker is."""
    refs = []
    for handle in handles:
        try:
            refs.append(handle.close.remote())
        except Exception:  # the actor or the cluster is gone: nothing to close
            pass
    if refs:
        try:
            ray.wait(refs, num_returns=len(refs), timeout=wait_s)
        except Exception:  # the cluster went away meanwhile
            pass
    for handle in handles:
        _kill(ray, handle)
