"""Localisation views: a query's picture puts the ground truth and the predictions where they are on the map."""

from types import SimpleNamespace

import numpy as np

from navbench.localize.pipeline import LocalizationTrace
from navbench.scene.navigability import NavGrid
from navbench.viz.localize import QueryViews, query_view
from navbench.viz.topdown import TopDown


class FakeLocalizer:
    def __init__(self):
        self.last_trace = LocalizationTrace(prompt="chair", retrieved=[(3, 0.9), (5, 0.4)], kept=[5, 3],
                                            segmented=[5])
        rgb = np.full((30, 40, 3), 200, np.uint8)
        self.memory = SimpleNamespace(store=SimpleNamespace(rgb=lambda kf: rgb))
        self.segmenter = SimpleNamespace(segment=lambda img, prompt: (np.ones((30, 40), bool), 1.0))

    def _image(self, kf, backend):
        return None


def test_query_view_marks_truth_and_predictions(tmp_path):
    free = np.zeros((40, 60), bool)
    free[2:38, 2:58] = True
    grid = NavGrid(free, free, origin=(0.0, 0.0), cell_size=0.1, floor_height=0.0)
    rec = {"id": "q1", "type": "object", "query": "chair", "success": False,
           "top_k": [[1.0, 0.5, 1.0]], "gt_positions": [[4.0, 0.5, 2.5]]}
    cand = SimpleNamespace(points=np.array([[1.0, 0.5, 1.0], [1.1, 0.5, 1.0]]), centre=np.array([1.0, 0.5, 1.0]))
    img = query_view(FakeLocalizer(), None, [cand], rec, grid)
    assert img.ndim == 3 and img.shape[1] == 5 * 160
    # the map sits below the header and the keyframe row, 10 px in; find the star's green and the cross's red
    view = TopDown.fit(grid, max_side=img.shape[1] - 20)
    top = img.shape[0] - (view.size[0] + 10) + 5
    u, v = view.px(4.0, 2.5)
    patch = img[top + v - 3:top + v + 4, 10 + u - 3:10 + u + 4].reshape(-1, 3).astype(int)
    assert ((patch[:, 1] > 120) & (patch[:, 0] < 60)).any()  # green star at the ground truth
    u, v = view.px(1.0, 1.0)
    patch = img[top + v - 3:top + v + 4, 10 + u - 3:10 + u + 4].reshape(-1, 3).astype(int)
    assert ((patch[:, 0] > 180) & (patch[:, 1] < 80)).any()  # red cross at the prediction
    hook = QueryViews(tmp_path / "viz")
    hook._grids["s"] = grid
    hook(FakeLocalizer(), None, [cand], rec, "s")
    assert (tmp_path / "viz" / "q1.png").is_file()
