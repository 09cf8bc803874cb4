"""Training recipes as data: the TOML files reproduce the shipped checkpoints' training configs and the stages the
Makefile used to spell out, and ``navbench train`` runs them (and single trainers) as documented."""

import dataclasses
from pathlib import Path

import pytest
import torch

import navbench.policy.ppo as ppo
import navbench.policy.pretrain as pretrain
import navbench.policy.train as train
from navbench.cli import build_parser, main
from navbench.paths import POLICIES_DIR
from navbench.policy.config import CONFIGS, TrainConfig
from navbench.policy.recipe import build_config, load_recipe

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs" / "pointnav"

# ----------------------------------------------------------------------------------------------------------------
# The configs before the cleanup, as the old `navbench train encoder|pointnav|ppo` produced them: every default of
# the old dataclasses, then each Makefile command's options over them (`git show d7c17c0:Makefile`, targets
# train-pointnav and train-pointnav-2h with P2H_WORKERS=2 P2H_ITERS=106 P2H_EPOCHS=12 P2H_PPO1=0 P2H_TIGHT=0
# P2H_PPO2=0 P2H_ENCODER_FLAGS=--bf16 "P2H_DAGGER_FLAGS=--bf16 --act-bf16"
# "P2H_S1_FLAGS=--tight-starts 0.2 --max-episode-steps 500"), computed once through the old parser.
OLD_DEFAULTS = {
    "encoder": {"frames_per_scene": 6000, "heldout_frames": 1500, "updates": 2500, "batch_size": 64, "lr": 0.001,
                "min_lr": 1e-05, "warmup": 100, "weight_decay": 0.0001, "patch_weight": 1.0,
                "ray_headings_deg": tuple(float(a) for a in range(-36, 37, 6)), "ray_range": 4.0, "patch_cells": 16,
                "patch_cell_size": 0.25, "log_every": 100, "save_every": 250, "seed": 0, "threads": 2,
                "bf16": False},
    "dagger": {"expert": "geodesic", "train_split": "train", "iterations": 14, "frames_per_iteration": 6000,
               "num_envs": 8, "beta0": 1.0, "beta_decay": 0.7, "beta_min": 0.1, "random_action_prob": 0.08,
               "max_episode_steps": 250, "buffer_frames": 250000, "full_episodes": True, "chunk_len": 32,
               "batch_chunks": 16, "epochs_per_iteration": 16.0, "lr": 0.0005, "lr_schedule": "constant",
               "lr_min": 1e-05, "weight_decay": 0.0, "inflection_weight": 3.0, "collision_weight": 1.0,
               "endgame_weight": 1.0, "endgame_radius": 0.75, "turnaround_weight": 1.0, "turnaround_turns": 3,
               "prev_action": True, "expert_margin": 0.15, "expert_success_distance": None, "grad_clip": 1.0,
               "val_episodes": 16, "val_max_steps": 250, "success_distance": 0.2, "tight_starts": 0.0, "seed": 0,
               "threads": 2, "workers": 1, "bf16": False, "act_bf16": False, "freeze_visual": True,
               "aux_free_space_weight": 1.0, "free_space_headings_deg": (-30.0, -15.0, 0.0, 15.0, 30.0),
               "free_space_range": 2.5},
    "ppo": {"train_split": "train_large", "num_envs": 8, "rollout_steps": 128, "updates": 300, "lr": 2.5e-05,
            "lr_schedule": "constant", "lr_min": 0.0, "critic_lr": 0.001, "gamma": 0.99, "gae_lambda": 0.95,
            "clip": 0.2, "ppo_epochs": 2, "num_minibatches": 2, "value_coef": 0.5, "entropy_coef": 0.001,
            "max_grad_norm": 0.2, "critic_warmup": 30, "slack_reward": -0.01, "success_reward": 2.5,
            "waste_weight": 0.0, "collision_penalty": 0.0, "success_spl": False, "bc_weight": 0.0,
            "replay_failures": 0.0, "replay_buffer": 64, "tight_starts": 0.0, "train_encoder": False,
            "encoder_lr_scale": 0.1, "bf16": False, "act_bf16": False, "expert_success_distance": 0.1,
            "expert_margin": 0.15, "seed": 0, "threads": 2, "workers": 1, "save_every": 5},
}
_LARGE = {"train_split": "train_large", "frames_per_iteration": 8000, "beta0": 0.1, "expert_success_distance": 0.1}
_STAGE5 = {**_LARGE, "epochs_per_iteration": 24.0, "val_episodes": 0}
_WEIGHTED = {**_STAGE5, "collision_weight": 3.0, "endgame_weight": 3.0}
OLD_STAGES = {
    "full": [
        ("encoder", {}),
        ("dagger", {"frames_per_iteration": 8000}),
        ("dagger", {"iterations": 6, "frames_per_iteration": 8000, "beta0": 0.1, "expert_success_distance": 0.1}),
        ("dagger", {**_LARGE, "iterations": 18}),
        ("dagger", {**_STAGE5, "iterations": 16, "lr": 0.00025}),
        ("dagger", {**_WEIGHTED, "iterations": 10, "lr": 0.00025}),
        ("dagger", {**_WEIGHTED, "iterations": 18, "lr": 0.000125, "seed": 9}),
        ("ppo", {"updates": 250, "bc_weight": 0.1, "seed": 35}),
        ("ppo", {"updates": 250, "bc_weight": 0.1, "seed": 36}),
        ("dagger", {**_WEIGHTED, "iterations": 10, "lr": 1.5625e-05, "tight_starts": 0.3, "seed": 25}),
        ("ppo", {"updates": 250, "bc_weight": 0.1, "seed": 47}),
    ],
    "2h": [
        ("encoder", {"bf16": True}),
        ("dagger", {"train_split": "train_large", "iterations": 106, "frames_per_iteration": 8000,
                    "max_episode_steps": 500, "epochs_per_iteration": 12.0, "lr_schedule": "cosine",
                    "lr_min": 1.5e-05, "collision_weight": 3.0, "endgame_weight": 3.0,
                    "expert_success_distance": 0.1, "val_episodes": 0, "tight_starts": 0.2, "seed": 60,
                    "workers": 2, "bf16": True, "act_bf16": True}),
    ],
}

RENAMED = {"dagger": {"val_episodes": "monitor_episodes", "val_max_steps": "monitor_max_steps",
                      "batch_chunks": "batch_episodes"},
           "ppo": {"success_spl": "terminal_reward"}}
# Options added after these configs were written (distributed runs' preemption): they held their defaults then.
ADDED = {"preempt_fraction", "preempt_min_share"}
# Options removed as experiment residue, each with the value at which it changed nothing (the behaviour the code
# now has), or None where the option only mattered under another removed one (noted beside it).
REMOVED = {
    "encoder": {},
    "dagger": {"expert": "geodesic", "turnaround_weight": 1.0, "turnaround_turns": None,
               "prev_action": True, "freeze_visual": True, "full_episodes": True,
               "chunk_len": None,  # truncated chunks only (full_episodes False)
               "aux_free_space_weight": None, "free_space_headings_deg": None, "free_space_range": None,  # encoder
               "success_distance": 0.2},  # the task's radius, which the envs always used
    "ppo": {"waste_weight": 0.0, "collision_penalty": 0.0, "replay_failures": 0.0,
            "replay_buffer": None,  # replay only
            "train_encoder": False, "encoder_lr_scale": None, "bf16": None,  # the encoder's update pass only
            "lr_min": None},  # the cosine schedule only
}

def as_new(trainer: str, old: dict) -> dict:
    """An old config as the new fields: renamed keys, removed keys checked to be at their neutral value, the
    DAgger expert's stop distance made explicit (None meant the 0.2 m success distance)."""
    out = {}
    for key, value in old.items():
        if key in REMOVED[trainer]:
            neutral = REMOVED[trainer][key]
            assert neutral is None or value == neutral, f"{trainer}.{key} = {value!r} is behaviour that was removed"
            continue
        if key == "success_spl":  # the SPL-scaled success bonus, now terminal_reward
            value = "spl" if value else "flat"
        if key == "expert_success_distance" and value is None:
            value = old.get("success_distance", 0.2)
        if isinstance(value, list):
            value = tuple(value)
        out[RENAMED.get(trainer, {}).get(key, key)] = value
    return out


@pytest.mark.parametrize("name", ["full", "2h"])
def test_each_recipe_parses_into_stages_that_build(name):
    recipe = load_recipe(CONFIG_DIR / f"{name}.toml")
    assert recipe.name == name
    assert recipe.stages[0].trainer == "encoder"
    for stage in recipe.stages:
        assert isinstance(stage.config, CONFIGS[stage.trainer])


@pytest.mark.parametrize("name", ["full", "2h"])
def test_each_stage_lists_only_options_that_differ_from_the_defaults(name):
    import tomllib

    with open(CONFIG_DIR / f"{name}.toml", "rb") as f:
        tables = tomllib.load(f)["stage"]
    for table in tables:
        defaults = CONFIGS[table["trainer"]]()
        for key, value in table.items():
            if key not in ("name", "trainer"):
                assert getattr(defaults, key) != value, f"{name}: stage {table['name']}: {key} is the default"


@pytest.mark.parametrize("name", ["full", "2h"])
def test_every_stage_is_the_config_the_old_makefile_command_produced(name):
    stages = load_recipe(CONFIG_DIR / f"{name}.toml").stages
    assert [s.trainer for s in stages] == [t for t, _ in OLD_STAGES[name]]
    for stage, (trainer, options) in zip(stages, OLD_STAGES[name]):
        expected = as_new(trainer, {**OLD_DEFAULTS[trainer], **options})
        actual = dataclasses.asdict(stage.config)
        added = [k for k in ADDED if k in actual]
        assert {k: actual.pop(k) for k in added} == {k: getattr(type(stage.config)(), k) for k in added}
        assert actual == expected, stage.name


@pytest.mark.parametrize(("name", "checkpoint", "key"), [("2h", "pointnav_2h.pth", "train_config"),
                                                        ("full", "pointnav_navbench.pth", "ppo_config")])
def test_the_last_stage_is_the_training_config_stored_in_the_shipped_file(name, checkpoint, key):
    stored = torch.load(POLICIES_DIR / checkpoint, weights_only=False)["config"][key]
    last = load_recipe(CONFIG_DIR / f"{name}.toml").stages[-1]
    if last.trainer == "ppo":
        # PPO's bf16 default followed the CPU; it reached only the encoder pass of train_encoder, off here
        assert stored["train_encoder"] is False
        stored = {**stored, "bf16": None}
    expected = as_new(last.trainer, stored)
    actual = dataclasses.asdict(last.config)
    # options added after the file was trained were not stored: they held their defaults then
    missing = set(actual) - set(expected)
    assert missing <= {"act_bf16", "workers", *ADDED}
    assert {k: actual[k] for k in missing} == {k: getattr(type(last.config)(), k) for k in missing}
    assert {k: actual[k] for k in expected} == expected


def test_a_stage_with_an_unknown_or_mistyped_option_is_refused_by_name(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\n[[stage]]\nname = "s"\ntrainer = "dagger"\nbc_weight = 0.1\n')
    with pytest.raises(ValueError, match="stage 's': dagger has no option 'bc_weight'"):
        load_recipe(bad)
    with pytest.raises(ValueError, match="iterations: expected int"):
        build_config("dagger", {"iterations": 1.5})
    with pytest.raises(ValueError, match="lr_schedule must be one of constant, cosine, linear"):
        build_config("dagger", {"lr_schedule": "step"})
    assert build_config("dagger", {"lr": 1}).lr == 1.0  # TOML ints are fine for floats


# ------------------------------------------------------------------------------------------------ the commands
def _fake_trainers(monkeypatch) -> list:
    """Replace the three trainers by a recorder that writes a stand-in output file."""
    calls = []

    def fake(name):
        def run(cfg, out, state_dir, *rest, device="cpu"):
            init = rest[0] if len(rest) == 2 else None
            calls.append({"trainer": name, "cfg": cfg, "out": Path(out), "state_dir": Path(state_dir), "init": init,
                          "resume": rest[-1], "device": device})
            Path(out).parent.mkdir(parents=True, exist_ok=True)
            Path(out).write_text(name)
        return run

    for name, module in (("encoder", pretrain), ("dagger", train), ("ppo", ppo)):
        monkeypatch.setattr(module, "main", fake(name))
    return calls


def test_a_recipe_runs_its_stages_in_order_each_from_the_last_under_runs(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    calls = _fake_trainers(monkeypatch)
    assert main(["train", "--config", str(CONFIG_DIR / "full.toml")]) == 0
    stages = load_recipe(CONFIG_DIR / "full.toml").stages
    run_dir = Path("runs/pointnav/full")
    assert [c["out"] for c in calls] == [run_dir / f"{s.name}.pth" for s in stages]
    assert [c["state_dir"] for c in calls] == [run_dir / f"{s.name}_state" for s in stages]
    assert [c["init"] for c in calls] == [None] + [run_dir / f"{s.name}.pth" for s in stages[:-1]]
    assert [c["cfg"] for c in calls] == [s.config for s in stages]
    assert not any(c["resume"] for c in calls)
    assert not Path("policies").exists()  # nothing shipped unless asked by path


def test_resume_only_and_out(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    calls = _fake_trainers(monkeypatch)
    config = str(CONFIG_DIR / "2h.toml")
    assert main(["train", "--config", config, "--only", "dagger_cosine"]) == 2  # its init is missing
    assert calls == []
    assert main(["train", "--config", config, "--out-dir", "d", "--resume"]) == 0
    assert [c["resume"] for c in calls] == [True, True]
    calls.clear()
    assert main(["train", "--config", config, "--out-dir", "d", "--only", "dagger_cosine",
                 "--out", "shipped/p.pth"]) == 0
    assert [(c["trainer"], c["init"]) for c in calls] == [("dagger", Path("d/encoder.pth"))]
    assert Path("shipped/p.pth").read_text() == "dagger"
    assert main(["train", "--config", config, "--only", "encoder", "--out", "x.pth"]) == 2  # not the final file
    assert main(["train", "--config", config, "--only", "nope"]) == 2


@pytest.mark.parametrize("trainer", ["encoder", "dagger", "ppo"])
def test_each_trainer_has_one_option_per_field_and_writes_under_runs(monkeypatch, tmp_path, trainer):
    monkeypatch.chdir(tmp_path)
    calls = _fake_trainers(monkeypatch)
    cls = CONFIGS[trainer]
    args = build_parser().parse_args(["train", trainer])
    assert all(hasattr(args, f.name) for f in dataclasses.fields(cls))
    assert main(["train", trainer]) == 0
    (call,) = calls
    assert call["cfg"] == cls()
    assert call["out"] == Path(f"runs/pointnav/{trainer}.pth")
    assert call["state_dir"] == Path(f"runs/pointnav/{trainer}_state")


def test_options_reach_the_config_and_foreign_options_are_argparse_errors(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    calls = _fake_trainers(monkeypatch)
    assert main(["train", "dagger", "--tight-starts", "0.3", "--bf16", "--lr-schedule", "cosine", "--init", "a.pth",
                 "--out", "o.pth", "--resume"]) == 0
    (call,) = calls
    assert call["cfg"] == TrainConfig(tight_starts=0.3, bf16=True, lr_schedule="cosine")
    assert (call["init"], call["out"], call["state_dir"], call["resume"]) == (Path("a.pth"), Path("o.pth"),
                                                                              Path("o_state"), True)
    for argv in (["train", "dagger", "--bc-weight", "0.1"], ["train", "ppo", "--iterations", "3"],
                 ["train", "encoder", "--init", "a.pth"], ["train", "ppo", "--train-encoder"],
                 ["train", "dagger", "--expert", "optimistic"], ["train", "pointnav"],
                 ["train", "dagger", "--train-split", "val"]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 2, argv
    assert main(["train"]) == 2  # neither a recipe nor a trainer
    assert main(["train", "--config", str(CONFIG_DIR / "2h.toml"), "ppo"]) == 2  # both
    assert len(calls) == 1


def test_train_device_reaches_every_stage_and_a_missing_one_is_one_line(monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(tmp_path)
    calls = _fake_trainers(monkeypatch)
    assert main(["train", "--device", "cpu", "--config", "configs/pointnav/2h.toml", "--out-dir", "r"]) == 0
    assert calls and all(c["device"] == "cpu" for c in calls)
    assert main(["train", "--device", "auto", "dagger", "--out", "d.pth", "--init", "r/dagger.pth"]) == 0
    assert calls[-1]["device"] == ("cuda:0" if torch.cuda.is_available() else "cpu")
    if not torch.cuda.is_available():
        n = len(calls)
        capsys.readouterr()
        assert main(["train", "--device", "cuda", "dagger", "--out", "d.pth"]) == 2
        assert len(calls) == n and capsys.readouterr().err.startswith("navbench: error: device 'cuda' is not")
