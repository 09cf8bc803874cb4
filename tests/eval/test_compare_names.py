"""compare names what differs by setting, with BASE's value first, and says what an absent value means."""

import json
import shutil

import pytest

from navbench.cli import main
from navbench.eval.provenance import ProtocolError, check_same_protocol, protocol, protocol_diff
from navbench.paths import RESULTS_DIR

VAL_UNSEEN = RESULTS_DIR / "runs" / "objectnav" / "val_unseen"


def test_compare_names_the_agent_setting_not_the_labels(capsys):
    assert main(["compare", str(VAL_UNSEEN / "memory"), str(VAL_UNSEEN / "memory-noise_default"), "--json",
                 "--metric", "spl"]) == 0
    diffs = json.loads(capsys.readouterr().out)["differences"]
    assert [(x["field"], x["base"], x["other"], x["line"]) for x in diffs] == \
        [("noise", "none", "default", "noise none vs default")]


def test_an_absent_protocol_field_says_what_it_means():
    looks = protocol("pointnav", 0.2, {"actions": ["STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP",
                                                  "LOOK_DOWN"], "tilt_angle_deg": 30.0})
    plain = protocol("pointnav", 0.2)
    diff = protocol_diff(looks, plain)
    assert "tilt_angle_deg 30.0 vs none (no look actions)" in diff
    noisy = protocol("pointnav", 0.2, {"actuation_noise": "LoCoBot-ILQR", "gps_compass": False})
    assert protocol_diff(plain, noisy) == ["actuation_noise none (noiseless) vs 'LoCoBot-ILQR'",
                                           "gps_compass True (the default) vs False"]


def test_a_protocol_refusal_names_base_first(tmp_path):
    far = tmp_path / "far"
    shutil.copytree(VAL_UNSEEN / "frontier", far, ignore=shutil.ignore_patterns("videos"))
    doc = json.loads((far / "provenance.json").read_text())
    doc["protocol"]["success_distance"] = 1.0
    (far / "provenance.json").write_text(json.dumps(doc))
    base = VAL_UNSEEN / "memory"
    with pytest.raises(ProtocolError) as exc:
        check_same_protocol([base, far])
    assert str(exc.value).startswith(f"{base} vs {far}: scored under different protocols (success_distance 0.25 "
                                     f"vs 1.0)")
