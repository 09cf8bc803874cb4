"""Slow: the committed reference records are reproduced by their commands (run with `make test-slow`)."""

import json

import pytest

from navbench.agents.registry import make_memory, make_optimistic, make_oracle, make_pointnav
from navbench.eval.runner import RunConfig, read_records, run
from navbench.paths import RESULTS_DIR


@pytest.mark.slow
@pytest.mark.parametrize("run_name,factory", [("pointnav_val", make_pointnav),
                                              ("pointnav-sampled_t0.5_val", make_pointnav),
                                              ("pointnav-sampled-revisit_val", make_pointnav),
                                              ("pointnav-sampled-revisit-leasttried_val", make_pointnav),
                                              ("pointnav_2h-leasttried-seed0_val", make_pointnav),
                                              ("oracle_val_unseen", make_oracle),
                                              ("optimistic_pointnav_val", make_optimistic),
                                              ("memory_val_unseen", make_memory),
                                              ("memory-sampled-revisit-leasttried_val_unseen", make_memory)])
def test_reference_run_reproduces_first_episodes(run_name, factory, tmp_path, monkeypatch):
    monkeypatch.chdir(RESULTS_DIR.parent)  # a --checkpoint in a run's config is relative to the project root
    ref_dir = RESULTS_DIR / "runs" / run_name
    cfg = RunConfig(**{k: v for k, v in json.loads((ref_dir / "config.json").read_text()).items()
                       if k in RunConfig.__dataclass_fields__})
    cfg.limit, cfg.workers = 8, 1
    run(cfg, factory, tmp_path / "run")
    ref = {r["episode_id"]: r for r in read_records(ref_dir / "episodes.jsonl")}
    for r in read_records(tmp_path / "run" / "episodes.jsonl"):
        for k in ("success", "spl", "soft_spl", "distance_to_goal", "num_steps", "path_length"):
            assert r[k] == ref[r["episode_id"]][k], (r["episode_id"], k)
