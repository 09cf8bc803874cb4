"""The RL examples (SB3, TorchRL, CleanRL-style) train for a few hundred steps without a warning docs/rl.md
does not explain."""

import importlib.util
import warnings
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
# docs/rl.md: TorchRL 0.14 deprecates its own weight-updater classes while importing itself.
EXPLAINED = ("WeightUpdaterBase",)


def _example(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _unexplained(caught) -> list[str]:
    return [f"{w.category.__name__}: {w.message}" for w in caught if not any(e in str(w.message) for e in EXPLAINED)]


@pytest.mark.slow
def test_sb3_example_trains_and_evaluates_without_warnings(tmp_path):
    pytest.importorskip("stable_baselines3")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ex = _example("train_sb3")
        summary = ex.main(["--steps", "256", "--size", "48", "--episodes", "1", "--max-steps", "50",
                           "--out", str(tmp_path / "ppo.zip")])
    assert _unexplained(caught) == []
    assert set(summary) == {"success", "spl"} and (tmp_path / "ppo.zip").is_file()
    from stable_baselines3 import PPO
    model = PPO.load(tmp_path / "ppo.zip", device="cpu")
    assert type(model.policy.features_extractor.extractors["depth"]).__name__ == "NatureCNN"  # depth is an image


@pytest.mark.slow
def test_torchrl_example_trains_and_reads_success_from_info():
    pytest.importorskip("torchrl")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ex = _example("train_torchrl")
        rates = ex.main(["--frames", "400", "--batch", "200", "--max-steps", "100"])
    assert _unexplained(caught) == []
    assert len(rates) == 2 and all(0 <= r <= 1 for r in rates)  # NaN (no episode ended) fails too


@pytest.mark.slow
def test_cleanrl_style_example_trains_on_a_vector_env():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rates = _example("train_cleanrl").main(["--total-timesteps", "512", "--num-envs", "2", "--num-steps", "128",
                                                "--max-steps", "100"])
    assert _unexplained(caught) == []
    assert len(rates) == 2 and all(0 <= r <= 1 for r in rates)
