"""VLN-CE episode files, written here by hand from the published schema (jacobkrantz/VLN-CE
``habitat_extensions/task.py``; the field values are shaped like R2R_VLNCE_v1-3_preprocessed and an
RxR_VLNCE_v0 sample), read by navbench.episodes.vlnce."""

import gzip
import io
import json
import zipfile

import numpy as np
import pytest

from navbench.episodes.types import EpisodeError
from navbench.episodes.vlnce import (
    gt_paths_beside,
    instruction_observation,
    read_gt,
    read_text_features,
    read_vlnce,
    text_features_path,
)

WORDS = ["<PAD>", "<UNK>", "walk", "past", "the", "sofa", "stop", "."]


def r2r_episode(eid, goals=True):
    ep = {"episode_id": eid, "trajectory_id": 4000 + eid, "scene_id": "mp3d/zsNo4HB9uLZ/zsNo4HB9uLZ.glb",
          "start_position": [1.0, 0.17, -2.0], "start_rotation": [0, 0.7071, 0, 0.7071],
          "info": {"geodesic_distance": 6.42},
          "reference_path": [[1.0, 0.17, -2.0], [3.0, 0.17, -2.0], [5.0, 0.17, -1.0]],
          "instruction": {"instruction_text": "Walk past the sofa. Stop.",
                          "instruction_tokens": [2, 3, 4, 5, 7, 6, 7] + [0] * 193}}
    if goals:
        ep["goals"] = [{"position": [5.0, 0.17, -1.0], "radius": 3.0}]
    else:
        ep["goals"] = None
    return ep


def gt_entry(locs):
    return {"actions": [1] * (len(locs) - 1) + [0], "forward_steps": len(locs) - 1, "locations": locs}


def write(path, data):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(json.dumps(data).encode()))
    return path


@pytest.fixture
def r2r_split(tmp_path):
    d = tmp_path / "R2R_VLNCE_v1-3_preprocessed" / "val_seen"
    ep = write(d / "val_seen.json.gz", {"episodes": [r2r_episode(7), r2r_episode(9)],
                                         "instruction_vocab": {"word_list": WORDS, "word2idx_dict": {},
                                                               "itos": WORDS, "stoi": {}, "num_vocab": 8}})
    write(d / "val_seen_gt.json.gz", {"7": gt_entry([[1.0, 0.17, -2.0], [1.25, 0.17, -2.0]]),
                                      "9": gt_entry([[1.0, 0.17, -2.0]]), "11": gt_entry([[0, 0, 0]])})
    return ep


def test_r2r_preprocessed_with_gt_beside(r2r_split):
    ds = read_vlnce(r2r_split)
    assert ds.flavor == "r2r" and ds.split == "val_seen" and ds.word_list == WORDS
    assert [e.episode_id for e in ds.episodes] == ["7", "9"]  # ints in the file, strings after loading
    ep = ds.episodes[0]
    assert ep.extra["trajectory_id"] == "4007"
    assert ep.goals[0].position == [5.0, 0.17, -1.0]
    assert ep.extra["reference_path"][-1] == [5.0, 0.17, -1.0]
    assert ds.gt_files == [r2r_split.parent / "val_seen_gt.json.gz"]
    assert set(ds.gt_locations) == {"7", "9"}  # only the episodes read are kept
    assert ds.gt_locations["7"] == [[1.0, 0.17, -2.0], [1.25, 0.17, -2.0]]
    obs = instruction_observation(ep)
    assert obs["text"] == "Walk past the sofa. Stop." and len(obs["tokens"]) == 200 and obs["tokens"][-1] == 0
    assert obs["trajectory_id"] == "4007"


def test_gt_given_explicitly_and_missing_entry(tmp_path, r2r_split):
    other = write(tmp_path / "elsewhere.json.gz", {"7": gt_entry([[0, 0, 0]])})
    with pytest.raises(EpisodeError, match="no entry for episode 9"):
        read_vlnce(r2r_split, gt=other)
    ds = read_vlnce(r2r_split, find_gt=False)
    assert ds.gt_locations is None and ds.has_goals


def test_test_split_without_goals_reads(tmp_path):
    p = write(tmp_path / "test" / "test.json.gz", {"episodes": [r2r_episode(1, goals=False)],
                                                   "instruction_vocab": {"word_list": WORDS}})
    ds = read_vlnce(p)
    assert not ds.has_goals and ds.gt_locations is None and ds.episodes[0].goals == []


def test_minimal_r2r_without_tokens(tmp_path):
    ep = r2r_episode(3)
    del ep["instruction"]["instruction_tokens"]
    ds = read_vlnce(write(tmp_path / "train.json.gz", {"episodes": [ep], "instruction_vocab": {"word_list": WORDS}}))
    assert instruction_observation(ds.episodes[0])["tokens"] is None


RXR_EP = {"episode_id": "1", "trajectory_id": "5", "scene_id": "mp3d/SN83YJsR3w2/SN83YJsR3w2.glb",
          "start_position": [-16.27, 0.15, 0.71], "start_rotation": [0, 0.97, 0, -0.24],
          "info": {"role": "guide"}, "goals": [{"position": [-9.9, 0.15, 2.6], "radius": 3.0}],
          "reference_path": [[-16.27, 0.15, 0.71], [-9.9, 0.15, 2.6]],
          "instruction": {"instruction_id": "12", "instruction_text": "Turn around and walk to the kitchen.",
                          "language": "en-IN", "annotator_id": "3", "edit_distance": 0.07,
                          "timed_instruction": [{"word": "Turn", "start_time": 1.0, "end_time": 1.3}]}}


def test_rxr_guide_merges_both_gt_files_and_filters_languages(tmp_path):
    d = tmp_path / "RxR_VLNCE_v0" / "val_unseen"
    hindi = json.loads(json.dumps(RXR_EP))
    hindi["episode_id"], hindi["instruction"]["language"] = "2", "hi-IN"
    p = write(d / "val_unseen_guide.json.gz", {"episodes": [RXR_EP, hindi]})
    write(d / "val_unseen_guide_gt.json.gz", {"1": gt_entry([[-16.27, 0.15, 0.71]])})
    write(d / "val_unseen_follower_gt.json.gz", {"2": gt_entry([[0, 0, 0], [0, 0, 0.25]])})
    assert [f.name for f in gt_paths_beside(p)] == ["val_unseen_guide_gt.json.gz", "val_unseen_follower_gt.json.gz"]
    ds = read_vlnce(p)
    assert ds.flavor == "rxr" and ds.split == "val_unseen" and ds.word_list is None
    assert set(ds.gt_locations) == {"1", "2"}
    en = read_vlnce(p, languages=["en-US", "en-IN"])
    assert [e.episode_id for e in en.episodes] == ["1"]
    assert en.episodes[0].extra["instruction"]["timed_instruction"][0]["word"] == "Turn"


@pytest.mark.parametrize("mutate, field", [
    (lambda e: e.pop("trajectory_id"), "trajectory_id: missing"),
    (lambda e: e.pop("instruction"), "instruction: missing"),
    (lambda e: e["instruction"].pop("instruction_text"), "instruction.instruction_text"),
    (lambda e: e["instruction"].__setitem__("instruction_tokens", [1, "x"]), "instruction.instruction_tokens"),
    (lambda e: e["instruction"].__setitem__("instruction_tokens", [99]), "outside the vocabulary"),
    (lambda e: e.__setitem__("reference_path", [[1, 2]]), "reference_path"),
    (lambda e: e.pop("start_position"), "start_position"),
    (lambda e: e.__setitem__("goals", [{"radius": 3.0}]), "position"),
])
def test_a_malformed_field_is_one_line_naming_file_and_field(tmp_path, mutate, field):
    ep = r2r_episode(5)
    mutate(ep)
    p = write(tmp_path / "val.json.gz", {"episodes": [ep], "instruction_vocab": {"word_list": WORDS}})
    with pytest.raises(EpisodeError) as exc:
        read_vlnce(p)
    msg = str(exc.value)
    assert "\n" not in msg and str(p) in msg and field in msg


def test_r2r_without_vocabulary_is_named(tmp_path):
    p = write(tmp_path / "val.json.gz", {"episodes": [r2r_episode(5)]})
    with pytest.raises(EpisodeError, match="instruction_vocab"):
        read_vlnce(p)


@pytest.mark.parametrize("gt, field", [
    ({"7": {"actions": [0]}}, "locations: missing"),
    ({"7": {"locations": []}}, "locations: must be"),
    ({"7": {"locations": [[0, 0]]}}, "locations: must be"),
    ([1, 2], "not a VLN-CE gt file"),
])
def test_malformed_gt(tmp_path, gt, field):
    p = write(tmp_path / "val_gt.json.gz", gt)
    with pytest.raises(EpisodeError, match=field):
        read_gt(p, {"7"})


def test_gt_truncated_and_bomb(tmp_path):
    p = tmp_path / "val_gt.json.gz"
    p.write_bytes(gzip.compress(json.dumps({"7": gt_entry([[0, 0, 0]] * 50)}).encode())[:-30])
    with pytest.raises(EpisodeError, match="corrupt or truncated"):
        read_gt(p)
    p.write_bytes(gzip.compress(json.dumps({"7": gt_entry([[0, 0, 0]] * 5000)}).encode()))
    with pytest.raises(EpisodeError, match="larger than"):
        read_gt(p, cap=1000)


def npz(arrays):
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def test_text_features_padded_and_bounded(tmp_path):
    path = text_features_path(tmp_path, "val_unseen", "12", "en-IN")
    assert path == tmp_path / "rxr_val_unseen" / "000012_en_text_features.npz"
    path.parent.mkdir()
    feats = np.arange(3 * 768, dtype=np.float64).reshape(3, 768)
    path.write_bytes(npz({"features": feats}))
    out = read_text_features(path)
    assert out.shape == (512, 768) and out.dtype == np.float32
    assert np.array_equal(out[:3], feats.astype(np.float32)) and not out[3:].any()
    path.write_bytes(npz({"features": np.zeros((600, 768))}))
    with pytest.raises(EpisodeError, match="features: "):
        read_text_features(path)
    path.write_bytes(npz({"other": np.zeros(3)}))
    with pytest.raises(EpisodeError, match="features: missing"):
        read_text_features(path)
    path.write_bytes(b"PK not a zip")
    with pytest.raises(EpisodeError, match="not a text-features"):
        read_text_features(path)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:  # a deflate bomb
        zf.writestr("features.npy", b"\0" * (8 << 20))
    with pytest.raises(EpisodeError, match="larger than"):
        read_text_features(path)
    for bad in (("../x", "en-US"), ("12", "../../etc")):
        with pytest.raises(ValueError):
            text_features_path(tmp_path, "val", *bad)


def test_the_cli_names_file_and_field_and_exits_2(tmp_path, capsys):
    from navbench.cli import main

    ep = r2r_episode(5)
    del ep["instruction"]["instruction_text"]
    p = write(tmp_path / "val.json.gz", {"episodes": [ep], "instruction_vocab": {"word_list": WORDS}})
    assert main(["run", "--task", "r2r_ce", "--episodes", str(p), "--agent", "vln_random",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(p) in err and "instruction.instruction_text" in err
