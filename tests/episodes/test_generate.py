"""The bundled PointNav policy splits: ``train_large`` to train on, ``select`` to choose among policies."""

from navbench.episodes.generate import generate_policy_select_split
from navbench.episodes.io import load_dataset
from navbench.paths import SCENES_DIR, split_file
from navbench.scene.procedural import POLICY_SELECT_HOUSES, generate_house


def _houses(task: str, split: str) -> set[str]:
    return {e.scene_id for e in load_dataset(split_file(task, split)).episodes}


def test_select_split_is_reproduced_by_its_generator_in_houses_of_its_own(tmp_path):
    bundled = load_dataset(split_file("pointnav", "select"))
    assert generate_policy_select_split(tmp_path, SCENES_DIR, log=lambda *_: None) == len(bundled.episodes) == 200
    again = load_dataset(tmp_path / "pointnav" / "select" / "select.json.gz")
    assert again.episodes == bundled.episodes

    select = _houses("pointnav", "select")
    assert len(select) == POLICY_SELECT_HOUSES["n_val"]
    assert all(s.startswith(POLICY_SELECT_HOUSES["dir"] + "/val/") for s in select)
    # choosing a policy here must not look at a house it trained in or is reported on
    others = _houses("pointnav", "train_large") | _houses("pointnav", "val") | _houses("objectnav", "val_seen")
    assert not select & others
    # the GLB itself is the generator's house for seed 2 * 1000 + i, so it is no copy of any other house
    first = SCENES_DIR / POLICY_SELECT_HOUSES["dir"] / "val" / "house_000.glb"
    assert first.read_bytes() == generate_house(2000)[0].export(file_type="glb")
