"""``navbench train``: one trainer run from the command line, or a recipe of stages read from a TOML file.

    navbench train --config configs/pointnav/2h.toml                       # every stage, in order
    navbench train --config 2h                                             # the same bundled recipe, by name
    navbench train --config configs/pointnav/full.toml --resume            # continue after a kill
    navbench train --config configs/pointnav/2h.toml --only dagger_cosine  # one stage (its init must exist)
    navbench train --config configs/pointnav/2h.toml --out policies/pointnav_2h.pth   # also copy the result
    navbench train encoder|dagger|ppo [--FIELD VALUE ...] [--init PATH] [--out PATH] [--state-dir DIR] [--resume]

A recipe names itself and lists its stages::

    name = "2h"
    [[stage]]
    name = "encoder"
    trainer = "encoder"     # encoder | dagger | ppo
    bf16 = true             # any field of that trainer's config (navbench.policy.config), else its default

``--config`` takes a recipe file, or a bundled recipe (``navbench.paths.CONFIGS_DIR``) by name (``2h``,
``pointnav/full``) or by its path in the project (``configs/pointnav/2h.toml``, found from any directory).

Each stage starts from the previous stage's output and writes ``<out-dir>/<stage>.pth`` (default out-dir
``runs/pointnav/<name>``), its log beside it and its resumable state in ``<out-dir>/<stage>_state``. Nothing is
written under ``policies/`` unless ``--out`` names the path.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import os
import shutil
import sys
import tomllib
import typing
from pathlib import Path
from typing import Any

from navbench.device import DEVICES, device_arg, resolve_device
from navbench.paths import CONFIGS_DIR, ROOT
from navbench.policy.config import CONFIGS

RUNS_DIR = Path("runs/pointnav")
# The precision options that make a trainer compute in bfloat16 (the CPU warning names them).
BF16_FIELDS = {"encoder": ("bf16",), "dagger": ("bf16", "act_bf16"), "ppo": ("act_bf16",)}
TRAINER_HELP = {"encoder": "pre-train the depth encoder on geometric targets (navbench.policy.pretrain)",
                "dagger": "train the policy by DAgger imitation of the geodesic expert (navbench.policy.train)",
                "ppo": "fine-tune the policy with PPO on the PointNav reward (navbench.policy.ppo)"}


# ------------------------------------------------------------------------------------------- stages
@dataclasses.dataclass(frozen=True)
class Stage:
    name: str
    trainer: str  # a key of CONFIGS
    config: Any  # that trainer's config dataclass


@dataclasses.dataclass(frozen=True)
class Recipe:
    name: str
    stages: tuple[Stage, ...]


def _field_types(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _coerce(value: Any, kind: Any, where: str) -> Any:
    """A TOML value as the field's type: ints are accepted for floats, lists for tuples; anything else must
    match exactly (a bool is no number here)."""
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if typing.get_origin(kind) is tuple and isinstance(value, list):
        return tuple(float(v) for v in value)
    if kind in (int, float, str, bool) and (type(value) is not kind):
        raise ValueError(f"{where}: expected {kind.__name__}, got {value!r}")
    return value


def build_config(trainer: str, options: dict[str, Any], where: str = "options") -> Any:
    """``trainer``'s config with ``options`` over its defaults; an unknown option or a bad value is an error."""
    if trainer not in CONFIGS:
        raise ValueError(f"{where}: unknown trainer {trainer!r}: choose from {', '.join(CONFIGS)}")
    cls = CONFIGS[trainer]
    types = _field_types(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    values = {}
    for key, value in options.items():
        if key not in fields:
            raise ValueError(f"{where}: {trainer} has no option {key!r}")
        value = _coerce(value, types[key], f"{where}: {key}")
        choices = fields[key].metadata.get("choices")
        if choices and value not in choices:
            raise ValueError(f"{where}: {key} must be one of {', '.join(choices)}, got {value!r}")
        values[key] = value
    return cls(**values)


def bundled_recipes() -> list[str]:
    """The bundled recipes' names, e.g. ``pointnav/2h``."""
    return sorted(p.relative_to(CONFIGS_DIR).with_suffix("").as_posix() for p in CONFIGS_DIR.rglob("*.toml"))


def recipe_path(spec: str | Path) -> Path:
    """The recipe file ``spec`` names: an existing file as given; else a bundled recipe by its name (``2h``,
    ``pointnav/2h``) or by its path in the project (``configs/pointnav/2h.toml``); else ``spec`` unchanged."""
    path = Path(spec)
    if path.is_file() or path.is_absolute():
        return path
    text = str(spec).removesuffix(".toml")
    candidates = [ROOT / path, CONFIGS_DIR / f"{text}.toml", *(CONFIGS_DIR / f"{n}.toml" for n in bundled_recipes()
                                                                if n.rsplit("/", 1)[-1] == text)]
    return next((c for c in candidates if c.is_file()), path)


def load_recipe(path: str | Path) -> Recipe:
    """Parse a recipe file (or a bundled recipe: :func:`recipe_path`): a ``name`` and a list of ``[[stage]]``
    tables, each with ``name``, ``trainer`` and that trainer's options."""
    given, path = path, recipe_path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"{given}: recipe file not found (bundled recipes: "
                                f"{', '.join(bundled_recipes()) or 'none'})") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: unreadable recipe ({type(exc).__name__}: {exc})") from None
    unknown = set(data) - {"name", "description", "stage"}
    if unknown:
        raise ValueError(f"{path}: unknown keys {sorted(unknown)}: a recipe has name, description and [[stage]]")
    if not data.get("stage"):
        raise ValueError(f"{path}: no [[stage]] tables")
    stages = []
    for i, table in enumerate(data["stage"]):
        table = dict(table)
        name, trainer = table.pop("name", None), table.pop("trainer", None)
        if not name or not trainer:
            raise ValueError(f"{path}: stage {i + 1} needs a name and a trainer")
        if any(s.name == name for s in stages):
            raise ValueError(f"{path}: two stages are named {name!r}")
        stages.append(Stage(name, trainer, build_config(trainer, table, f"{path}: stage {name!r}")))
    return Recipe(str(data.get("name", path.stem)), tuple(stages))


# ------------------------------------------------------------------------------------------ running
def bf16_warning(trainer: str, cfg: Any) -> None:
    """Warn on stderr when this config asks for bfloat16 on a CPU that emulates it (navbench.policy.precision)."""
    from navbench.policy.precision import emulated_bf16_warning

    flags = [f"--{name.replace('_', '-')}" for name in BF16_FIELDS[trainer] if getattr(cfg, name)]
    warning = emulated_bf16_warning(flags)
    if warning:
        print(warning, file=sys.stderr)


def run_trainer(trainer: str, cfg: Any, out: Path, state_dir: Path, init: Path | None, resume: bool,
                device: str = "cpu") -> Any:
    """Run one trainer (imported here: the CLI stays light until it trains) with its updates on ``device``."""
    bf16_warning(trainer, cfg)
    if trainer == "encoder":
        from navbench.policy import distributed
        from navbench.policy.pretrain import main

        # the encoder's pre-training is not distributed: rank 0 runs it while the other ranks wait for its output
        dist = distributed.init()
        try:
            return main(cfg, out, state_dir, resume, device=device) if dist.is_main else None
        finally:
            distributed.barrier()
    if trainer == "dagger":
        from navbench.policy.train import main
    else:
        from navbench.policy.ppo import main
    return main(cfg, out, state_dir, init, resume, device=device)


def run_recipe(recipe: Recipe, out_dir: Path, resume: bool = False, only: str | None = None,
               out: Path | None = None, init: Path | None = None, run=run_trainer) -> Path:
    """Run ``recipe``'s stages in order (or just ``only``) under ``out_dir``; returns the last output written,
    copied to ``out`` when given. ``init`` is the first stage's starting point when it is not the encoder stage."""
    names = [s.name for s in recipe.stages]
    if only is not None and only not in names:
        raise ValueError(f"recipe {recipe.name!r} has no stage {only!r}: choose from {', '.join(names)}")
    if out is not None and only is not None and only != names[-1]:
        raise ValueError(f"--out takes the recipe's last stage ({names[-1]!r}), not {only!r}")
    previous = init
    result = None
    for stage in recipe.stages:
        stage_out = out_dir / f"{stage.name}.pth"
        if only is None or stage.name == only:
            if stage.trainer != "encoder" and previous is None:
                raise ValueError(f"stage {stage.name!r} starts from a trained policy: give --init PATH")
            if only is not None and previous is not None and not previous.is_file():
                raise FileNotFoundError(f"{previous}: stage {stage.name!r} starts from it; run the stage "
                                        "before it first")
            print(f"stage {stage.name} ({stage.trainer}) -> {stage_out}", file=sys.stderr)
            done = run(stage.trainer, stage.config, stage_out, out_dir / f"{stage.name}_state",
                       previous if stage.trainer != "encoder" else None, resume)
            result = stage_out
            if isinstance(done, dict) and done.get("stopped_by_signal"):
                print(f"stage {stage.name} stopped by a signal: rerun with --resume to continue", file=sys.stderr)
                return result
        previous = stage_out
    if out is not None and os.environ.get("RANK", "0") == "0":  # one copy in a distributed run: rank 0's
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(result, out)
        print(f"copied {result} to {out}", file=sys.stderr)
    return result


# -------------------------------------------------------------------------------------------- parser
def _add_field_options(parser: argparse.ArgumentParser, cls: type) -> None:
    """One ``--field-name`` option per config field, typed and with its default in the help."""
    types = _field_types(cls)
    for f in dataclasses.fields(cls):
        flag = "--" + f.name.replace("_", "-")
        kind = types[f.name]
        help_ = f"{f.metadata.get('help', '')} (default {f.default!r})"
        if kind is bool:
            parser.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=f.default,
                                help=help_)
        elif typing.get_origin(kind) is tuple:
            parser.add_argument(flag, dest=f.name, type=float, nargs="+", default=f.default, help=help_)
        else:
            parser.add_argument(flag, dest=f.name, type=kind, default=f.default, help=help_,
                                choices=f.metadata.get("choices"))


def add_train_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """``navbench train``: ``--config FILE`` for a recipe, or a trainer subcommand with its own options."""
    tr = sub.add_parser("train", help="train the PointNav policy: a recipe (--config) or one trainer "
                                      "(encoder, dagger, ppo)",
                        description="Run a training recipe (--config FILE) or one trainer.")
    tr.add_argument("--config", help="recipe file, e.g. configs/pointnav/2h.toml, or a bundled recipe's name: "
                                     "2h, full")
    tr.add_argument("--out-dir", help=f"where a recipe's stages write (default {RUNS_DIR}/<recipe name>)")
    tr.add_argument("--only", metavar="STAGE", help="run only this stage of the recipe")
    tr.add_argument("--resume", action="store_true", help="continue each stage from its resumable state")
    tr.add_argument("--out", help="also copy the recipe's final checkpoint to this path")
    tr.add_argument("--init", help="the first stage's starting checkpoint, when the recipe's first stage is not "
                                   "the encoder")
    tr.add_argument("--device", type=device_arg, default="cpu",
                    help=f"where the updates run: {DEVICES} (default cpu; rollout workers act on the CPU)")
    trainers = tr.add_subparsers(dest="trainer", metavar="{encoder,dagger,ppo}")
    for name, cls in CONFIGS.items():
        p = trainers.add_parser(name, help=TRAINER_HELP[name], description=TRAINER_HELP[name])
        _add_field_options(p, cls)
        if name != "encoder":
            p.add_argument("--init", dest="stage_init", help="start from this checkpoint's weights")
        p.add_argument("--out", dest="stage_out", default=str(RUNS_DIR / f"{name}.pth"),
                       help=f"checkpoint to write (default {RUNS_DIR / (name + '.pth')})")
        p.add_argument("--state-dir", default=None,
                       help=f"resumable training state (default {RUNS_DIR / (name + '_state')})")
        p.add_argument("--resume", dest="stage_resume", action="store_true",
                       help="continue from --state-dir")
    tr.set_defaults(func=main)
    return tr


def main(args: argparse.Namespace) -> int:
    """``navbench train``'s entry: a recipe with ``--config``, else the trainer subcommand."""
    try:
        return _main(args)
    finally:
        if "navbench.policy.distributed" in sys.modules:  # a trainer joined a process group: leave it
            sys.modules["navbench.policy.distributed"].shutdown()


def _main(args: argparse.Namespace) -> int:
    device = resolve_device(args.device)
    if args.config is not None:
        if args.trainer is not None:
            raise ValueError("give either --config FILE or a trainer (encoder, dagger, ppo), not both")
        recipe = load_recipe(args.config)
        out_dir = Path(args.out_dir) if args.out_dir else RUNS_DIR / recipe.name
        run_recipe(recipe, out_dir, resume=args.resume, only=args.only,
                   out=Path(args.out) if args.out else None, init=Path(args.init) if args.init else None,
                   run=functools.partial(run_trainer, device=device))
        return 0
    if args.trainer is None:
        raise ValueError("give --config FILE (e.g. configs/pointnav/2h.toml) or a trainer: encoder, dagger, ppo")
    stray = [flag for flag, value in (("--out-dir", args.out_dir), ("--only", args.only), ("--out", args.out),
                                      ("--init", args.init), ("--resume", args.resume)) if value]
    if stray:
        raise ValueError(f"{', '.join(stray)} before the trainer go with --config; give the trainer's own "
                         f"options after `{args.trainer}`")
    cls = CONFIGS[args.trainer]
    cfg = cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})
    if isinstance(getattr(cfg, "ray_headings_deg", None), list):
        cfg = dataclasses.replace(cfg, ray_headings_deg=tuple(cfg.ray_headings_deg))
    out = Path(args.stage_out)
    state_dir = Path(args.state_dir) if args.state_dir else out.with_name(out.stem + "_state")
    init = getattr(args, "stage_init", None)
    run_trainer(args.trainer, cfg, out, state_dir, Path(init) if init else None, args.stage_resume, device=device)
    return 0
