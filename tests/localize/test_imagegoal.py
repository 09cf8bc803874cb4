"""The ImageNav camera estimate: its parts (panoramic z-buffered render of a labelled cloud, heading scores, free
floor, id-histogram retrieval) and the whole search on goal images of a bundled house."""

from __future__ import annotations

import numpy as np

from navbench.localize.imagegoal import (
    _EMPTY,
    ImageGoalConfig,
    _histogram,
    free_floor,
    goal_cylinder,
    render_cylinders,
    score_headings,
    similarity,
)


def _wall(z: float, instance: int, n: int = 60, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = np.meshgrid(np.linspace(-3, 3, n)[::step], np.linspace(-2, 4, n)[::step])
    pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)
    return pts, np.full(len(pts), instance, np.int64)


def test_render_cylinders_shows_the_nearest_surface_at_each_heading():
    near, far = _wall(-2.0, 7), _wall(-4.0, 9)
    behind = _wall(+2.0, 5)  # heading pi from a camera at the origin
    pts = np.concatenate([far[0], near[0], behind[0]])
    ids = np.concatenate([far[1], near[1], behind[1]])
    shown = render_cylinders(pts, ids, np.array([[0.0, 1.0, 0.0]]), 36, 12, 0.8)[0]
    ahead = shown[:, [34, 35, 0, 1]]  # headings within 20 degrees of 0 (looking along -z)
    assert (ahead == 7).all() and not (shown == 9).any()
    assert (shown[:, [16, 17, 18, 19]] == 5).all()  # headings within 20 degrees of pi
    assert (shown[:, 9] == _EMPTY).all()  # a quarter turn: nothing there


def test_render_cylinders_fills_a_sparse_near_surface_before_a_dense_far_one():
    near, far = _wall(-1.0, 7, n=240, step=2), _wall(-6.0, 9, n=300)  # points 5 cm and 2 cm apart
    pts, ids = np.concatenate([near[0], far[0]]), np.concatenate([near[1], far[1]])
    cam = np.array([[0.0, 1.0, 0.0]])
    ahead = np.ix_(np.arange(20, 40), np.arange(-5, 5) % 360)  # 10 degrees either side of the camera's heading
    bare = render_cylinders(pts, ids, cam, 360, 60, 0.8, fill=0)[0][ahead]
    filled = render_cylinders(pts, ids, cam, 360, 60, 0.8, fill=2)[0][ahead]
    assert (bare == 9).mean() > 0.2  # the far wall shows through the near one's gaps
    assert (filled == 7).all()


def test_score_headings_peaks_at_the_goal_cameras_heading():
    rng = np.random.default_rng(0)
    rendered = rng.integers(0, 5, (1, 16, 72))
    goal = goal_cylinder(np.zeros((32, 32), np.int64), 79.0, 72, 16, 1.0)
    cols = (20 + goal.offsets) % 72
    labels = rendered[0][:, cols]
    goal = type(goal)(labels, goal.weights, goal.offsets, goal.tan_half)
    scores = score_headings(rendered, goal)[0]
    assert int(np.argmax(scores)) == 20 and scores[20] == 1.0 and scores[30] < 0.5
    assert np.array_equal(score_headings(rendered, goal, np.array([20, 30]))[0], scores[[20, 30]])


def test_free_floor_keeps_clear_of_obstacles():
    g = np.arange(-2.0, 2.0, 0.02)
    fx, fz = np.meshgrid(g, g)
    floor = np.stack([fx.ravel(), np.zeros(fx.size), fz.ravel()], axis=1)
    post = np.array([[0.0, h, 0.0] for h in np.arange(0.2, 0.9, 0.05)])  # a thin post at the origin
    far = np.array([[3.0, 0.5, 3.0]])  # an obstacle point where no floor was seen
    free, origin = free_floor(np.concatenate([floor, post, far]), 0.0, ImageGoalConfig(clearance=0.15, cell=0.05))

    def at(x, z):
        i, j = np.floor((np.array([x, z]) - origin) / 0.05).astype(int)
        return bool(free[i, j])
    assert at(1.0, 1.0) and at(0.3, 0.0) and not at(0.0, 0.0) and not at(0.1, 0.0)
    assert not at(2.6, 2.6)  # no floor seen there


def test_similarity_is_the_histogram_intersection():
    a = _histogram(np.array([1, 1, 2, -1]))
    assert a == {1: 2 / 3, 2: 1 / 3}
    assert similarity(a, a) == 1.0
    assert abs(similarity(a, {2: 1.0}) - 1 / 3) < 1e-12
    assert similarity(a, {3: 1.0}) == 0.0


def test_estimate_camera_finds_where_goal_images_were_taken(oracle_memory, oracle_scene):
    """House 011's ImageNav val goals whose images show objects: each estimate within 0.25 m of the camera."""
    from navbench.env.config import EnvConfig
    from navbench.episodes.instance_imagenav import ImageGoal
    from navbench.localize.imagegoal import estimate_camera
    from navbench.paths import split_file
    from navbench.render.goal_images import render_image_goal_ids
    from navbench.tasks import get_task
    from navbench.tasks.imagenav import goal_rotation

    c = EnvConfig()
    episodes = {e.episode_id: e for e in get_task("imagenav").read_episodes(split_file("imagenav", "val")).episodes
                if e.scene_id.endswith("house_011.glb")}
    errors = []
    for eid in ("300", "304", "315", "319"):
        e = episodes[eid]
        eye = np.asarray(e.goals[0].position) + [0.0, c.agent_height, 0.0]
        q = goal_rotation(eid)
        goal = ImageGoal((eye[0], eye[1], eye[2]), (q[0], q[1], q[2], q[3]), c.hfov_deg, c.height, c.width)
        rgb, ids = render_image_goal_ids(oracle_scene, goal)
        est = estimate_camera(oracle_memory, ids, c.hfov_deg, rgb)
        errors.append(float(np.hypot(*(est.position - eye)[[0, 2]])))
        assert abs(est.position[1] - eye[1]) < 0.05
    assert max(errors) < 0.25, errors


def test_refine_camera_finds_the_goal_camera_from_live_views_taken_near_it(oracle_memory, oracle_scene):
    """An agent that stands 0.3-0.4 m from where a goal image of house 011 was taken and turns a full circle: the
    search over its views (depth, ids, colours) joined to the memory puts the camera within 0.15 m, with a score
    above that of the same search started a room away (where the image was not taken)."""
    from navbench.env.config import EnvConfig
    from navbench.episodes.instance_imagenav import ImageGoal
    from navbench.localize.geometry import backproject
    from navbench.localize.imagegoal import goal_labels, memory_cloud, refine_camera
    from navbench.paths import split_file
    from navbench.render.camera import CameraConfig, camera_pose, intrinsics
    from navbench.render.goal_images import render_image_goal_ids
    from navbench.render.renderer import Renderer
    from navbench.scene.pose import quat_from_yaw
    from navbench.tasks import get_task
    from navbench.tasks.imagenav import goal_rotation, goal_yaw

    c = EnvConfig()
    cam = CameraConfig(width=c.width, height=c.height, hfov_deg=c.hfov_deg)
    config = ImageGoalConfig()
    cloud = memory_cloud(oracle_memory, config.stride)
    mp, mi, mc = cloud.voxels(config.stages[-1][2])
    episodes = {e.episode_id: e for e in get_task("imagenav").read_episodes(split_file("imagenav", "val")).episodes
                if e.scene_id.endswith("house_011.glb")}

    def look_round(renderer, eye):
        parts = []
        for k in range(12):
            yaw = k * np.pi / 6
            out = renderer.render(eye, quat_from_yaw(yaw), rgb=True, depth=True, ids=True)
            mask = np.zeros(out.depth.shape, bool)
            mask[::2, ::2] = True
            mask &= (out.depth > c.min_depth) & (out.depth < c.max_depth)
            parts.append((backproject(out.depth, mask, intrinsics(cam), camera_pose(eye, quat_from_yaw(yaw))),
                          out.ids[mask], out.rgb[..., :3][mask]))
        pts, ids, rgb = (np.concatenate(p) for p in zip(*parts))
        near = np.hypot(mp[:, 0] - eye[0], mp[:, 2] - eye[2]) < config.radius
        return np.concatenate([pts, mp[near]]), np.concatenate([ids, mi[near]]), np.concatenate([rgb, mc[near]])

    free = cloud.free(float(cloud.camera_y[0]) - cloud.camera_height, config)
    with Renderer(oracle_scene, cam) as renderer:
        for eid, offset in (("300", (0.3, -0.2)), ("304", (-0.25, 0.3))):
            e = episodes[eid]
            eye = np.asarray(e.goals[0].position) + [0.0, c.agent_height, 0.0]
            q = goal_rotation(eid)
            rgb, ids = render_image_goal_ids(oracle_scene, ImageGoal(tuple(eye), tuple(q), c.hfov_deg, c.height,
                                                                     c.width))
            goal = goal_labels(ids, c.hfov_deg, rgb, config)
            start = eye + [offset[0], 0.0, offset[1]]
            found = refine_camera(*look_round(renderer, start), goal, start, goal_yaw(eid) + 0.3, free, config)
            assert np.hypot(*(found.position - eye)[[0, 2]]) < 0.15, (eid, found.position, eye)
            elsewhere = eye + [2.5, 0.0, 0.0] if eid == "300" else eye + [0.0, 0.0, 2.5]
            wrong = refine_camera(*look_round(renderer, elsewhere), goal, elsewhere, goal_yaw(eid), free, config)
            assert wrong.score < found.score - 0.1, (eid, wrong.score, found.score)
