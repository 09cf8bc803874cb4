"""``navbench protocol RUN``: a run's protocol as a paragraph for a paper's methods section.

The paragraph names the task in words, the episodes (file, how many the run scored, the file's sha256 and, for a
split read with other files (``content/``, a gt file), the split's), the task's rules (``Task.rules``: what the
agent is given, when an episode succeeds and ends, what its measures mean) with the run's success distance and
step limit, the actions, the agent's body and sensors, the noise, the navigability rules, navbench's version and
the protocol id. Every figure comes from the run directory: the protocol from ``provenance.json`` (or, for a run
written before it, derived from ``config.json``:
:func:`navbench.eval.provenance.run_protocol`), the episode file's checksum and the version from
``provenance.json``, the count from ``summary.json`` (else the records). ``--format markdown`` (the
default), ``latex`` (special characters escaped) or ``json`` (the facts the paragraph is written from).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from navbench.env.config import CONDITIONS, SUCCESS_DISTANCE, EnvConfig
from navbench.eval.provenance import ProtocolError, protocol_id, run_protocol
from navbench.eval.stats import doc_get, read_run_doc
from navbench.safeio import printable
from navbench.tasks import TASKS, Task

FORMATS = ("markdown", "latex", "json")
# A protocol's task that is not a registered one: "ovon", ObjectNav's rules at OVON's distance.
_OTHER = {"ovon": ("open-vocabulary ObjectNav (HM3D-OVON style)", "objectnav")}


def protocol_facts(run_dir: str | Path) -> dict[str, Any]:
    """What the paragraph says, as data: the protocol, its id, the episodes and navbench's version."""
    run_dir = Path(run_dir)
    proto = run_protocol(run_dir)
    cfg, prov, summary = (read_run_doc(run_dir, n) for n in ("config.json", "provenance.json", "summary.json"))
    episodes = doc_get(prov, "files", "episodes") or {}
    count = summary.get("num_episodes")
    if not isinstance(count, int) or isinstance(count, bool):
        count = _count_records(run_dir)
    version = doc_get(prov, "navbench", "version") or cfg.get("navbench_version")
    return {
        "protocol": {k: v for k, v in proto.items() if k != "derived"},
        "protocol_id": protocol_id(proto),
        "derived": bool(proto.get("derived")),
        "episodes": {"file": episodes.get("path") or cfg.get("episodes") or cfg.get("split"),
                     "split": cfg.get("split"), "count": count, "sha256": episodes.get("sha256"),
                     "split_files": sorted(episodes.get("split_files") or {}),
                     "split_sha256": episodes.get("split_sha256"),
                     "split_version": episodes.get("split_version"), "datasets": prov.get("datasets")},
        "navbench_version": version,
    }


def _count_records(run_dir: Path) -> int | None:
    from navbench.eval.rundir import read_records

    try:
        return sum(not r.get("skipped") for r in read_records(run_dir / "episodes.jsonl"))
    except (OSError, ValueError):
        return None


def _num(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _sentences(f: dict[str, Any]) -> list[tuple[str, list[str]]]:
    """The paragraph as (sentence, the literal names in it that markdown sets as code)."""
    p, e = f["protocol"], f["episodes"]
    task = str(p.get("task"))
    out: list[tuple[str, list[str]]] = []
    count = f"{e['count']} episodes" if e.get("count") is not None else "the episodes"
    file = str(e.get("file") or "an unrecorded episode file")
    what = f"{count} of {file}"
    if e.get("sha256") and e.get("split_files") and e.get("split_sha256"):  # content/ or gt files read with it
        n = len(e["split_files"])
        what += f" (sha256 {e['sha256']}; with the {n} file{'s' * (n > 1)} read beside it, split sha256 " \
                f"{e['split_sha256']})"
    elif e.get("sha256"):
        what += f" (sha256 {e['sha256']})"
    extras = []
    if e.get("split_version") is not None:
        extras.append(f"split version {e['split_version']}")
    for k, v in (e.get("datasets") or {}).items():
        extras.append(f"{k} from the {v} release")
    if extras:
        what += ", " + ", ".join(extras)
    name, t = _task(task)
    out.append((f"We evaluate {name} on {what}.", [file]))
    sd = p.get("success_distance", SUCCESS_DISTANCE.get(task))
    if t is not None and t.rules:
        out.append((t.rules.format(sd=_num(sd), max_steps=p.get("max_steps")), []))
    else:
        out.append((f"An episode succeeds when the agent calls STOP within {_num(sd)} m geodesic distance of the "
                    f"goal, and ends after at most {p.get('max_steps')} actions.", []))
    actions = p.get("actions") or []
    names = [a if isinstance(a, str) else json.dumps(a, sort_keys=True) for a in actions]
    act = (f"The actions are {', '.join(names)}: a forward step of {_num(p.get('forward_step'))} m, turns of "
           f"{_num(p.get('turn_angle_deg'))} deg")
    if any(str(a).startswith("LOOK_") for a in names):  # a protocol leaves out EnvConfig's default tilt
        act += f", camera tilts of {_num(p.get('tilt_angle_deg', EnvConfig().tilt_angle_deg))} deg"
    act += "; a blocked step " + ("slides along the obstacle." if p.get("allow_sliding") else "does not slide.")
    out.append((act, names))
    body = (f"The agent is a cylinder of radius {_num(p.get('agent_radius'))} m with its camera "
            f"{_num(p.get('agent_height'))} m above the floor; it climbs steps of up to {_num(p.get('max_climb'))} m.")
    out.append((body, []))
    pitch = p.get("camera_pitch_deg", CONDITIONS["camera_pitch_deg"])
    sensors = (f"It senses RGB and depth at {p.get('width')} x {p.get('height')} pixels with a "
               f"{_num(p.get('hfov_deg'))} deg horizontal field of view (depth {_num(p.get('min_depth'))}-"
               f"{_num(p.get('max_depth'))} m{', normalised' if p.get('normalize_depth') else ''}), the camera "
               + (f"pitched {_num(pitch)} deg" if pitch else "level"))
    sensors += (", and GPS+compass." if p.get("gps_compass", CONDITIONS["gps_compass"]) else ", without GPS+compass.")
    out.append((sensors, []))
    noise = []
    if p.get("actuation_noise"):
        noise.append(f"{p['actuation_noise']} actuation noise (x{_num(p.get('actuation_noise_multiplier', 1.0))})")
    if p.get("depth_noise"):
        noise.append(f"{p['depth_noise']} depth noise (x{_num(p.get('depth_noise_multiplier', 1.0))})")
    if p.get("rgb_noise"):
        noise.append(f"{p['rgb_noise']} RGB noise (intensity {_num(p.get('rgb_noise_intensity', 0.2))})")
    out.append(("Noise: " + "; ".join(noise) + ", as habitat-sim models them." if noise
                else "Actuation and sensors are noiseless.", []))
    nav = (f"Navigability and geodesic distances follow navbench's rules version {p.get('navigability')} on a "
           f"{_num(p.get('cell_size'))} m grid, an episode start snapped onto it from up to "
           f"{_num(p.get('start_snap_tolerance'))} m away." if p.get("navigability") is not None else
           f"Navigability follows a {_num(p.get('cell_size'))} m grid (the rules' version is not recorded).")
    out.append((nav, []))
    others = sorted(set(p) - _SAID)
    if others:
        out.append(("Also: " + ", ".join(f"{k} {json.dumps(p[k], sort_keys=True)}" for k in others) + ".", others))
    ver = f"navbench {f['navbench_version']}" if f.get("navbench_version") else "navbench"
    out.append((f"Runs use {ver}; protocol id {f['protocol_id']}"
                + (" (derived from the run's configuration)." if f.get("derived") else "."), [f["protocol_id"]]))
    return out


def _task(task: str) -> tuple[str, Task | None]:
    """A protocol's task as prose names it, and its definition (whose ``rules`` the paragraph states)."""
    if task in _OTHER:
        name, rules_of = _OTHER[task]
        return name, TASKS[rules_of]
    t = TASKS.get(task)
    return (t.display_name, t) if t is not None else (task, None)


_SAID = {"task", "success_distance", "max_steps", "actions", "forward_step", "turn_angle_deg", "tilt_angle_deg",
         "allow_sliding", "agent_radius", "agent_height", "max_climb", "width", "height", "hfov_deg", "min_depth",
         "max_depth", "normalize_depth", "camera_pitch_deg", "gps_compass", "actuation_noise",
         "actuation_noise_multiplier", "depth_noise", "depth_noise_multiplier", "rgb_noise", "rgb_noise_intensity",
         "navigability", "cell_size", "start_snap_tolerance"}

_LATEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
          "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}
_LATEX_RE = re.compile("|".join(re.escape(k) for k in _LATEX))


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped (``\\ & % $ # _ { } ~ ^``)."""
    return _LATEX_RE.sub(lambda m: _LATEX[m.group(0)], text)


def _markdown(sentence: str, literals: list[str]) -> str:
    for lit in sorted(set(literals), key=len, reverse=True):
        if lit and "`" not in lit:
            sentence = sentence.replace(lit, f"`{lit}`", 1)
    return sentence


def protocol_text(run_dir: str | Path, fmt: str = "markdown") -> str:
    """The run's protocol as a methods paragraph (``markdown``, ``latex``) or its facts (``json``)."""
    if fmt not in FORMATS:
        raise ProtocolError(f"format {fmt!r}: choose one of {', '.join(FORMATS)}")
    facts = protocol_facts(run_dir)
    if fmt == "json":
        return json.dumps(facts, indent=1)
    # a run directory's strings are printed on one line, control characters escaped
    sentences = [(printable(s, 2000), [printable(x, 2000) for x in lits]) for s, lits in _sentences(facts)]
    if fmt == "latex":
        return " ".join(latex_escape(s).replace(" x ", r" $\times$ ") for s, _ in sentences)
    return " ".join(_markdown(s, lits) for s, lits in sentences)
