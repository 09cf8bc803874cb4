"""What produced a run: its protocol (what makes two runs' numbers comparable) and its provenance.

``OUT/provenance.json`` holds

- ``protocol``: the task, success distance, step limit, action set and step sizes, how goal images are
  rendered (a task's ``goal_images``: ImageNav, InstanceImageNav, GOAT-Bench), sensor size, HFOV and
  depth range, the agent's body (height, radius, climb), the start snapping, the navigability grid's
  cell size and the version of its rules (``navigability``: the grid's for an episode file whose scenes
  each stand the agent on one storey, the storeys' and their joined surfaces' when some scene's starts and
  goals lie on more than one: :func:`spans_storeys`), and the realistic conditions that are on
  (actuation, depth and RGB noise, camera pitch, ``gps_compass: false``; docs/realistic.md): every rule
  that changes a score given the same agent. ``protocol_id`` is the first 12 hex
  digits of the sha256 of its canonical JSON. The policy's decoding is the agent's choice, not the
  protocol's: it is recorded in config.json's ``agent_options`` and shown by ``navbench table``.
- ``navbench``: version, and the git commit with a dirty flag when run from a checkout;
  ``versions`` of Python, torch (its build as torch reports it: ``2.13.0+cpu``), numpy, gymnasium, pyrender
  and trimesh; ``datasets``: the dataset releases the files can be told to come from
  (:func:`dataset_versions`: ``objectnav/hm3d/v2`` episodes, ``hm3d/v0.2`` scenes); ``opengl_renderer``; ``cpu``
  (model and flags); ``run_on``: the torch device, the real models' precision and the GL platform (none of
  them part of the protocol: docs/comparing.md); it is rewritten when a run is resumed (the records may then
  come from two machines);
- ``files``: the sha256 of the episode file (and ``split_files``, of each other file its split is read from:
  habitat-lab's ``content/`` files, VLN-CE's gt file; ``split_sha256``, one checksum of them all that identifies
  the split: :func:`split_entry`), of every scene file the run's episodes use (and of the files
  beside it sharing its stem: its annotations) and of the policy checkpoint, each path relative to the
  directory of the generated benchmark holding it (``"root": "benchmark"``: a directory with ``benchmark.json``;
  ``files.benchmark`` then holds the sha256 of its ``SHA256SUMS``), else to navbench's data root when it lies
  under it (``"root": "navbench"``), else as given; the episode file's ``split_version`` when it states one
  (navbench's generated splits do).

A run directory without provenance.json (written before it existed) gets its protocol derived from
config.json and the EnvConfig defaults of the navbench reading it, without ``navigability`` (config.json
does not say which rules it ran under, so it is never taken for a run under today's); ``derived: true``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import platform
import re
import subprocess
import sys
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

from navbench._version import __version__
from navbench.env.config import ACTION_NAMES, CONDITIONS, SUCCESS_DISTANCE, EnvConfig
from navbench.paths import ROOT
from navbench.safeio import open_input, printable, read_input
from navbench.scene import MULTI_STOREY_NAVIGABILITY_VERSION, NAVIGABILITY_VERSION
from navbench.tasks import TASKS

PROVENANCE = "provenance.json"
RUN_FILE_CAP = 16 << 20  # the most a run directory's config.json or provenance.json is read of
PACKAGES = ("torch", "numpy", "gymnasium", "pyrender", "trimesh")
# EnvConfig fields that do not change a score: which images are rendered (each agent's own) and the GL platform.
_NOT_PROTOCOL = ("rgb", "depth", "semantic", "gl_platform")
# EnvConfig fields a protocol lists only when set: the action list (its names are the protocol's `actions`)
# and the tilt of LOOK_UP / LOOK_DOWN (only when an action looks).
_WHEN_SET = {"actions": None, "tilt_angle_deg": EnvConfig().tilt_angle_deg}


class ProtocolError(ValueError):
    """Runs under different protocols, or a protocol that cannot be read; the message says which."""


def protocol(task: str, success_distance: float | None, env: dict[str, Any] | None = None,
             multi_storey: bool = False) -> dict[str, Any]:
    """The protocol of a run of ``task`` with ``success_distance`` and these EnvConfig overrides, on an episode
    file whose scenes have one storey each (the grid's rules, ``NAVIGABILITY_VERSION``) or, ``multi_storey``,
    not (the storeys' rules, ``MULTI_STOREY_NAVIGABILITY_VERSION``)."""
    if not isinstance(env or {}, dict):
        raise ProtocolError(f"'env' must be an object, got {env!r}"[:200])
    try:
        cfg = EnvConfig(**(env or {}))
    except TypeError as exc:
        raise ProtocolError(f"'env' is not EnvConfig's ({exc})") from None
    fields = {k: v for k, v in dataclasses.asdict(cfg).items() if k not in _NOT_PROTOCOL}
    # realistic conditions (noise, camera pitch, no GPS+compass) only when on: a noiseless run's protocol is
    # what it was before they existed, and a noisy one never matches it
    fields = {k: v for k, v in fields.items() if k not in CONDITIONS or v != CONDITIONS[k]}
    fields = {k: v for k, v in fields.items() if k not in _WHEN_SET or (v != _WHEN_SET[k] and k != "actions")}
    fields["success_distance"] = success_distance if success_distance is not None else SUCCESS_DISTANCE.get(task)
    fields["navigability"] = MULTI_STOREY_NAVIGABILITY_VERSION if multi_storey else NAVIGABILITY_VERSION
    known = TASKS.get(task)
    actions = cfg.actions or (known.actions if known is not None else ACTION_NAMES)
    if not any(a.startswith("LOOK_") for a in actions):
        fields.pop("tilt_angle_deg", None)  # nothing tilts the camera: its angle changes no score
    if known is not None and known.goal_images:
        fields["goal_images"] = known.goal_images  # what the agent is shown of its goal
    return {"task": task, "actions": list(actions), **dict(sorted(fields.items()))}


def _storey_rise(env: dict[str, Any] | None) -> float:
    return float((env or {}).get("agent_height", EnvConfig.agent_height))


@lru_cache(maxsize=16)
def _spans_storeys(path: str, mtime_ns: int, size: int, rise: float) -> bool:
    from navbench.episodes.io import load_dataset
    from navbench.episodes.types import NavigationGoal, ObjectGoal

    heights: dict[str, list[float]] = {}
    for e in load_dataset(path).episodes:
        ys = heights.setdefault(e.scene_id, [])
        ys.append(float(e.start_position[1]))
        for g in e.goals:  # navigable points only: an object's own height says nothing about the storey
            if isinstance(g, ObjectGoal):
                ys.extend(float(y) for y in g.view_point_positions()[:, 1])
            elif isinstance(g, NavigationGoal):
                ys.append(float(g.position[1]))
    return any(max(ys) - min(ys) > rise for ys in heights.values() if ys)


def spans_storeys(episodes: str | Path, rise: float = EnvConfig.agent_height) -> bool:
    """Whether the episode file stands the agent on more than one storey of a scene: in some scene, two of
    its starts and goal positions (PointNav's, ObjectNav's view points) are more than ``rise`` (the agent's
    height) apart in height. False for a file that cannot be read (the run reports it)."""
    try:
        st = Path(episodes).stat()
        return _spans_storeys(str(Path(episodes).resolve()), st.st_mtime_ns, st.st_size, rise)
    except (OSError, ValueError):
        return False


def protocol_id(proto: dict[str, Any]) -> str:
    try:
        text = json.dumps({k: v for k, v in proto.items() if k != "derived"}, sort_keys=True, separators=(",", ":"))
    except (TypeError, ValueError, RecursionError) as exc:
        raise ProtocolError(f"protocol cannot be hashed ({type(exc).__name__})") from None
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def config_protocol(cfg: Any) -> dict[str, Any]:
    """The protocol of a RunConfig."""
    return protocol(cfg.task, cfg.success_distance, cfg.env,
                    spans_storeys(cfg.episodes, _storey_rise(cfg.env)) if getattr(cfg, "episodes", None) else False)


def run_protocol(run_dir: str | Path) -> dict[str, Any]:
    """A run directory's protocol: provenance.json's, else derived from config.json (``derived: true``)."""
    run_dir = Path(run_dir)
    path = run_dir / PROVENANCE
    if path.is_file():
        try:
            doc = json.loads(read_input(path, RUN_FILE_CAP, gunzip=False))
            proto = doc["protocol"]
            if not isinstance(proto, dict) or not isinstance(proto.get("task"), str):
                raise TypeError
        except (OSError, ValueError, KeyError, TypeError, RecursionError):
            raise ProtocolError(f"{path}: corrupt provenance (no readable 'protocol')") from None
        return proto
    path = run_dir / "config.json"
    try:
        cfg = json.loads(read_input(path, RUN_FILE_CAP, gunzip=False))
        if not isinstance(cfg, dict):
            raise TypeError
    except FileNotFoundError:
        raise ProtocolError(f"{path}: no config.json (is this a navbench run directory?)") from None
    except (OSError, ValueError, TypeError, RecursionError):
        raise ProtocolError(f"{path}: corrupt config") from None
    task, sd = cfg.get("task"), cfg.get("success_distance")
    if not isinstance(task, str) or not (sd is None or (isinstance(sd, (int, float)) and not isinstance(sd, bool))):
        raise ProtocolError(f"{path}: corrupt config ('task' must be a string, 'success_distance' a number)")
    try:
        proto = protocol(task, sd, cfg.get("env"))
        del proto["navigability"]
        return {**proto, "derived": True}
    except ProtocolError as exc:
        raise ProtocolError(f"{path}: corrupt config ({exc})") from None


def protocol_differences(a: dict[str, Any], b: dict[str, Any]) -> list[tuple[str, Any, Any]]:
    """``(field, a's value, b's value)`` for each protocol field that differs (``derived`` aside)."""
    keys = sorted((set(a) | set(b)) - {"derived"})
    return [(k, a.get(k), b.get(k)) for k in keys if a.get(k) != b.get(k)]


# What a protocol field's absence means: a rule that is off is left out (``protocol``), a derived one lacks
# ``navigability``.
_ABSENT = {"tilt_angle_deg": "none (no look actions)", "goal_images": "none (no goal images)",
           "navigability": "not recorded (derived from config.json)", "actuation_noise": "none (noiseless)",
           "depth_noise": "none (noiseless)", "rgb_noise": "none (noiseless)"}


def protocol_value(field: str, value: Any) -> str:
    """A protocol field's value as a difference names it; an absent one says what its absence means."""
    if value is not None:
        return repr(value)
    if field in _ABSENT:
        return _ABSENT[field]
    return f"{CONDITIONS[field]!r} (the default)" if field in CONDITIONS else "none"


def protocol_diff(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """``key a vs b`` for each protocol field that differs (``derived`` aside), a's value first."""
    return [f"{k} {protocol_value(k, x)} vs {protocol_value(k, y)}" for k, x, y in protocol_differences(a, b)]


MIX_HINT = "; --mix-protocols to show them together anyway"


def check_same_protocol(run_dirs: list[str | Path], allow_mixed: bool = False, hint: str = MIX_HINT) -> list[str]:
    """Each run's protocol_id; a ProtocolError naming the first difference unless ``allow_mixed``."""
    protos = [run_protocol(d) for d in run_dirs]
    for d, p in zip(run_dirs[1:], protos[1:]):
        diff = protocol_diff(protos[0], p)
        if diff and not allow_mixed:
            raise ProtocolError(printable(f"{run_dirs[0]} vs {d}: scored under different protocols ({'; '.join(diff)})",
                                          1000) + hint)
    return [protocol_id(p) for p in protos]


# ----------------------------------------------------------------------------------------- provenance
def sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


BENCHMARK_MANIFEST = "benchmark.json"  # what marks a directory written by `navbench generate benchmark`


def benchmark_root(path: str | Path) -> Path | None:
    """The generated benchmark directory holding ``path`` (its scene dir, or a file up to two folders down)."""
    for parent in Path(path).resolve().parents[:3]:
        if (parent / BENCHMARK_MANIFEST).is_file():
            return parent
    return None


def data_path(path: str | Path) -> dict[str, str]:
    """``{"path": ..., "root": "benchmark"}`` (the path relative to it) for a file in a generated benchmark's
    directory (wherever that is, a checkout's ``runs/`` too), ``"root": "navbench"`` for one under navbench's
    data root, else the path as given."""
    p = Path(path)
    root = benchmark_root(p)
    if root is not None:
        return {"path": p.resolve().relative_to(root).as_posix(), "root": "benchmark"}
    try:
        return {"path": p.resolve().relative_to(ROOT.resolve()).as_posix(), "root": "navbench"}
    except ValueError:
        return {"path": str(p), "root": "absolute" if p.is_absolute() else "cwd"}


def benchmark_sums(episodes: str | Path) -> Path | None:
    """The ``SHA256SUMS`` of the generated benchmark holding the episode file ``episodes`` (it names the
    sha256 of every file of the benchmark); None for a file in no benchmark, or a benchmark without one."""
    root = benchmark_root(episodes) if data_path(episodes)["root"] == "benchmark" else None
    return root / "SHA256SUMS" if root is not None and (root / "SHA256SUMS").is_file() else None


def file_entry(path: str | Path) -> dict[str, str]:
    return {**data_path(path), "sha256": sha256(path)}


def capped_sha256(path: str | Path) -> str:
    """The sha256 of an input file's bytes as stored, refused (InputTooLarge) past the input cap on its size
    on disk, as its reader would refuse it (:mod:`navbench.safeio`)."""
    h = hashlib.sha256()
    with open_input(path, gunzip=False) as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def split_entry(task: str, episodes: str | Path, gt: str | Path | None = None) -> dict[str, Any]:
    """``files.episodes``' checksums of a split: ``sha256`` of the episode file; ``split_files``, the sha256 of
    every other file the task reads it with (:attr:`Task.episode_files`: habitat-lab's ``content/`` files,
    VLN-CE's gt file), each named relative to the episode file's folder; ``split_sha256``, what identifies the
    split: the episode file's sha256 when there is no other file, else the sha256 of the canonical JSON
    ``{"episodes": sha256, "files": split_files}``. Each file is read up to the input cap."""
    path = Path(episodes)
    known = TASKS.get(task)
    paths = known.episode_files(path, gt) if known is not None else [path]
    head = capped_sha256(path)
    others: dict[str, str] = {}
    for f in paths[1:]:
        try:
            name = f.resolve().relative_to(path.resolve().parent).as_posix()
        except ValueError:  # a --gt file elsewhere: its name
            name = f.name
        others[name] = capped_sha256(f)
    entry: dict[str, Any] = {"sha256": head}
    if others:
        entry["split_files"] = dict(sorted(others.items()))
    text = json.dumps({"episodes": head, "files": entry.get("split_files", {})}, sort_keys=True, separators=(",", ":"))
    entry["split_sha256"] = hashlib.sha256(text.encode()).hexdigest() if others else head
    return entry


def _git(*args: str) -> str | None:
    try:
        res = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout if res.returncode == 0 else None


@lru_cache(maxsize=1)
def navbench_origin() -> dict[str, Any]:
    """navbench's version, and its git commit and dirty flag (tracked files changed) in a checkout."""
    out: dict[str, Any] = {"version": __version__}
    if (ROOT / ".git").exists():
        commit = _git("rev-parse", "HEAD")
        status = _git("status", "--porcelain", "--untracked-files=no")
        if commit:
            out.update(git_commit=commit.strip(), git_dirty=bool(status and status.strip()))
    return out


def versions() -> dict[str, str]:
    """Python's and each of ``PACKAGES``' version; torch's as torch reports its build (``2.13.0+cpu``,
    ``2.14.1+cu130``), which its distribution's version does not tell apart."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        if name == "torch":
            try:
                out[name] = str(importlib.import_module("torch").__version__)
                continue
            except Exception:
                pass
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:  # a fork installed under another name (pyrender-maintained)
            try:
                out[name] = str(importlib.import_module(name).__version__)
            except Exception:
                out[name] = "not installed"
    return out


_TASKS = r"(objectnav|pointnav|instance_imagenav|imagenav|ovon|goat_bench|goat|vln_r2r|eqa)"
_SCANS = r"(hm3d|mp3d|hssd|gibson|procthor)"
_VERSION = r"(v\d+(?:\.\d+)*)"
# habitat-lab's layout (data/datasets/objectnav/hm3d/v2/val/val.json.gz) and its download names
# (objectnav_hm3d_v2, hm3d-val-habitat-v0.2, hm3d_v0.2)
_EPISODES_VERSION = (re.compile(rf"(?i)(?:^|/){_TASKS}/{_SCANS}/{_VERSION}(?:/|$)"),
                     re.compile(rf"(?i)(?:^|/){_TASKS}[_-]{_SCANS}[_-]{_VERSION}(?:[/_.-]|$)"))
_SCENES_VERSION = re.compile(rf"(?i)(?:^|/){_SCANS}(?:[_-][a-z]+)*[_-]{_VERSION}(?:[/_.-]|$)")


def dataset_versions(episodes: str | Path, scenes: list[Path]) -> dict[str, str]:
    """The dataset releases a run's files can be told to come from: ``episodes`` (``objectnav/hm3d/v2``) from
    the episode file's path as habitat-lab lays its datasets out; ``scenes`` (``hm3d/v0.2``) from the scene
    files' paths, else ``hm3d/v0.2`` for HM3D scenes whose dataset config declares ``has_semantic_textures``
    (the v0.2 semantics; v0.1 painted vertex colours). A release the paths do not name is left out."""
    from navbench.scene.datasets import stage_attributes

    out: dict[str, str] = {}
    text = Path(episodes).resolve().as_posix()
    for pattern in _EPISODES_VERSION:
        if m := pattern.search(text):
            out["episodes"] = "/".join(g.lower() for g in m.groups())
            break
    found = set()
    for path in scenes:
        if m := _SCENES_VERSION.search(path.resolve().as_posix()):
            found.add(f"{m.group(1).lower()}/{m.group(2).lower()}")
            continue
        try:
            stage = stage_attributes(path)
        except (OSError, ValueError):
            continue
        if stage.get("has_semantic_textures") and "hm3d" in str(stage.get("__config__", "")).lower():
            found.add("hm3d/v0.2")
    if found:
        out["scenes"] = ", ".join(sorted(found))
    return out


@lru_cache(maxsize=1)
def cpu() -> dict[str, Any]:
    model, flags = platform.processor() or platform.machine(), []
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model in ("", platform.machine(), platform.processor()):
                model = value.strip()
            elif key.strip() in ("flags", "Features") and not flags:
                flags = value.split()
    except OSError:
        pass
    return {"model": model, "flags": " ".join(sorted(flags)), "machine": platform.machine(), "system": sys.platform}


@lru_cache(maxsize=1)
def opengl_renderer() -> str:
    """The OpenGL renderer string of the context the renderer would use (e.g. ``llvmpipe (LLVM 15...)``)."""
    try:
        import pyrender
        from OpenGL import GL

        import navbench.render.renderer  # noqa: F401  (binds PyOpenGL's platform first)

        gl = pyrender.OffscreenRenderer(1, 1)
        try:
            gl._platform.make_current()
            name = GL.glGetString(GL.GL_RENDERER).decode()
            version = GL.glGetString(GL.GL_VERSION).decode()
        finally:
            gl.delete()
        return f"{name}; OpenGL {version}"
    except Exception as exc:  # no GL here: say so rather than fail the run
        return f"unavailable ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"


def _checkpoint(cfg: Any) -> str | Path | None:
    ckpt = (cfg.agent_options or {}).get("checkpoint")
    if ckpt:
        return ckpt
    from navbench.agents.registry import AGENTS

    spec = AGENTS.get(cfg.agent)
    if spec is not None and spec.drives_policy:
        from navbench.agents.pointnav import DEFAULT_CHECKPOINT
        return DEFAULT_CHECKPOINT
    return None


def provenance(cfg: Any, episodes: list | None = None) -> dict[str, Any]:
    """provenance.json's content for a RunConfig whose selected episodes are ``episodes``."""
    from navbench.scene.datasets import resolve_scene

    proto = config_protocol(cfg)
    from navbench.episodes.io import split_version

    episodes_entry: dict[str, Any] = {**data_path(cfg.episodes),
                                      **split_entry(cfg.task, cfg.episodes, getattr(cfg, "gt", None))}
    if (version := split_version(cfg.episodes)) is not None:
        episodes_entry["split_version"] = version
    files: dict[str, Any] = {"episodes": episodes_entry, "scene_dir": data_path(cfg.scene_dir),
                             "scenes": {}}
    if (sums := benchmark_sums(cfg.episodes)) is not None:
        files["benchmark"] = {"sha256sums": sha256(sums)}
    scene_paths = []
    for scene_id in sorted({e.scene_id for e in episodes or []}):
        try:
            path = resolve_scene(scene_id, Path(cfg.scene_dir))
        except (OSError, ValueError):  # a missing scene fails its episodes, as the env reports it
            files["scenes"][scene_id] = {"sha256": None}
            continue
        scene_paths.append(path)
        entry: dict[str, Any] = {"sha256": sha256(path)}
        stem = path.name.split(".")[0]
        # its annotations beside it (navbench's NAME.semantic.json, HM3D's NAME.semantic.glb / .txt)
        sidecars = {p.name: sha256(p) for p in sorted(path.parent.glob(f"{stem}.*")) if p != path and p.is_file()}
        if sidecars:
            entry["sidecars"] = sidecars
        files["scenes"][scene_id] = entry
    ckpt = _checkpoint(cfg)
    if ckpt is not None and Path(ckpt).is_file():
        files["checkpoint"] = file_entry(ckpt)
    doc = {"protocol": proto, "protocol_id": protocol_id(proto), "navbench": navbench_origin(),
           "versions": versions(), "opengl_renderer": opengl_renderer(), "cpu": cpu(), "run_on": run_on(cfg),
           "files": files}
    if datasets := dataset_versions(cfg.episodes, scene_paths):
        doc["datasets"] = datasets
    return doc


def run_on(cfg: Any) -> dict[str, Any]:
    """Where a run's work ran, which is not part of its protocol: the torch device (and its name), the real
    perception models' precision, and the GL platform the renderer is bound to (``gl_platform="auto"``:
    EGL on a GPU, else OSMesa)."""
    from navbench.device import device_name
    from navbench.render.gl_platform import bound_platform

    device = getattr(cfg, "device", "cpu")
    return {"device": device, "device_name": device_name(device), "precision": getattr(cfg, "precision", "fp32"),
            "gl_platform": bound_platform()}


def recorded_run_on(run_dir: str | Path) -> dict[str, str]:
    """A run directory's ``device`` and ``precision`` as its provenance.json records them; a run recorded
    without them ran on the CPU in fp32 (there was no other choice)."""
    try:
        doc = json.loads((Path(run_dir) / PROVENANCE).read_bytes())
        got = doc.get("run_on") if isinstance(doc, dict) else None
    except (OSError, ValueError, RecursionError):
        got = None
    got = got if isinstance(got, dict) else {}
    return {"device": str(got.get("device", "cpu")), "precision": str(got.get("precision", "fp32"))}


def write_provenance(out: Path, cfg: Any, episodes: list | None = None, resume: bool = False) -> dict[str, Any]:
    """Write ``out/provenance.json``; resuming, a run recorded under another protocol is refused."""
    from navbench.eval.rundir import RunError, write_atomic

    doc = provenance(cfg, episodes)
    old = Path(out) / PROVENANCE
    if resume and old.is_file():
        try:
            before = json.loads(old.read_text()).get("protocol_id")
        except (ValueError, AttributeError):
            before = None
        if before is not None and before != doc["protocol_id"]:
            raise RunError(f"{old}: cannot --resume, the run was scored under protocol {before}, this one is "
                           f"{doc['protocol_id']} (use another --out, or --overwrite to start over)")
    write_atomic(Path(out) / PROVENANCE, json.dumps(doc, indent=1) + "\n")
    return doc


def merge_provenance(run_dirs: list[Path], out: Path) -> None:
    """The merged run's provenance.json: the first shard's, with each shard's origin and machine listed
    under ``shards`` (merge checks first that they share the protocol)."""
    from navbench.eval.rundir import write_atomic

    docs = []
    for d in run_dirs:
        try:
            docs.append(json.loads((Path(d) / PROVENANCE).read_text()))
        except (OSError, ValueError):
            docs.append(None)
    if docs[0] is None or not isinstance(docs[0], dict):
        return
    merged = dict(docs[0])
    merged["shards"] = [{k: doc.get(k) for k in ("navbench", "versions", "opengl_renderer", "run_on")} | {
        "cpu_model": (doc.get("cpu") or {}).get("model")} if isinstance(doc, dict) else None for doc in docs]
    write_atomic(Path(out) / PROVENANCE, json.dumps(merged, indent=1) + "\n")
