"""End-to-end localisation over a real pre-scan memory with oracle perception."""

import math

import numpy as np
import pytest

from navbench.localize.backends.oracle import (
    NoiseProfile,
    OracleCaptioner,
    OracleDepthNoise,
    OracleEncoder,
    OracleReranker,
    OracleSegmenter,
    centre_instance,
)
from navbench.localize.pipeline import LocalizeError, Localizer, LocalizerConfig, Perception, Query
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.pose import quat_from_yaw, yaw_towards

FRIDGE, BROWN_CHAIR, NAVY_CHAIR = 13, 16, 17


def perception(asset, noise=NoiseProfile()):
    return Perception(OracleEncoder(asset.objects), OracleReranker(asset.objects, noise),
                      OracleSegmenter(asset.objects, noise), OracleCaptioner(asset.objects), OracleDepthNoise(noise))


def top_error(candidates, obj) -> float:
    return float(np.linalg.norm(candidates[0].centre - obj.center))


@pytest.mark.parametrize("fusion", [True, False])
def test_localises_a_known_object(oracle_memory, oracle_scene, fusion):
    loc = Localizer.from_perception(oracle_memory, perception(oracle_scene), LocalizerConfig(fusion=fusion))
    candidates = loc.localize(Query("object", "refrigerator"))
    fridge = oracle_scene.objects[FRIDGE]
    assert candidates and top_error(candidates, fridge) < 0.5
    trace = loc.last_trace
    assert 0 < len(trace.retrieved) <= 10 and set(trace.kept) <= {k for k, _ in trace.retrieved}
    best = candidates[0]
    assert best.keyframe_ids[0] == trace.kept[0] and len(best.points) > 100
    # Every supporting view actually shows the fridge (oracle ids), and the cloud sits on it.
    assert all((oracle_memory.store.instance_ids(k) == FRIDGE).any() for k in best.keyframe_ids)
    # ... and the candidate carries where those views were taken from (the agent's detour goals)
    assert np.allclose(best.view_positions, [oracle_memory.store.pose(k)[:3, 3] for k in best.keyframe_ids])
    lo, hi = np.asarray(fridge.aabb_min) - 0.1, np.asarray(fridge.aabb_max) + 0.1
    inside = np.all((best.points >= lo) & (best.points <= hi), axis=1).mean()
    assert inside > 0.95
    if fusion:
        assert len(best.keyframe_ids) > 1  # several views fused


def test_language_query_finds_the_described_instance(oracle_memory, oracle_scene):
    loc = Localizer.from_perception(oracle_memory, perception(oracle_scene))
    for colour, target, other in (("navy", NAVY_CHAIR, BROWN_CHAIR), ("brown", BROWN_CHAIR, NAVY_CHAIR)):
        c = loc.localize(Query("language", f"the {colour} chair in the kitchen next to the table"))
        assert top_error(c, oracle_scene.objects[target]) < 0.5
        assert top_error(c, oracle_scene.objects[other]) > 0.8


def test_image_query_from_a_new_view(oracle_memory, oracle_scene):
    asset, grid = load_scene_and_navgrid(oracle_scene.path)
    fridge = asset.objects[FRIDGE]
    with Renderer(asset, CameraConfig(224, 224, 79.0)) as r:
        for k in range(36):
            a = math.radians(10 * k + 5)
            p = np.array([fridge.center[0] + 1.7 * math.sin(a), grid.floor_height,
                          fridge.center[2] + 1.7 * math.cos(a)])
            if grid.is_navigable(p):
                out = r.render(p + [0, 0.88, 0], quat_from_yaw(yaw_towards(p, fridge.center)), ids=True)
                if centre_instance(out.ids) == FRIDGE:
                    break
        else:
            raise AssertionError("no view of the fridge")
    loc = Localizer.from_perception(oracle_memory, perception(oracle_scene))
    c = loc.localize(Query("image", image=out.rgb, image_ids=out.ids))
    assert loc.last_trace.prompt == "the black refrigerator"
    assert top_error(c, fridge) < 0.5
    for mode in ("image", "caption"):  # every retrieval mode still reaches the fridge
        cfg = LocalizerConfig(image_retrieval=mode)
        assert top_error(Localizer.from_perception(oracle_memory, perception(oracle_scene), cfg).localize(
            Query("image", image=out.rgb, image_ids=out.ids)), fridge) < 0.5


def test_several_instances_become_several_candidates(oracle_memory, oracle_scene):
    loc = Localizer.from_perception(oracle_memory, perception(oracle_scene))
    c = loc.localize(Query("object", "seat"))  # a synonym of chair
    for chair in (BROWN_CHAIR, NAVY_CHAIR):
        centre = oracle_scene.objects[chair].center
        assert min(np.hypot(*(x.centre - centre)[[0, 2]]) for x in c[:5]) < 1.5
    assert loc.localize(Query("object", "bathtub")) == []  # not in this house


def test_fusion_beats_single_views_when_masks_bleed(oracle_memory, oracle_scene):
    """Dilated masks bleed onto whatever lies behind the object, often metres away: the single view's
    bounding box stretches to it, HDBSCAN over the fused views drops it."""
    from navbench.localize.describe import describe_unique

    noise = NoiseProfile(mask_dilate_px=3)
    errors = {}
    for fusion in (True, False):
        loc = Localizer.from_perception(oracle_memory, perception(oracle_scene, noise), LocalizerConfig(fusion=fusion))
        errs = []
        for obj in oracle_scene.objects.values():
            desc = describe_unique(obj, oracle_scene.objects)
            c = loc.localize(Query("language", desc.text()))
            errs.append(np.hypot(*(c[0].centre - obj.center)[[0, 2]]) if c else np.inf)
        errors[fusion] = np.array(errs)
    assert np.isfinite(errors[True]).all()
    assert np.median(errors[True]) < np.median(errors[False])
    assert (errors[True] < 0.5).mean() > (errors[False] < 0.5).mean()


def test_bad_queries_and_mismatched_backends(oracle_memory, oracle_scene):
    with pytest.raises(LocalizeError, match="query type"):
        Query("sound", "beep")
    with pytest.raises(LocalizeError, match="non-empty text"):
        Query("object", " ")
    with pytest.raises(LocalizeError, match="needs an image"):
        Query("image")
    p = perception(oracle_scene)
    loc = Localizer(oracle_memory, p.encoder, p.reranker, p.segmenter)  # no captioner
    with pytest.raises(LocalizeError, match="captioner"):
        loc.localize(Query("image", image_ids=np.zeros((4, 4), np.int32)))

    class Renamed(OracleEncoder):
        name = "siglip2:elsewhere"

    with pytest.raises(LocalizeError, match="indexed with"):
        Localizer(oracle_memory, Renamed(oracle_scene.objects), p.reranker, p.segmenter)
