"""Top-down maps of a scene's navigability grid, with an episode drawn over them (OpenCV, RGB uint8).

Convention: image rows follow +z and columns +x, so north (-z, where an agent with yaw 0 faces) is up
and east (+x) is right. Grid cell ``(i, j)`` fills the ``s x s`` pixel block whose top-left corner is
``((j - j0) * s, (i - i0) * s)``, ``(i0, j0)`` being the first cell of the crop and ``s`` the pixels per cell.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import cv2
import numpy as np

from navbench.scene.navigability import NavGrid

# Colours (RGB)
NAVIGABLE = (245, 245, 240)
UNREACHABLE = (250, 205, 160)  # navigable, but not on the start's island
FREE = (215, 215, 210)  # floor the agent's body does not fit on (near walls and furniture)
OBSTACLE = (150, 150, 150)
WALL = (40, 40, 40)
EXPLORED = (190, 225, 250)
VIEW_POINT = (60, 170, 60)
GOAL = (0, 130, 0)
START = (30, 90, 220)
STOP_MARK = (220, 30, 30)
COLLISION = (230, 0, 0)
SHORTEST = (20, 160, 20)
CANDIDATE = (240, 140, 0)
DECISION = (200, 0, 200)


def category_colour(category: str) -> tuple[int, int, int]:
    """A stable, saturated colour per object category (the same in every map and run)."""
    h = zlib.crc32(category.encode()) % 180
    hsv = np.array([[[h, 150, 210]]], np.uint8)
    return tuple(int(v) for v in cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0])


@dataclass
class TopDown:
    """A grid crop and its pixel scale: world <-> pixel, and the scene layer of the map."""

    grid: NavGrid
    scale: int  # pixels per cell
    i0: int = 0
    j0: int = 0
    rows: int = 0
    cols: int = 0

    @classmethod
    def fit(cls, grid: NavGrid, max_side: int = 640, margin: int = 4) -> TopDown:
        """Crop to the floor (plus ``margin`` cells) at the largest whole scale within ``max_side`` pixels."""
        ii, jj = np.nonzero(grid.free)
        h, w = grid.shape
        if len(ii):
            i0, i1 = max(ii.min() - margin, 0), min(ii.max() + margin + 1, h)
            j0, j1 = max(jj.min() - margin, 0), min(jj.max() + margin + 1, w)
        else:
            i0, i1, j0, j1 = 0, h, 0, w
        scale = int(max(1, max_side // max(i1 - i0, j1 - j0)))
        return cls(grid, scale, int(i0), int(j0), int(i1 - i0), int(j1 - j0))

    @property
    def size(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        return self.rows * self.scale, self.cols * self.scale

    def to_px(self, x, z) -> np.ndarray:
        """Pixel coordinates (u right, v down; floats) of world points ``x``, ``z``."""
        g = self.grid
        u = ((np.asarray(x, float) - g.origin[0]) / g.cell_size + 0.5 - self.j0) * self.scale
        v = ((np.asarray(z, float) - g.origin[1]) / g.cell_size + 0.5 - self.i0) * self.scale
        return np.stack([u, v], axis=-1)

    def px(self, x, z) -> tuple[int, int]:
        """The pixel containing world point (x, z) (a hair of tolerance: 1.2 - 1.0 is 0.19999...)."""
        u, v = self.to_px(x, z)
        return int(math.floor(u + 1e-6)), int(math.floor(v + 1e-6))

    def crop(self, mask: np.ndarray) -> np.ndarray:
        """A grid-shaped array cropped and upscaled to the map's pixels."""
        m = mask[self.i0:self.i0 + self.rows, self.j0:self.j0 + self.cols]
        return np.repeat(np.repeat(m, self.scale, axis=0), self.scale, axis=1)

    def scene_layer(self, reachable: np.ndarray | None = None, explored: np.ndarray | None = None) -> np.ndarray:
        """Obstacle / floor / navigable / unreachable cells and walls. ``reachable``: navigable cells on the
        episode's island (others are drawn as unreachable); ``explored``: cells an agent has seen."""
        g = self.grid
        img = np.empty((*self.size, 3), np.uint8)
        img[:] = OBSTACLE
        img[self.crop(g.free)] = FREE
        nav = g.navigable if reachable is None else g.navigable & reachable
        img[self.crop(nav)] = NAVIGABLE
        if reachable is not None:
            img[self.crop(g.navigable & ~reachable)] = UNREACHABLE
        if explored is not None:
            e = self.crop(explored & g.free)
            img[e] = (0.5 * img[e] + 0.5 * np.array(EXPLORED)).astype(np.uint8)
        # Walls: obstacle cells bordering the floor.
        from scipy import ndimage
        wall = ~g.free & ndimage.binary_dilation(g.free, structure=np.ones((3, 3), bool))
        img[self.crop(wall)] = WALL
        return img

    def draw_objects(self, img: np.ndarray, objects, goal_ids=(), label: bool = False) -> None:
        """Objects' floor footprints (xz of their boxes), coloured by category; goal instances outlined."""
        for o in objects:
            a = self.to_px(o.aabb_min[0], o.aabb_min[2])
            b = self.to_px(o.aabb_max[0], o.aabb_max[2])
            p0, p1 = tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b)
            col = category_colour(o.category)
            sub = img.copy()
            cv2.rectangle(sub, p0, p1, col, -1)
            cv2.addWeighted(sub, 0.55, img, 0.45, 0, dst=img)
            cv2.rectangle(img, p0, p1, col, 1)
            if o.id in goal_ids:
                cv2.rectangle(img, (p0[0] - 2, p0[1] - 2), (p1[0] + 2, p1[1] + 2), GOAL, 2)
            if label:
                cv2.putText(img, o.category, (p0[0], p0[1] - 2), cv2.FONT_HERSHEY_SIMPLEX, 0.3, (60, 60, 60), 1,
                            cv2.LINE_AA)


@dataclass
class EpisodeDrawing:
    """What is drawn over the scene for one episode (world coordinates; any part may be empty)."""

    poses: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (T+1, 3) x, z, yaw
    collisions: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # (T,) per step
    stopped: bool = False
    shortest: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))  # (K, 2) x, z
    goal_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # view points / goal positions
    candidates: list = field(default_factory=list)  # memory agent: localised candidate centres [x, y, z]
    decisions: list = field(default_factory=list)  # [step, mode, ..., x, z] from the record's trace
    starts: bool = True  # poses[0] is the episode's start (a storey's panel may hold a later part of the path)
    ends: bool = True  # poses[-1] is where the episode ended


def time_colours(n: int) -> np.ndarray:
    """``n`` RGB colours from dark blue (start) to yellow (end): viridis."""
    ramp = np.linspace(0, 255, max(n, 1)).astype(np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(ramp, cv2.COLORMAP_VIRIDIS)[:, 0, ::-1].astype(int)


def draw_episode(img: np.ndarray, view: TopDown, d: EpisodeDrawing, upto: int | None = None,
                 current_goal: tuple[float, float] | None = None) -> None:
    """Draw ``d`` onto ``img`` (steps up to ``upto`` only, for video frames)."""
    for x, _, z in d.goal_points:
        cv2.circle(img, view.px(x, z), max(1, view.scale // 2), VIEW_POINT, -1)
    if len(d.shortest) > 1:
        pts = np.round(view.to_px(d.shortest[:, 0], d.shortest[:, 1])).astype(np.int32)
        cv2.polylines(img, [pts], False, SHORTEST, 1, cv2.LINE_AA)
    for k, c in enumerate(d.candidates):
        u, v = view.px(c[0], c[2])
        cv2.drawMarker(img, (u, v), CANDIDATE, cv2.MARKER_DIAMOND, 12, 2)
        cv2.putText(img, str(k), (u + 7, v - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.4, CANDIDATE, 1, cv2.LINE_AA)
    goals = [(r[0], r[-2], r[-1]) for r in d.decisions if r[-1] is not None]
    for _, x, z in goals:
        if upto is None:
            cv2.drawMarker(img, view.px(x, z), DECISION, cv2.MARKER_TILTED_CROSS, 7, 1)
    poses = d.poses if upto is None else d.poses[:upto + 1]
    if len(poses):
        px = np.round(view.to_px(poses[:, 0], poses[:, 1])).astype(np.int32)
        cols = time_colours(len(d.poses))
        for k in range(1, len(px)):
            cv2.line(img, tuple(px[k - 1]), tuple(px[k]), tuple(int(c) for c in cols[k]), 2, cv2.LINE_AA)
        n = len(poses) - 1
        for k in np.flatnonzero(d.collisions[:n]):
            cv2.circle(img, tuple(px[k + 1]), 3, COLLISION, -1)
        if d.starts:
            _agent(img, view, d.poses[0], START, 6)
        if upto is not None:
            _agent(img, view, poses[-1], (255, 255, 255), 5, outline=(0, 0, 0))
        elif not d.ends:
            pass
        elif d.stopped:
            cv2.drawMarker(img, tuple(px[-1]), STOP_MARK, cv2.MARKER_SQUARE, 10, 2)
        else:
            cv2.drawMarker(img, tuple(px[-1]), STOP_MARK, cv2.MARKER_TILTED_CROSS, 10, 2)
    if current_goal is not None:
        cv2.drawMarker(img, view.px(*current_goal), DECISION, cv2.MARKER_TILTED_CROSS, 12, 2)


def _agent(img, view: TopDown, pose, colour, r: int, outline=None) -> None:
    """A disc with a heading tick (yaw 0 faces -z, i.e. up; yaw grows counter-clockwise)."""
    u, v = view.px(pose[0], pose[1])
    yaw = pose[2]
    tip = (int(round(u - 2 * r * math.sin(yaw))), int(round(v - 2 * r * math.cos(yaw))))
    cv2.line(img, (u, v), tip, outline or colour, 2, cv2.LINE_AA)
    cv2.circle(img, (u, v), r, colour, -1, cv2.LINE_AA)
    if outline is not None:
        cv2.circle(img, (u, v), r, outline, 1, cv2.LINE_AA)


def annotate(img: np.ndarray, view: TopDown) -> None:
    """Scale bar (bottom left) and the north arrow (top right)."""
    h, w = img.shape[:2]
    ppm = view.scale / view.grid.cell_size  # pixels per metre
    metres = next(m for m in (1, 2, 5, 10, 20) if m * ppm >= w / 8 or m == 20)
    x0, y0 = 8, h - 10
    cv2.rectangle(img, (x0 - 3, y0 - 18), (x0 + int(metres * ppm) + 30, y0 + 4), (255, 255, 255), -1)
    cv2.line(img, (x0, y0), (x0 + int(round(metres * ppm)), y0), (0, 0, 0), 2)
    for x in (x0, x0 + int(round(metres * ppm))):
        cv2.line(img, (x, y0 - 4), (x, y0 + 2), (0, 0, 0), 1)
    cv2.putText(img, f"{metres} m", (x0 + int(metres * ppm) + 3, y0), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1,
                cv2.LINE_AA)
    cv2.arrowedLine(img, (w - 14, 30), (w - 14, 10), (0, 0, 0), 2, tipLength=0.4)
    cv2.putText(img, "N", (w - 30, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)


LEGEND = [("navigable", NAVIGABLE, "box"), ("unreachable", UNREACHABLE, "box"), ("obstacle", OBSTACLE, "box"),
          ("explored", EXPLORED, "box"), ("shortest path", SHORTEST, "line"), ("start", START, "disc"),
          ("STOP", STOP_MARK, "square"), ("collision", COLLISION, "disc"), ("candidate", CANDIDATE, "diamond"),
          ("goal driven to", DECISION, "cross"), ("goal view point", VIEW_POINT, "disc")]


def legend(width: int, title: str = "") -> np.ndarray:
    """A band to put under a map: the title, then the symbols and 'north up, path dark -> light in time'."""
    items = LEGEND
    per_row = max(1, width // 130)
    rows = (len(items) + per_row - 1) // per_row
    band = np.full((22 * (rows + 2), width, 3), 255, np.uint8)
    cv2.putText(band, title, (6, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    for k, (name, col, kind) in enumerate(items):
        x, y = 6 + (k % per_row) * 130, 22 * (k // per_row + 1) + 14
        c = (x + 6, y - 4)
        if kind == "box":
            cv2.rectangle(band, (x, y - 10), (x + 12, y + 2), col, -1)
            cv2.rectangle(band, (x, y - 10), (x + 12, y + 2), (90, 90, 90), 1)
        elif kind == "line":
            cv2.line(band, (x, y - 4), (x + 12, y - 4), col, 2)
        elif kind == "disc":
            cv2.circle(band, c, 4, col, -1)
        else:
            marker = {"square": cv2.MARKER_SQUARE, "diamond": cv2.MARKER_DIAMOND,
                      "cross": cv2.MARKER_TILTED_CROSS}[kind]
            cv2.drawMarker(band, c, col, marker, 10, 2)
        cv2.putText(band, name, (x + 17, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    y = 22 * (rows + 1) + 14
    cv2.putText(band, "north (-z, yaw 0) up, +x right; path coloured by time, dark blue (start) -> yellow (end)",
                (6, y), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (60, 60, 60), 1, cv2.LINE_AA)
    return band


def shortest_path(field, start) -> np.ndarray:
    """Steepest descent of a geodesic field's cell values from ``start`` (8-neighbours): (K, 2) x, z."""
    g = field.grid
    vals = field.values
    i, j = (int(v) for v in g.world_to_grid(np.asarray(start, float)))
    h, w = vals.shape
    if not (0 <= i < h and 0 <= j < w) or not np.isfinite(vals[i, j]):
        return np.zeros((0, 2))
    cells = [(i, j)]
    for _ in range(h * w):
        best, bi, bj = vals[i, j], i, j
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if (di or dj) and 0 <= a < h and 0 <= b < w and vals[a, b] < best:
                    best, bi, bj = vals[a, b], a, b
        if (bi, bj) == (i, j):
            break
        i, j = bi, bj
        cells.append((i, j))
    world = g.grid_to_world(np.array(cells))
    pts = world[:, [0, 2]]
    return np.concatenate([[[start[0], start[2]]], pts])
