"""A cross-storey episode's map has one panel per storey its path touches, each with that storey's part."""

import json
import sys
from pathlib import Path

import numpy as np

from navbench.cli import main
from navbench.viz.replay import Replayer, Run

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
from storeys import UPPER, house


def test_map_of_an_episode_up_the_stairs_has_a_panel_per_storey(tmp_path):
    from navbench.viz.maps import episode_map
    from navbench.viz.topdown import START, STOP_MARK, TopDown

    house("stairs").export(tmp_path / "stairs.glb")
    ep = {"episode_id": "0", "scene_id": "stairs.glb", "start_position": [1.0, 0.0, 1.0],
          "start_rotation": [0.0, 0.0, 0.0, 1.0], "goals": [{"position": [8.5, UPPER, 5.0], "radius": None}],
          "info": {}}
    (tmp_path / "eps.json").write_text(json.dumps({"episodes": [ep]}))
    out = tmp_path / "run"
    assert main(["run", "--episodes", str(tmp_path / "eps.json"), "--scene-dir", str(tmp_path), "--agent", "oracle",
                 "--workers", "1", "--out", str(out), "-q"]) == 0
    run = Run.load(out)
    rp = Replayer(run)
    r = run.records[0]
    assert r["success"] == 1.0
    storeys = rp.storeys(r)
    assert [round(g.floor_height, 2) for g, _ in storeys] == [0.0, UPPER]
    ground, upper = storeys
    assert ground[1][0] and upper[1][-1] and (ground[1] | upper[1]).all()
    img = episode_map(rp, r, max_side=300, with_legend=False)
    views = [TopDown.fit(g, max_side=300) for g, _ in storeys]
    assert img.shape[1] == views[0].size[1] + 4 + views[1].size[1]
    x0, z0, _ = r["trace"]["poses"][0]
    u, v = views[0].px(x0, z0)
    assert tuple(img[v, u]) == START  # the start on the ground floor's panel
    x1, z1, _ = r["trace"]["poses"][-1]
    u, v = views[1].px(x1, z1)
    u += views[0].size[1] + 4  # the stop on the upper floor's panel
    patch = img[v - 6:v + 7, u - 6:u + 7].reshape(-1, 3)
    assert (patch == np.array(STOP_MARK)).all(axis=1).any()
    assert main(["viz", str(out), "--episode", "0", "-o", str(tmp_path / "maps")]) == 0
    assert (tmp_path / "maps" / "0.png").is_file()
