"""Map geometry on a hand-made grid: cells, world points and a path land on the expected pixels."""

import numpy as np

from navbench.scene.navigability import NavGrid
from navbench.viz.topdown import (
    COLLISION,
    NAVIGABLE,
    OBSTACLE,
    SHORTEST,
    UNREACHABLE,
    WALL,
    EpisodeDrawing,
    TopDown,
    draw_episode,
    shortest_path,
)


def grid() -> NavGrid:
    """10 x 12 cells of 0.1 m, origin (1.0, -2.0): an open room (rows 1-8, cols 1-10) split by a wall at
    column 6 with a door at rows 6-7; a second, closed room's floor never reached from the first."""
    free = np.zeros((10, 12), bool)
    free[1:9, 1:11] = True
    free[1:6, 6] = False  # the wall, door below it
    free[8, 1:11] = False
    nav = free.copy()
    nav[1, 9:11] = False
    island = np.zeros_like(free)
    island[1, 10] = True
    return NavGrid(free | island, nav, origin=(1.0, -2.0), cell_size=0.1, floor_height=0.0)


def test_cells_land_on_their_pixel_blocks():
    g = grid()
    v = TopDown(g, scale=4, i0=0, j0=0, rows=10, cols=12)
    img = v.scene_layer()
    assert img.shape == (40, 48, 3)
    assert tuple(img[2 * 4 + 1, 2 * 4 + 2]) == NAVIGABLE  # cell (2, 2): pixels rows 8-11, cols 8-11
    assert tuple(img[3 * 4, 6 * 4 + 3]) == WALL  # cell (3, 6): obstacle bordering the floor
    assert tuple(img[0, 0]) == WALL and tuple(img[9 * 4 + 3, 0]) == OBSTACLE  # (0,0) borders floor; (9,0) not
    # world (x, z) of cell (i, j)'s centre is origin + (j, i) * cell_size -> the middle of its block
    np.testing.assert_allclose(v.to_px(1.0 + 0.2, -2.0 + 0.3), [2 * 4 + 2, 3 * 4 + 2])
    assert v.px(1.0 + 0.2, -2.0 + 0.3) == (10, 14)


def test_crop_shifts_pixels_and_unreachable_is_drawn():
    g = grid()
    v = TopDown.fit(g, max_side=100, margin=0)
    assert (v.i0, v.j0, v.rows, v.cols, v.scale) == (1, 1, 7, 10, 10)  # floor rows 1-7 (row 8 is blocked), cols 1-10
    np.testing.assert_allclose(v.to_px(1.0 + 0.1, -2.0 + 0.1), [5, 5])  # cell (1, 1) is the crop's first
    reach = g.navigable.copy()
    reach[:, 7:] = False  # pretend the right half is another island
    img = v.scene_layer(reachable=reach)
    assert tuple(img[(3 - 1) * 10 + 5, (8 - 1) * 10 + 5]) == UNREACHABLE
    assert tuple(img[(3 - 1) * 10 + 5, (2 - 1) * 10 + 5]) == NAVIGABLE


def test_path_and_collision_pixels():
    g = grid()
    v = TopDown(g, scale=4, i0=0, j0=0, rows=10, cols=12)
    img = np.full((40, 48, 3), 255, np.uint8)
    # along row 3 from column 2 to 5 (x 1.2 -> 1.5, z -1.7), a collision at the last pose
    poses = np.array([[1.2, -1.7, 0.0], [1.3, -1.7, 0.0], [1.4, -1.7, 0.0], [1.5, -1.7, 0.0]])
    draw_episode(img, v, EpisodeDrawing(poses=poses, collisions=np.array([False, False, True])))
    row = 3 * 4 + 2
    assert (img[row, 3 * 4 + 2] != 255).any() and (img[row, 4 * 4 + 2] != 255).any()  # the path
    assert tuple(img[row, 5 * 4 + 2]) in {COLLISION, (220, 30, 30)}  # collision dot (or STOP mark)
    assert (img[8 * 4:, :] == 255).all()  # nothing below row 7


def test_shortest_path_goes_through_the_door():
    g = grid()
    start = np.array([1.2, 0.0, -1.7])  # cell (3, 2), left of the wall
    goal = np.array([[1.9, 0.0, -1.7]])  # cell (3, 9), right of it
    f = g.distance_field(goal)
    path = shortest_path(f, start)
    ij = g.world_to_grid(np.column_stack([path[:, 0], np.zeros(len(path)), path[:, 1]]))
    assert g.navigable[ij[:, 0], ij[:, 1]].all()
    assert (np.abs(np.diff(ij, axis=0)) <= 1).all()  # neighbouring cells
    assert tuple(ij[-1]) == (3, 9)
    crossing = ij[ij[:, 1] == 6]
    assert len(crossing) and (crossing[:, 0] >= 6).all()  # crosses column 6 only in the door
    v = TopDown(g, scale=4, i0=0, j0=0, rows=10, cols=12)
    img = np.full((40, 48, 3), 255, np.uint8)
    draw_episode(img, v, EpisodeDrawing(shortest=path))
    i = int(crossing[0, 0])
    px = img[i * 4 + 2, 6 * 4 + 2].astype(int)  # the door cell it crosses: green (antialiased)
    assert px[1] > px[0] + 50 and px[1] > px[2] + 50, px
    assert (img[1 * 4:6 * 4, 6 * 4:7 * 4] == 255).all()  # nothing drawn on the wall's cells
    assert SHORTEST[1] > SHORTEST[0] + 50
