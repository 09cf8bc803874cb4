"""Training state: saved as tensors plus JSON, read with torch.load(weights_only=True), so a crafted state
file runs no code; a resumed optimizer is the one that was saved."""

import os
import pickle

import pytest
import torch

from navbench.cli import main
from navbench.policy.checkpoint import CheckpointError, load_train_state, read_train_state, save_train_state


def _model_and_opt():
    torch.manual_seed(0)
    model = torch.nn.Sequential(torch.nn.Linear(4, 3), torch.nn.Linear(3, 2))
    opt = torch.optim.Adam(model.parameters(), lr=1e-3, betas=(0.8, 0.99))
    model(torch.ones(1, 4)).sum().backward()
    opt.step()
    return model, opt


def test_state_round_trips_weights_optimizer_and_counters(tmp_path):
    model, opt = _model_and_opt()
    path = tmp_path / "train_state.pt"
    save_train_state(path, {"policy": model.state_dict(), "optimizer": opt.state_dict(), "iteration": 7,
                            "frames": 1234, "wall_s": 5.5})
    fresh, fresh_opt = torch.nn.Sequential(torch.nn.Linear(4, 3), torch.nn.Linear(3, 2)), None
    fresh_opt = torch.optim.Adam(fresh.parameters(), lr=1.0)
    assert load_train_state(path, fresh, fresh_opt, "iteration") == (7, 1234, 5.5)
    for a, b in zip(model.state_dict().values(), fresh.state_dict().values()):
        assert torch.equal(a, b)
    saved, loaded = opt.state_dict(), fresh_opt.state_dict()
    assert saved["param_groups"] == loaded["param_groups"]
    for k, st in saved["state"].items():
        assert all(torch.equal(v, loaded["state"][k][n]) for n, v in st.items())
    # what is on disk is tensors and a string: weights_only reads it
    obj = torch.load(path, weights_only=True)
    assert set(obj) == {"format", "state", "tensors"} and isinstance(obj["state"], str)


class Payload:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


@pytest.mark.parametrize("how", ["pickle", "torch"])
def test_a_crafted_state_runs_no_code_and_fails_in_one_line(how, tmp_path):
    marker = tmp_path / "pwned"
    path = tmp_path / "state" / "train_state.pt"
    path.parent.mkdir()
    if how == "pickle":
        path.write_bytes(pickle.dumps({"policy": Payload(marker)}))
    else:
        torch.save({"policy": Payload(marker), "optimizer": {}, "iteration": 1}, path)
    with pytest.raises(CheckpointError, match=str(path)):
        read_train_state(path)
    assert main(["train", "dagger", "--out", str(tmp_path / "p.pth"), "--state-dir", str(path.parent),
                 "--resume"]) == 2
    assert not marker.exists()


def test_a_planted_temporary_symlink_redirects_nothing(tmp_path):
    model, opt = _model_and_opt()
    victim = tmp_path / "victim"
    victim.write_text("keep")
    path = tmp_path / "train_state.pt"
    for name in (".train_state.pt.tmp", "train_state.tmp"):
        (tmp_path / name).symlink_to(victim)
    save_train_state(path, {"policy": model.state_dict(), "optimizer": opt.state_dict(), "iteration": 1,
                            "frames": 1, "wall_s": 1.0})
    assert victim.read_text() == "keep" and read_train_state(path)["iteration"] == 1
