"""`navbench protocol RUN`: the run's protocol as a methods paragraph, in markdown, LaTeX and JSON."""

import json

from navbench.cli import main
from navbench.eval.methods import latex_escape
from navbench.paths import RESULTS_DIR

RUN = RESULTS_DIR / "runs" / "objectnav" / "val_unseen" / "memory-navbench-all-noise"


def test_the_paragraph_names_the_success_rule_limit_actions_and_checksum(capsys):
    assert main(["protocol", str(RUN)]) == 0
    text = capsys.readouterr().out.strip()
    prov = json.loads((RUN / "provenance.json").read_text())
    assert len(text.splitlines()) == 1
    assert "calls STOP within 0.25 m geodesic distance of the nearest view point" in text
    assert "at most 500 actions" in text
    assert "`STOP`, `MOVE_FORWARD`, `TURN_LEFT`, `TURN_RIGHT`: a forward step of 0.25 m, turns of 30 deg" in text
    assert f"40 episodes of `episodes/objectnav/val_unseen/val_unseen.json.gz` (sha256 " \
           f"{prov['files']['episodes']['sha256']})" in text
    assert "LoCoBot-Proportional actuation noise (x0.5)" in text and "gaussian RGB noise (intensity 0.1)" in text
    assert f"protocol id `{prov['protocol_id']}`" in text


def test_latex_escapes_special_characters_and_json_gives_the_facts(tmp_path, capsys):
    assert latex_escape(r"a_b & 50% $x$ #a {y} ~ ^ \z") == \
        r"a\_b \& 50\% \$x\$ \#a \{y\} \textasciitilde{} \textasciicircum{} \textbackslash{}z"
    assert main(["protocol", str(RUN), "--format", "latex"]) == 0
    text = capsys.readouterr().out
    assert r"val\_unseen/val\_unseen.json.gz" in text and r"MOVE\_FORWARD" in text and "`" not in text
    assert main(["protocol", str(RUN), "--format", "json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["protocol"]["max_steps"] == 500 and facts["episodes"]["count"] == 40
    assert facts["protocol_id"] == json.loads((RUN / "provenance.json").read_text())["protocol_id"]


def test_a_directory_that_is_no_run_is_one_line_exit_2(tmp_path, capsys):
    assert main(["protocol", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "config.json" in err[0]
    (tmp_path / "config.json").write_text('{"task": "pointnav", "success_distance": 0.2, "env": {"max_steps": 9}}')
    assert main(["protocol", str(tmp_path)]) == 0  # a run without provenance: its protocol derived, and said
    out = capsys.readouterr().out
    assert "at most 9 actions" in out and "derived from the run's configuration" in out


def _paragraph(run, capsys):
    assert main(["protocol", str(RESULTS_DIR / "runs" / run)]) == 0
    return capsys.readouterr().out.strip()


def test_each_tasks_paragraph_states_that_tasks_rules_in_words(capsys):
    goat = _paragraph("goat/val/memory", capsys)
    assert goat.startswith("We evaluate GOAT-Bench on ") and "SUBTASK_STOP, which succeeds when the agent stands " \
        "within 0.25 m geodesic distance of the nearest view point of that subtask's goal instances" in goat
    assert "STOP at any time, ends the episode" in goat and "by goal type (object, description, image)" in goat
    inst = _paragraph("instance_imagenav/val/memory", capsys)
    assert inst.startswith("We evaluate InstanceImageNav on ") and "within 0.1 m geodesic distance of the nearest of " \
        "the pictured instance's view points" in inst
    assert "`LOOK_UP`, `LOOK_DOWN`: a forward step of 0.25 m, turns of 30 deg, camera tilts of 15 deg" in inst
    r2r = _paragraph("r2r_ce/val/vln_random", capsys)
    assert r2r.startswith("We evaluate R2R-CE on ") and "a Room-to-Room instruction" in r2r
    assert "no goal position" in r2r
    assert "within 3 m geodesic distance of the goal point at the route's end" in r2r and "nDTW" in r2r
    assert "without GPS+compass." in r2r and "PointNav" not in r2r
    for text in (goat, inst, r2r):
        assert "We evaluate goat" not in text and "instance_imagenav on" not in text and "r2r_ce on" not in text
