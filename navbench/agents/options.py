"""The built-in agents' options: one frozen dataclass per kind of agent, with its defaults, its flags and
the dict a run's ``config.json`` records (``agent_options``).

A field's metadata says how ``navbench run`` spells it (:func:`add_flags`): ``flag`` (default
``--field-name``; a bool that defaults to True gets ``--no-field-name``), ``help``, ``choices`` and,
for a flag whose words are not the field's values, ``values`` (word -> value). A field with
``internal`` set is never a flag or a user option (the Ray backend points it at a worker's copy).

    >>> o = MemoryOptions.from_user({"fusion": False}, "memory")
    >>> (o.decoding, o.fusion, MemoryOptions.from_record(o.to_record()) == o)
    ('argmax', False, True)
"""

from __future__ import annotations

import argparse
import dataclasses
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from navbench.paths import POLICIES_DIR

DEFAULT_CHECKPOINT = POLICIES_DIR / "pointnav_navbench.pth"  # the shipped PointNav policy
DECODINGS = ("argmax", "sample", "least-tried")  # navbench.policy.net.DECODINGS, without importing torch
KEYFRAME_RES = ("full", "640x480", "160x120")
MODEL_FIELDS = ("siglip2", "qwen_vl", "sam3")  # recorded together as ``models``


def _opt(default: Any, help: str, **meta: Any) -> Any:
    return field(default=default, metadata={"help": help, **meta})


@dataclass(frozen=True)
class AgentOptions:
    """An agent without options (the oracles). Subclasses add typed fields; every field is an option."""

    # Whether the agent's actions depend on the run's seed (then a seed other than 0 names the run).
    draws: ClassVar[bool] = False

    @classmethod
    def user_fields(cls) -> list[dataclasses.Field]:
        """The fields a user may set (flags, ``--agent-opt``, ``evaluate(options=...)``)."""
        return [f for f in dataclasses.fields(cls) if not f.metadata.get("internal")]

    @classmethod
    def from_user(cls, options: dict[str, Any], agent: str) -> AgentOptions:
        """The options with ``options`` over the defaults; a one-line ValueError names an option ``agent``
        does not read or a value it does not take.

        Args:
            options: field name -> value (``models`` as a dict of model directories is accepted too).
            agent: the agent's name, for the error message.

        Returns:
            The checked options.
        """
        options = _split_models(dict(options))
        names = [f.name for f in cls.user_fields()]
        unknown = sorted(set(options) - set(names))
        if unknown:
            raise ValueError(f"agent {agent!r} takes no option {', '.join(map(repr, unknown))} "
                             f"(it takes: {', '.join(names) or 'none'})")
        types = typing.get_type_hints(cls)
        for f in cls.user_fields():
            if f.name not in options:
                continue
            value, kind = options[f.name], types[f.name]
            if kind is bool and not isinstance(value, bool):
                raise ValueError(f"agent {agent!r}: option {f.name!r} must be true or false, got {value!r}")
            if kind in (str, str | None) and not isinstance(value, str):
                raise ValueError(f"agent {agent!r}: option {f.name!r} must be a string, got {value!r}")
            if kind in (float, float | None) and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise ValueError(f"agent {agent!r}: option {f.name!r} must be a number, got {value!r}")
            choices = f.metadata.get("choices")
            if choices and value not in choices:
                raise ValueError(f"agent {agent!r}: unknown {f.name} {value!r}: choose from {', '.join(choices)}")
        return cls(**options)

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> AgentOptions:
        """The options a run's ``config.json`` recorded (keys it does not know are ignored)."""
        record = _split_models(dict(record))
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in record.items() if k in names})

    def to_record(self) -> dict[str, Any]:
        """The ``agent_options`` dict ``config.json`` records."""
        return {}

    def uses_seed(self) -> bool:
        return self.draws

    def label_parts(self, agent: str, seed: int) -> list[str]:
        """What the run's name says after the agent (see :func:`navbench.agents.registry.run_label`)."""
        return [f"seed{seed}"] if seed and self.uses_seed() else []

    def identity(self) -> dict[str, str]:
        """The table's identity columns this agent has (checkpoint, decoding, perception)."""
        return {}


def _split_models(options: dict[str, Any]) -> dict[str, Any]:
    """``models={"siglip2": DIR, ...}`` as the fields siglip2/qwen_vl/sam3 (empty directories dropped)."""
    models = options.pop("models", None)
    if models is None:
        return options
    if not isinstance(models, dict) or set(models) - set(MODEL_FIELDS):
        raise ValueError(f"option 'models' must map {', '.join(MODEL_FIELDS)} to directories, got {models!r}")
    return {**{k: v for k, v in models.items() if v}, **options}


@dataclass(frozen=True)
class RandomOptions(AgentOptions):
    """Habitat's random agent: no options, but every action is drawn from the run's seed."""
    draws: ClassVar[bool] = True


_DECODING_HELP = ("how actions are chosen from the policy's output: argmax; sample (every action drawn, as "
                  "habitat-baselines evaluates); least-tried (argmax, but at a pose already visited drawn among the "
                  "movements taken there least often). Draws are seeded by --seed and the episode")


@dataclass(frozen=True)
class PolicyOptions(AgentOptions):
    """An agent that drives with the PointNav policy: its checkpoint and how actions are decoded."""
    checkpoint: str | None = _opt(None, "policy checkpoint in habitat's layout (default: the shipped one)")
    decoding: str = _opt("argmax", _DECODING_HELP, choices=DECODINGS)
    temperature: float | None = _opt(None, "with --decoding sample: draw from softmax(logits / T) (default 1; lower "
                                     "is closer to the argmax)")

    def __post_init__(self):
        if self.temperature is not None and self.decoding != "sample":
            raise ValueError(f"--temperature applies to decoding 'sample' only, not {self.decoding!r}")
        if self.temperature is not None and not self.temperature > 0:  # also refuses NaN
            raise ValueError(f"temperature must be > 0, got {self.temperature}")

    @property
    def sampling_temperature(self) -> float:
        return 1.0 if self.temperature is None else float(self.temperature)

    @classmethod
    def from_record(cls, record: dict[str, Any]) -> AgentOptions:
        decoding, temperature = decoding_of(record)
        record = {**record, "decoding": decoding, "temperature": temperature if decoding == "sample" else None}
        return super().from_record(record)

    def to_record(self) -> dict[str, Any]:
        out: dict[str, Any] = {"checkpoint": self.checkpoint} if self.checkpoint else {}
        out["decoding"] = self.decoding
        if self.decoding == "sample":
            out["temperature"] = self.sampling_temperature
        return out

    def uses_seed(self) -> bool:
        return self.decoding != "argmax"

    def label_parts(self, agent: str, seed: int) -> list[str]:
        parts = []
        if self.checkpoint and Path(self.checkpoint).resolve() != DEFAULT_CHECKPOINT.resolve():
            parts.append(Path(self.checkpoint).stem)
        default = type(self)().decoding
        t = self.sampling_temperature
        if self.decoding != default or t != 1.0:
            parts.append(f"sample_t{t:g}" if t != 1.0 else self.decoding)
        return parts + super().label_parts(agent, seed)

    def identity(self) -> dict[str, str]:
        decoding = self.decoding
        if decoding == "sample" and self.sampling_temperature != 1.0:
            decoding = f"sample T={self.sampling_temperature:g}"
        checkpoint = Path(self.checkpoint).name.split(".")[0] if self.checkpoint else DEFAULT_CHECKPOINT.stem
        return {"checkpoint": checkpoint, "decoding": decoding}


@dataclass(frozen=True)
class PointNavOptions(PolicyOptions):
    # The PointNav table's headline figures are the shipped policy's with least-tried decoding.
    decoding: str = _opt("least-tried", _DECODING_HELP, choices=DECODINGS)


@dataclass(frozen=True)
class PerceptionOptions(PolicyOptions):
    """A policy agent that perceives objects (the frontier agent's live detector): perception and models."""
    perception: str = _opt("oracle", "oracle | siglip2+qwen2.5-vl+sam3")
    noise: str = _opt("none", "oracle noise profile: none | default | heavy")
    siglip2: str | None = _opt(None, "local SigLIP2 model directory")
    qwen_vl: str | None = _opt(None, "local Qwen2.5-VL model directory, or http://HOST:PORT/v1[#MODEL]: an "
                                     "OpenAI-compatible server (vLLM...) that every worker shares")
    sam3: str | None = _opt(None, "local SAM 3 model directory")

    def models(self) -> dict[str, str]:
        return {k: getattr(self, k) for k in MODEL_FIELDS if getattr(self, k)}

    def to_record(self) -> dict[str, Any]:
        own = {k: getattr(self, k) for k in self._recorded()}
        return {**super().to_record(), **own, "models": self.models()}

    def _recorded(self) -> tuple[str, ...]:
        return ("perception", "noise")

    def label_parts(self, agent: str, seed: int) -> list[str]:
        parts = super().label_parts(agent, seed)
        if self.perception != "oracle":
            parts.append(self.perception)
        if self.noise != "none":
            parts.append(f"noise_{self.noise}")
        return parts

    def identity(self) -> dict[str, str]:
        noise = "" if self.noise == "none" else f", noise {self.noise}"
        return {**super().identity(), "perception": (self.perception or "oracle") + noise}


@dataclass(frozen=True)
class MemoryOptions(PerceptionOptions):
    """The memory agent's options: perception, then the localisation and stopping ablations (all on = the
    agent as reported)."""
    fusion: bool = _opt(True, "single-view backprojection (no multi-view fusion)")
    rerank: bool = _opt(True, "'none': skip VLM re-ranking", flag="--rerank", values={"vlm": True, "none": False})
    keyframe_res: str = _opt("full", "resolution keyframes are stored at", choices=KEYFRAME_RES)
    all_frames: bool = _opt(False, "store every pre-scan frame, not keyframes")
    goal_tracking: bool = _opt(True, "no dynamic goal tracking", flag="--no-tracking")
    visibility_stop: bool = _opt(True, "STOP on distance alone")
    look_round: bool = _opt(True, "ImageNav: take the policy's STOP near the estimated goal camera, without "
                                  "looking round there and searching the live views (oracle perception)",
                            flag="--no-look-round")
    # Where the keyframe memories are kept (default: navbench's cache); set on a Ray worker to its copy.
    memory_root: str | None = _opt(None, "", internal=True)

    def _recorded(self) -> tuple[str, ...]:
        return ("perception", "noise", "fusion", "rerank", "keyframe_res", "all_frames", "goal_tracking",
                "visibility_stop")

    def to_record(self) -> dict[str, Any]:
        out = super().to_record()
        if not self.look_round:  # recorded when off: the other tasks' runs, which it never changes, keep their records
            out["look_round"] = False
        if self.memory_root is not None:
            out["memory_root"] = self.memory_root
        return out

    def label_parts(self, agent: str, seed: int) -> list[str]:
        parts = super().label_parts(agent, seed)
        parts += [tag for tag, on in (("norerank", not self.rerank), ("nofusion", not self.fusion),
                                      ("notrack", not self.goal_tracking), ("novisstop", not self.visibility_stop))
                  if on]
        if self.keyframe_res != "full":
            parts.append(self.keyframe_res)
        if self.all_frames:
            parts.append("allframes")
        if not self.look_round:
            parts.append("nolookround")
        return parts


@dataclass(frozen=True)
class VLNMemoryOptions(MemoryOptions):
    """``vln_memory``'s options: the memory agent's, and how much of the instruction it reads."""
    instruction: str = _opt("full", "how much of a VLN instruction vln_memory reads: the whole (full) or only its "
                            "last sentence (last, an ablation)", choices=("full", "last"))

    def _recorded(self) -> tuple[str, ...]:
        return (*super()._recorded(), "instruction")

    def label_parts(self, agent: str, seed: int) -> list[str]:
        parts = super().label_parts(agent, seed)
        return parts + ([f"instruction_{self.instruction}"] if self.instruction != "full" else [])


def decoding_of(options: dict[str, Any]) -> tuple[str, float]:
    """(decoding, temperature) of a run's agent options. ``navbench run`` always records ``decoding``; a
    config written before that option existed says it with ``sample_actions``/``sample_on_revisit``/
    ``least_tried`` flags (none: argmax), read here so its records can be rerun from it.

    >>> decoding_of({"sample_actions": True, "temperature": 0.5})
    ('sample', 0.5)
    """
    temperature = float(options.get("temperature") or 1.0)
    if "decoding" in options:
        return options["decoding"], temperature
    if not options.get("sample_actions"):
        return "argmax", temperature
    if not options.get("sample_on_revisit"):
        return "sample", temperature
    if options.get("least_tried"):
        return "least-tried", temperature
    raise ValueError("agent_options draw on revisits only (sample_on_revisit without least_tried), a decoding "
                     "navbench no longer has: use decoding 'least-tried' or 'sample'")


# ---------------------------------------------------------------------------------------------- flags
def flag_of(f: dataclasses.Field) -> str:
    """The flag a field is given with on the command line."""
    if "flag" in f.metadata:
        return f.metadata["flag"]
    dashed = f.name.replace("_", "-")
    return f"--no-{dashed}" if f.default is True else f"--{dashed}"


def add_flags(group: Any, classes: dict[str, type[AgentOptions]]) -> dict[str, dataclasses.Field]:
    """One flag per user field of ``classes`` (agent name -> its options class), each added once, with the
    agents that read it in its help. A flag not given leaves no attribute on the parsed namespace, so
    :func:`given_flags` tells what was given from what was not.

    Returns:
        field name -> its field, for every flag added.
    """
    readers: dict[str, dict[str, Any]] = {}  # field -> {agent: its default}
    fields: dict[str, dataclasses.Field] = {}
    for agent, cls in classes.items():
        for f in cls.user_fields():
            fields.setdefault(f.name, f)
            readers.setdefault(f.name, {})[agent] = f.default
    types: dict[str, Any] = {}
    for cls in classes.values():
        types.update(typing.get_type_hints(cls))
    for name, f in fields.items():
        flag, default = flag_of(f), f.default
        defaults = readers[name]
        if len(set(defaults.values())) > 1:  # e.g. each policy agent's own decoding
            help_ = f"{f.metadata.get('help', '')} (default: {', '.join(f'{a} {d}' for a, d in defaults.items())})"
        else:
            help_ = f"{f.metadata.get('help', '')} [{', '.join(defaults)}]"
        if "values" in f.metadata:  # words, read as the field's values by given_flags
            group.add_argument(flag, dest=name, default=argparse.SUPPRESS, choices=tuple(f.metadata["values"]),
                               help=help_)
        elif types[name] is bool:
            group.add_argument(flag, dest=name, default=argparse.SUPPRESS,
                               action="store_false" if default else "store_true", help=help_)
        else:
            kind = float if types[name] in (float, float | None) else str
            group.add_argument(flag, dest=name, default=argparse.SUPPRESS, type=kind, help=help_,
                               choices=f.metadata.get("choices"))
    return fields


def given_flags(args: argparse.Namespace, fields: dict[str, dataclasses.Field]) -> dict[str, Any]:
    """The agent options given on the command line (field name -> value), of :func:`add_flags`'s fields."""
    out = {}
    for name, f in fields.items():
        if hasattr(args, name):
            value = getattr(args, name)
            out[name] = f.metadata["values"][value] if "values" in f.metadata else value
    return out
