"""Oracle perception over rendered instance ids, its noise, and the description grounding it uses."""

import math

import numpy as np
import pytest

from navbench.localize.backends import Encoder, Reranker, Segmenter
from navbench.localize.backends.oracle import (
    NOISE_PROFILES,
    NoiseProfile,
    OracleCaptioner,
    OracleDepthNoise,
    OracleEncoder,
    OracleReranker,
    OracleSegmenter,
    centre_instance,
    noise_profile,
)
from navbench.localize.describe import Description, describe_unique, describe_with_room, ground, parse
from navbench.paths import SCENES_DIR
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.pose import quat_from_yaw, yaw_towards

SCENE = SCENES_DIR / "houses" / "val" / "house_011.glb"
FRIDGE, BROWN_CHAIR, NAVY_CHAIR, TABLE = 13, 16, 17, 15  # house_011's annotations


@pytest.fixture(scope="module")
def scene():
    return load_scene_and_navgrid(SCENE)


def view_of(scene, obj_id: int, distance: float = 2.0, accept=None):
    """A rendered (rgb, ids, depth) 96 x 96 view from a navigable point facing the object, in which the
    object is the centre instance (or which ``accept(ids)`` accepts)."""
    asset, grid = scene
    centre = asset.objects[obj_id].center
    if accept is None:
        def accept(ids):
            return centre_instance(ids) == obj_id and (ids == obj_id).mean() > 0.03
    with Renderer(asset, CameraConfig(96, 96, 79.0)) as r:
        for k in range(36):
            a = math.radians(10 * k)
            p = np.array([centre[0] + distance * math.sin(a), grid.floor_height, centre[2] + distance * math.cos(a)])
            if not grid.is_navigable(p):
                continue
            out = r.render(p + [0, 0.88, 0], quat_from_yaw(yaw_towards(p, centre)), rgb=True, depth=True, ids=True)
            if accept(out.ids):
                return out.rgb, out.ids, out.depth
    raise AssertionError(f"no suitable view of object {obj_id}")


def test_parse_and_ground_descriptions(scene):
    asset, _ = scene
    assert parse("couch") == Description("sofa")
    assert parse("Coffee_Table").category == "coffee_table"  # longest phrase wins over "table"
    assert parse("armchair").category == "armchair"  # a scene category keeps its own name
    assert parse("the blue laundry basket in the laundry") == Description("laundry_basket", "blue", "laundry")
    assert parse("the navy chair in the kitchen next to the table") == Description("chair", "navy", "kitchen",
                                                                                   "table")
    assert parse("a thing") is None
    assert ground("chair", asset.objects) == [BROWN_CHAIR, NAVY_CHAIR]
    assert ground("the navy chair", asset.objects) == [NAVY_CHAIR]
    assert ground("the navy chair in the bathroom", asset.objects) == []
    assert ground("the fridge", asset.objects) == [FRIDGE]
    desc = describe_unique(asset.objects[BROWN_CHAIR], asset.objects)
    assert desc == Description("chair", "brown") and ground(desc.text(), asset.objects) == [BROWN_CHAIR]
    full = describe_with_room(asset.objects[BROWN_CHAIR], asset.objects)
    assert full.text() == "the brown chair in the kitchen next to the table"


def test_oracle_backends_on_a_rendered_frame(scene):
    asset, _ = scene
    rgb, ids, _ = view_of(scene, FRIDGE)
    enc, rr, seg = OracleEncoder(asset.objects), OracleReranker(asset.objects), OracleSegmenter(asset.objects)
    assert isinstance(enc, Encoder) and isinstance(rr, Reranker) and isinstance(seg, Segmenter)
    assert {enc.modality, rr.modality, seg.modality} == {"instance_ids"}

    image = enc.encode_images([ids, np.full((8, 8), -1, np.int32)])
    assert image.shape == (2, enc.dim) and np.allclose(np.linalg.norm(image, axis=1), 1.0)
    text = enc.encode_text(["refrigerator", "the black fridge", "toilet"])
    assert not (ids == 8).any()  # the toilet is in the bathroom
    scores = text @ image[0]
    assert scores[0] > 0.2 and scores[1] > scores[0] and scores[2] == 0.0  # colour sharpens, absent is 0
    assert np.all(text @ image[1] == 0.0)  # a view of bare walls matches no object

    yes, vis = rr.score(ids, "fridge")
    assert yes and vis == pytest.approx(min(1.0, (ids == FRIDGE).mean() / 0.2))
    assert rr.score(ids, "toilet") == (False, 0.0)
    mask, score = seg.segment(ids, "refrigerator")
    assert np.array_equal(mask, ids == FRIDGE) and score == 1.0
    assert seg.segment(ids, "toilet") == (None, 0.0)
    with pytest.raises(ValueError, match="instance-id images"):
        seg.segment(rgb, "refrigerator")

    # A category query takes the largest visible instance; a description its own instance.
    def both_chairs(v):
        n = [(v == c).sum() for c in (BROWN_CHAIR, NAVY_CHAIR)]
        return min(n) >= 30 and n[0] != n[1]

    _, ids_t, _ = view_of(scene, TABLE, 2.5, accept=both_chairs)
    larger, smaller = sorted((BROWN_CHAIR, NAVY_CHAIR), key=lambda i: -(ids_t == i).sum())
    assert np.array_equal(seg.segment(ids_t, "chair")[0], ids_t == larger)
    colour = asset.objects[smaller].colour
    assert np.array_equal(seg.segment(ids_t, f"the {colour} chair")[0], ids_t == smaller)
    assert rr.score(ids_t, f"the {colour} chair")[1] < rr.score(ids_t, "chair")[1]

    assert OracleCaptioner(asset.objects).describe(ids) == "the black refrigerator"


def test_noise_is_seeded_and_deterministic_per_query_and_view(scene):
    asset, _ = scene
    _, ids, depth = view_of(scene, FRIDGE)
    _, ids2, _ = view_of(scene, NAVY_CHAIR)
    default = noise_profile("default")
    assert default == NOISE_PROFILES["default"] and noise_profile("none").is_noiseless
    with pytest.raises(ValueError, match="unknown noise profile"):
        noise_profile("loud")

    # Dilation grows the exact mask by the ring and nothing else.
    dil = OracleSegmenter(asset.objects, NoiseProfile(mask_dilate_px=2)).segment(ids, "fridge")[0]
    exact = ids == FRIDGE
    assert dil[exact].all() and dil.sum() > exact.sum()
    ero = OracleSegmenter(asset.objects, NoiseProfile(mask_erode_px=1)).segment(ids, "fridge")[0]
    assert not ero[~exact].any() and ero.sum() < exact.sum()

    # Same profile, query and view -> same answer, from fresh instances and in any order.
    noisy = NoiseProfile(mask_dilate_px=1, wrong_view_prob=0.5, miss_prob=0.5, seed=3)
    views = [ids, ids2, np.roll(ids, 5, axis=1), np.roll(ids2, 7, axis=0)]
    queries = ["fridge", "toilet", "the navy chair", "sofa", "oven"]

    def run(order):
        seg = OracleSegmenter(asset.objects, noisy)  # a fresh instance: nothing carried between runs
        return {(q, v): seg.segment(views[v], q) for q, v in order}

    pairs = [(q, v) for q in queries for v in range(len(views))]
    a, b = run(pairs), run(pairs[::-1])
    for key in pairs:
        ma, mb = a[key][0], b[key][0]
        assert (ma is None) == (mb is None) and (ma is None or np.array_equal(ma, mb))
    # ... and the draws actually vary across (query, view) pairs and with the seed.
    outcomes = [a[k][0] is None for k in pairs]
    assert 0 < sum(outcomes) < len(outcomes)
    reseeded = OracleSegmenter(asset.objects, NoiseProfile(mask_dilate_px=1, wrong_view_prob=0.5, miss_prob=0.5,
                                                          seed=4))
    assert [reseeded.segment(views[v], q)[0] is None for q, v in pairs] != outcomes

    # Certain noise: every detection missed; every view without the target becomes a wrong detection
    # of the largest other object, which the reranker reports as the best possible view.
    assert OracleSegmenter(asset.objects, NoiseProfile(miss_prob=1.0)).segment(ids, "fridge")[0] is None
    wrong = NoiseProfile(wrong_view_prob=1.0)
    assert OracleReranker(asset.objects, wrong).score(ids, "toilet") == (True, 1.0)
    mask = OracleSegmenter(asset.objects, wrong).segment(ids, "toilet")[0]
    assert np.array_equal(mask, ids == FRIDGE)

    # Depth noise: relative, deterministic per (query, depth image), zero stays zero.
    dn = OracleDepthNoise(NoiseProfile(depth_noise_std=0.05))
    d1, d2 = dn.perturb(depth, "fridge"), dn.perturb(depth, "fridge")
    assert np.array_equal(d1, d2) and not np.array_equal(d1, dn.perturb(depth, "sofa"))
    valid = depth > 0
    rel = d1[valid] / depth[valid] - 1.0
    assert 0.03 < rel.std() < 0.07 and np.all(d1[~valid] == 0)


def _ann(oid, category, lo, hi):
    from navbench.scene.asset import ObjectAnnotation
    return ObjectAnnotation(oid, category, "", "", (0, 0, 0), tuple(lo), tuple(hi))


def test_open_vocabulary_goal_is_grounded_from_the_goals_positions():
    from navbench.localize.backends.oracle import teach
    from navbench.localize.pipeline import Perception

    objects = {1: _ann(1, "tv_monitor", (0, 1, 0), (1, 2, 0.2)), 2: _ann(2, "tv_monitor", (4, 1, 0), (5, 2, 0.2)),
               3: _ann(3, "chest_of_drawers", (2, 0, 2), (3, 1, 3))}
    enc, rr, seg = OracleEncoder(objects), OracleReranker(objects), OracleSegmenter(objects)
    with pytest.raises(Exception, match="names no known object category"):
        enc.encode_text(["flat screen"])
    stack = Perception(enc, rr, seg)
    # A goal at instance 2's AABB centre: only that tv is the answer, whatever the name.
    assert teach(stack, "flat screen", [[4.5, 1.5, 0.1]]) == (2,)
    ids = np.full((20, 20), -1)
    ids[:, :10] = 1
    ids2 = np.full((20, 20), -1)
    ids2[:, :10] = 2
    assert rr.score(ids2, "flat screen")[0] and not rr.score(ids, "flat screen")[0]
    assert (seg.segment(ids2, "flat screen")[0] == (ids2 == 2)).all()
    # The encoder ranks views of the taught instances' category first; a scan's own category has a slot.
    text = enc.encode_text(["flat screen", "chest of drawers"])
    chest = np.full((20, 20), -1)
    chest[5:15, 5:15] = 3
    img = enc.encode_images([ids2, chest])
    assert np.argmax(img @ text[0]) == 0 and np.argmax(img @ text[1]) == 1
    assert enc.dim == OracleEncoder({1: objects[1]}).dim + 1 and enc.name != OracleEncoder({1: objects[1]}).name
    assert teach(stack, "nothing there", [[50, 50, 50]]) == ()
