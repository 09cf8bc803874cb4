"""Layered navigability: every walkable surface of a mesh, joined where the agent can step between them.

A :class:`LayeredNav` models what Habitat's Recast navmesh models and a single-floor
:class:`~navbench.scene.navigability.NavGrid` cannot: storeys, landings, stairs and ramps as one walkable
surface. It is built as Recast builds its heightfield (``rcRasterizeTriangles`` and the filters after it):
every triangle is rasterised into the columns of the NavGrid's xz cell lattice it touches, with its vertical
extent in each cell; the extents of a column merge into solids wherever they overlap or touch, so walls,
slabs and steps composed of touching parts (coincident faces) make one solid, and a wall thinner than a cell
still fills the cells it crosses. A solid's top is walkable if an upward-facing triangle within 45 deg of
vertical reaches within ``max_climb`` of it (or the solid right under it is walkable and within
``max_climb``: a slab's edge over a flight's last tread); with ``agent_height`` of room to the next solid
above it is a *span*. Two spans of neighbouring cells are joined if their heights differ by at most
``max_climb`` (a stair's 0.17 m riser is, a 0.3 m ledge is not) and the room over both overlaps by the
agent's height, so a flight of steps joins the storeys it runs between, and two storeys without one stay
apart.

- Clearance: a span is navigable if its distance along the joined surface to the nearest span missing one
  of its four neighbours (a wall, a ledge, the stairwell's edge) is at least ``agent_radius`` (the same
  half-cell convention as the NavGrid: boundary cell centres lie half a cell inside the edge).
- Geodesics: shortest paths over the navigable spans with 32 directions (every lattice step up to 3 x 2
  cells whose cells in between are navigable and joined), each step as long as its 3-D chord on the
  surface smoothed over a stair's tread (so a flight of steps measures as the ramp through it, as a
  navmesh path over it does). The direction set keeps lattice paths within 1.3% of straight lines.
  A point not connected to the start is unreachable (``inf``).

The single-storey NavGrid stays the engine for one floor; these surfaces serve episodes across storeys.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from pathlib import Path

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from navbench.scene.asset import SceneError
from navbench.scene.navigability import _HORIZONTAL_NY, NavGridConfig, _points, grid_cells, storey_floors
from navbench.scene.pose import vector_length

# Unit lattice steps (row, col): the four orthogonal ones first, then the diagonals.
_UNIT = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)]
# Jacobi iterations of the height smoothing: spreads a riser over ~ +-4 cells (a 0.3 m tread at 5 cm).
_SMOOTH_ITERS = 40


def _directions() -> list[tuple[int, int]]:
    out = []
    for a, b in ((1, 0), (1, 1), (2, 1), (3, 1), (3, 2)):
        for p, q in ((a, b), (b, a)):
            for sp in (1, -1):
                for sq in (1, -1):
                    if (sp * p, sq * q) not in out:
                        out.append((sp * p, sq * q))
    return out


def _unit_path(di: int, dj: int) -> list[int]:
    """Indices into _UNIT of the lattice cells a straight step (di, dj) passes through, in order."""
    n = 64
    cells = []
    for k in range(n + 1):
        t = k / n
        c = (int(math.floor(t * di + 0.5)), int(math.floor(t * dj + 0.5)))
        if not cells or cells[-1] != c:
            cells.append(c)
    return [_UNIT.index((b[0] - a[0], b[1] - a[1])) for a, b in itertools.pairwise(cells)]


def _csr(dst: np.ndarray, wt: np.ndarray, n: int) -> sparse.csr_matrix:
    """(n, n) sparse matrix from a per-row table of targets (-1: none) and weights, built row by row."""
    mask = dst >= 0
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))])
    return sparse.csr_matrix((np.asarray(wt)[mask], dst[mask], indptr), shape=(n, n))


def _joins(cell: np.ndarray, height: np.ndarray, h: int, w: int, max_climb: float,
           ceiling: np.ndarray | None = None, agent_height: float = 0.0) -> np.ndarray:
    """(N, 8) joined neighbour of each span in the directions of ``_UNIT`` (-1: none), spans sorted by cell.
    Orthogonal: the neighbouring cell's span nearest in height, if within ``max_climb`` and (given each span's
    ``ceiling``) the room over both is at least ``agent_height``, as Recast connects spans; diagonal: both
    orthogonal routes round the corner reach the same span."""
    n = len(cell)
    start = np.full(h * w, 0, np.int64)
    count = np.bincount(cell, minlength=h * w)
    start[1:] = np.cumsum(count)[:-1]
    ci, cj = cell // w, cell % w
    nbr = np.full((n, 8), -1, np.int64)
    for d, (di, dj) in enumerate(_UNIT[:4]):
        ni, nj = ci + di, cj + dj
        inside = (ni >= 0) & (ni < h) & (nj >= 0) & (nj < w)
        nc = np.where(inside, ni * w + nj, 0)
        best = np.full(n, np.inf)
        for k in range(int(count.max())):
            t = start[nc] + k
            has = inside & (count[nc] > k)
            other = np.where(has, t, 0)
            dh = np.abs(height[other] - height)
            if ceiling is not None:
                room = np.minimum(ceiling[other], ceiling) - np.maximum(height[other], height)
                has = has & (room >= agent_height - 1e-9)
            better = has & (dh <= max_climb + 1e-9) & (dh < best)
            nbr[better, d] = t[better]
            best[better] = dh[better]
    for d, (di, dj) in enumerate(_UNIT[4:], start=4):
        a, b = _UNIT.index((di, 0)), _UNIT.index((0, dj))
        via_a = np.where(nbr[:, a] >= 0, nbr[np.maximum(nbr[:, a], 0), b], -1)
        via_b = np.where(nbr[:, b] >= 0, nbr[np.maximum(nbr[:, b], 0), a], -1)
        nbr[:, d] = np.where((via_a >= 0) & (via_a == via_b), via_a, -1)
    return nbr


def _lattice(nbr: np.ndarray, passable: np.ndarray, cell: np.ndarray, smooth: np.ndarray, w: int,
             cs: float) -> sparse.csr_matrix:
    """The geodesic steps between ``passable`` spans: the 32 directions of :func:`_directions`, each a straight
    lattice step whose cells in between are passable and joined (``nbr``), as long as its 3-D chord on the
    ``smooth`` surface. Each direction's (source, target) pairs are int32, scattered into the rows of the CSR
    arrays in direction order (no dense N x 32 table, no sort); the step lengths are computed last."""
    n = len(cell)
    nav_nbr = np.where(passable[:, None] & (nbr >= 0), nbr, -1)
    nav_nbr[nav_nbr >= 0] = np.where(passable[nav_nbr[nav_nbr >= 0]], nav_nbr[nav_nbr >= 0], -1)
    parts = []
    nav_idx = np.flatnonzero(passable)
    for di, dj in _directions():
        cur = nav_idx
        for d in _unit_path(di, dj):
            cur = np.where(cur >= 0, nav_nbr[np.maximum(cur, 0), d], -1)
        ok = cur >= 0
        parts.append((nav_idx[ok].astype(np.int32), cur[ok].astype(np.int32)))
    del nav_nbr
    counts = np.zeros(n, np.int64)
    for src, _ in parts:
        counts[src] += 1  # a direction has each source once
    nnz = int(counts.sum())
    index_dtype = np.int32 if nnz < np.iinfo(np.int32).max else np.int64
    indptr = np.zeros(n + 1, index_dtype)
    indptr[1:] = np.cumsum(counts)
    fill = indptr[:-1].copy()
    indices = np.empty(nnz, np.int32)
    for src, t in parts:
        indices[fill[src]] = t
        fill[src] += 1
    del parts, fill, counts
    src = np.repeat(np.arange(n, dtype=np.int32), np.diff(indptr))
    return sparse.csr_matrix((_step_lengths(cell, smooth, w, cs, src, indices), indices, indptr), shape=(n, n))


def _step_lengths(cell: np.ndarray, smooth: np.ndarray, w: int, cs: float, src: np.ndarray,
                  dst: np.ndarray, chunk: int = 1 << 20) -> np.ndarray:
    """Length of each lattice step ``src`` -> ``dst`` (span indices): its 3-D chord on the smoothed surface,
    sqrt((cs di)^2 + (cs dj)^2 + dh^2), in chunks of steps (bounded temporaries). The builder and the cache
    loader both compute the weights here, so a loaded graph is the built one."""
    row, col = (cell // w).astype(np.int32), (cell % w).astype(np.int32)
    out = np.empty(len(src))
    for k in range(0, len(src), chunk):
        s, t = src[k:k + chunk], dst[k:k + chunk]
        di, dj = (row[t] - row[s]).astype(np.float64), (col[t] - col[s]).astype(np.float64)
        out[k:k + chunk] = np.sqrt((cs * di) ** 2 + (cs * dj) ** 2 + (smooth[t] - smooth[s]) ** 2)
    return out


def _clip_extent(tri: np.ndarray, xa: np.ndarray, xb: np.ndarray, za: np.ndarray, zb: np.ndarray,
                 eps: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """(min y, max y) of each triangle ``tri`` ((M, 3, 3)) clipped to the vertical prism over its cell's square
    [xa, xb] x [za, zb] (Recast's ``rasterizeTri`` divides the polygon cell by cell for the same extent);
    (inf, -inf) where the triangle misses the square. y is linear on the triangle, so its extremes lie on the
    clipped polygon's vertices: the triangle's own corners inside the square, its edges' crossings of the
    square's sides, and the square's corners inside the triangle (seen from above)."""
    x, y, z = tri[:, :, 0], tri[:, :, 1], tri[:, :, 2]
    lo = np.full(len(tri), np.inf)
    hi = np.full(len(tri), -np.inf)

    def take(mask, val):
        nonlocal lo, hi
        lo = np.where(mask, np.minimum(lo, val), lo)
        hi = np.where(mask, np.maximum(hi, val), hi)

    xa_, xb_, za_, zb_ = xa[:, None], xb[:, None], za[:, None], zb[:, None]
    take_in = (x >= xa_ - eps) & (x <= xb_ + eps) & (z >= za_ - eps) & (z <= zb_ + eps)
    for k in range(3):
        take(take_in[:, k], y[:, k])
    for k in range(3):  # edge k -> k + 1 against the square's four sides
        p, q = tri[:, k], tri[:, (k + 1) % 3]
        d = q - p
        for axis, other, lines, (oa, ob) in ((0, 2, (xa, xb), (za, zb)), (2, 0, (za, zb), (xa, xb))):
            dx = d[:, axis]
            ok_dir = np.abs(dx) > 1e-12
            safe = np.where(ok_dir, dx, 1.0)
            for line in lines:
                t = (line - p[:, axis]) / safe
                o = p[:, other] + t * d[:, other]
                take(ok_dir & (t >= -eps) & (t <= 1 + eps) & (o >= oa - eps) & (o <= ob + eps), p[:, 1] + t * d[:, 1])
    # the square's corners inside the triangle's footprint (a vertical triangle has none: its footprint is a line)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    det = e1[:, 0] * e2[:, 2] - e1[:, 2] * e2[:, 0]
    flat = np.abs(det) > 1e-12
    sdet = np.where(flat, det, 1.0)
    for cx, cz in ((xa, za), (xa, zb), (xb, za), (xb, zb)):
        rx, rz = cx - tri[:, 0, 0], cz - tri[:, 0, 2]
        u = (rx * e2[:, 2] - rz * e2[:, 0]) / sdet
        v = (e1[:, 0] * rz - e1[:, 2] * rx) / sdet
        take(flat & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps), tri[:, 0, 1] + u * e1[:, 1] + v * e2[:, 1])
    return lo, hi


def _rasterise(mesh: trimesh.Trimesh, origin: np.ndarray, cs: float, h: int, w: int, walkable_ny: float,
               chunk: int = 1 << 18) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Recast's heightfield (``rcRasterizeTriangles``): every triangle's vertical extent in every cell its
    footprint touches, as (cell, bottom, top, walkable) per triangle and cell. A triangle is walkable if it
    faces up within the slope limit (``normal.y >= walkable_ny``, signed: a slab's underside is not a floor)."""
    tris = np.asarray(mesh.vertices, np.float64)[np.asarray(mesh.faces)]
    walk = np.asarray(mesh.face_normals)[:, 1] >= walkable_ny
    fx, fz = tris[:, :, 0], tris[:, :, 2]
    # cell j spans x in [origin + (j - 1/2) cs, origin + (j + 1/2) cs]
    j0 = np.clip(np.floor((fx.min(axis=1) - origin[0]) / cs + 0.5 - 1e-9), 0, w - 1).astype(np.int64)
    j1 = np.clip(np.floor((fx.max(axis=1) - origin[0]) / cs + 0.5 + 1e-9), 0, w - 1).astype(np.int64)
    i0 = np.clip(np.floor((fz.min(axis=1) - origin[1]) / cs + 0.5 - 1e-9), 0, h - 1).astype(np.int64)
    i1 = np.clip(np.floor((fz.max(axis=1) - origin[1]) / cs + 0.5 + 1e-9), 0, h - 1).astype(np.int64)
    nj, ni = j1 - j0 + 1, i1 - i0 + 1
    count = nj * ni
    cells, bots, tops, walks = [], [], [], []
    cum = np.cumsum(count)
    start = 0
    while start < len(tris):  # triangles in groups of about ``chunk`` (triangle, cell) pairs
        end = max(int(np.searchsorted(cum, cum[start] - count[start] + chunk, side="right")), start + 1)
        sl = slice(start, end)
        start = end
        c = count[sl]
        t = np.repeat(np.arange(sl.start, sl.stop), c)
        k = np.arange(len(t)) - np.repeat(np.cumsum(c) - c, c)
        j = j0[t] + k % nj[t]
        i = i0[t] + k // nj[t]
        cx, cz = origin[0] + j * cs, origin[1] + i * cs
        # A walkable triangle counts in a cell it overlaps with some area (Recast drops a clipped polygon of
        # under three vertices), so a tread ending on a cell's edge does not raise the cell beside it; any
        # other triangle counts in every cell it touches, so a wall on a cell edge blocks both sides.
        e = np.where(walk[t], 1e-7, 0.0)
        lo, hi = _clip_extent(tris[t], cx - cs / 2 + e, cx + cs / 2 - e, cz - cs / 2 + e, cz + cs / 2 - e)
        hit = lo <= hi
        cells.append(i[hit] * w + j[hit])
        bots.append(lo[hit])
        tops.append(hi[hit])
        walks.append(walk[t[hit]])
    return (np.concatenate(cells), np.concatenate(bots), np.concatenate(tops), np.concatenate(walks))


def _solids(cell: np.ndarray, bot: np.ndarray, top: np.ndarray, walk: np.ndarray,
            merge_walkable: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The column of each cell as merged solid intervals, bottom-up (Recast's ``rcAddSpan``): extents that
    overlap or touch merge, so coincident and stacked faces make one solid whichever of them a query sees.
    A merged interval's top is walkable if a walkable triangle reaches within ``merge_walkable`` of it (Recast's
    flag-merge threshold, its walkable climb). Returns (cell, bottom, top, walkable) per merged interval."""
    order = np.lexsort((bot, cell))
    cell, bot, top, walk = cell[order], bot[order], top[order], walk[order]
    # integer micrometres: the running maximum of tops within a cell is exact with the cell index as an offset
    q = 1e6
    ti = np.round(top * q).astype(np.int64)
    bi = np.round(bot * q).astype(np.int64)
    span = int(max(ti.max(), bi.max()) - min(ti.min(), bi.min())) + 2
    base = min(ti.min(), bi.min())
    key = cell.astype(np.int64) * span
    run = np.maximum.accumulate(key + (ti - base))
    new = np.ones(len(cell), bool)
    new[1:] = (cell[1:] != cell[:-1]) | (key[1:] + (bi[1:] - base) > run[:-1])
    grp = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    m_cell = cell[starts]
    m_bot = bot[starts]
    m_top = np.maximum.reduceat(top, starts)
    near = walk & (top >= m_top[grp] - merge_walkable - 1e-9)
    m_walk = np.logical_or.reduceat(near, starts)
    return m_cell, m_bot, m_top, m_walk


class LayeredNav:
    """Walkable spans of every level of a mesh and the surface joining them (see :meth:`from_mesh`)."""

    def __init__(self, origin, cell_size: float, shape: tuple[int, int], cell: np.ndarray, height: np.ndarray,
                 smooth: np.ndarray, navigable: np.ndarray, graph: sparse.csr_matrix, config: NavGridConfig):
        self.origin = np.asarray(origin, float).reshape(2)
        self.cell_size = float(cell_size)
        self.shape = shape
        self.cell = cell  # (N,) flat cell index (row * W + col) of each span
        self.height = height  # (N,) surface height of each span
        self.smooth = smooth  # (N,) height smoothed over treads (the surface geodesics are measured on)
        self.navigable = navigable  # (N,) bool
        self.graph = graph  # (N, N) step lengths between navigable spans
        self.config = config
        self.num_components, self.component = csgraph.connected_components(graph, directed=False)
        self.component = np.where(navigable, self.component, -1)
        self._count = np.bincount(cell, minlength=shape[0] * shape[1])
        self._start = np.concatenate([[0], np.cumsum(self._count)[:-1]])  # spans are sorted by cell
        idx = np.flatnonzero(navigable)
        self._nav = idx
        xz = self.xz(cell[idx])
        # Vertical offsets weigh 4x: a point snaps to the surface under it before one beside it.
        self._tree = cKDTree(np.column_stack([xz, 4.0 * height[idx]])) if len(idx) else None

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh, config: NavGridConfig = NavGridConfig()) -> LayeredNav:
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise SceneError(f"navigability needs a non-empty trimesh.Trimesh, got {type(mesh).__name__}")
        cs = config.cell_size
        lo, hi = mesh.bounds
        w, h, origin, xs, zs = grid_cells(lo, hi, cs)

        # 1. spans, as Recast's heightfield: every triangle rasterised into the columns it touches, the
        # columns merged into solid intervals; a walkable top with agent_height of room to the next solid above
        # is a span (rcRasterizeTriangles, rcFilterWalkableLowHeightSpans)
        m_cell, m_bot, m_top, m_walk = _solids(*_rasterise(mesh, origin, cs, h, w, _HORIZONTAL_NY), config.max_climb)
        same = m_cell[1:] == m_cell[:-1]
        # a solid whose top is within max_climb over a walkable one right below it is walkable too (a slab's edge
        # over a flight's last tread, a kerb: rcFilterLowHangingWalkableObstacles)
        m_walk[1:] |= same & m_walk[:-1] & (m_top[1:] - m_top[:-1] <= config.max_climb + 1e-9)
        ceiling = np.full(len(m_cell), np.inf)
        ceiling[:-1][same] = m_bot[1:][same]
        ok = m_walk & (ceiling - m_top >= config.agent_height)
        cell, height, ceiling = m_cell[ok], m_top[ok], ceiling[ok]
        del m_cell, m_bot, m_top, m_walk, same, ok
        n = len(cell)
        if n == 0:
            raise SceneError(f"mesh has no walkable surface with {config.agent_height} m headroom")

        # 2. joins between spans of neighbouring cells (orthogonal: |dh| <= max_climb; diagonal: both
        # orthogonal routes round the corner reach the same span)
        nbr = _joins(cell, height, h, w, config.max_climb, ceiling, config.agent_height)

        # 3. clearance along the surface from the spans missing an orthogonal neighbour
        unit_w = np.array([cs * math.hypot(di, dj) for di, dj in _UNIT])
        unit = _csr(nbr, np.broadcast_to(unit_w, nbr.shape), n)
        boundary = np.flatnonzero((nbr[:, :4] < 0).any(axis=1))
        if len(boundary):
            dist = csgraph.dijkstra(unit, indices=boundary, min_only=True)
        else:
            dist = np.full(n, np.inf)
        navigable = dist + 0.5 * cs >= config.agent_radius - 0.5 * cs - 1e-9
        # only the passages Habitat's navmesh admits, as NavGrid._navmesh_topology: within k - 1 cells of
        # the spans Recast's erosion (k = ceil(radius / cs) voxels from the edge) keeps
        k = int(math.ceil(config.agent_radius / cs - 1e-9))
        core = np.flatnonzero(dist >= k * cs - 1e-9)
        if len(core):
            navigable &= csgraph.dijkstra(unit, indices=core, min_only=True) <= (k - 1) * cs + 1e-9
        else:
            navigable[:] = False

        # 4. heights smoothed over the joined surface (a flight of steps becomes the ramp through it)
        adj = _csr(nbr[:, :4], np.ones((n, 4)), n)  # orthogonal joins
        deg = np.asarray(adj.sum(axis=1)).ravel()
        smooth = height.copy()
        for _ in range(_SMOOTH_ITERS):
            smooth = (smooth + adj @ smooth) / (1.0 + deg)

        # 5. geodesic steps: 32 directions over navigable spans, through navigable joined cells only
        del unit, adj
        graph = _lattice(nbr, navigable, cell, smooth, w, cs)
        del nbr
        return cls(origin, cs, (h, w), cell, height, smooth, navigable, graph, config)

    # ------------------------------------------------------------------ persistence

    def save(self, path: str | Path) -> None:
        """Write the surfaces to an ``.npz`` file of plain arrays: the graph as its CSR structure (the step
        lengths follow from the spans and are recomputed on loading, which keeps the file small)."""
        g = self.graph
        np.savez_compressed(
            Path(path), origin=self.origin, cell_size=np.float64(self.cell_size), shape=np.array(self.shape, np.int64),
            cell=self.cell, height=self.height, smooth=self.smooth, navigable=self.navigable,
            graph_indices=g.indices, graph_indptr=g.indptr,
            config=np.array(json.dumps(dataclasses.asdict(self.config))))

    @classmethod
    def load(cls, path: str | Path) -> LayeredNav:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as d:
                config = NavGridConfig(**json.loads(str(d["config"])))
                cell, smooth, indices, indptr = d["cell"], d["smooth"], d["graph_indices"], d["graph_indptr"]
                n = len(cell)
                h, w = (int(v) for v in d["shape"])
                if len(indptr) != n + 1 or indptr[-1] != len(indices) or (len(indices) and indices.max() >= n):
                    raise ValueError("graph arrays do not match the spans")
                if {len(d[k]) for k in ("height", "smooth", "navigable")} != {n} or (n and cell.max() >= h * w):
                    raise ValueError("span arrays do not match each other or the lattice")
                src = np.repeat(np.arange(n, dtype=np.int32), np.diff(indptr))
                lengths = _step_lengths(cell, smooth, w, float(d["cell_size"]), src, indices)
                graph = sparse.csr_matrix((lengths, indices, indptr), shape=(n, n))
                return cls(d["origin"], float(d["cell_size"]), (h, w), cell, d["height"], smooth,
                           d["navigable"].astype(bool), graph, config)
        except FileNotFoundError:
            raise SceneError(f"{path}: layered navigability file not found") from None
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            raise SceneError(f"{path}: corrupt layered navigability ({type(exc).__name__}: {exc})") from None

    # ------------------------------------------------------------------ queries

    def xz(self, cells) -> np.ndarray:
        """World (x, z) of the centres of flat cell indices ((N,) -> (N, 2), a scalar -> (2,))."""
        cells = np.asarray(cells)
        w = self.shape[1]
        return np.stack([self.origin[0] + (cells % w) * self.cell_size,
                         self.origin[1] + (cells // w) * self.cell_size], axis=-1)

    def _cell_ij(self, x: float, z: float) -> tuple[int, int]:
        """(row, column) of the cell holding (x, z). Coordinates are rounded to a millionth of a cell first: 0.25 m
        steps and 30 deg turns land exactly on cell edges, and a point the env and an agent compute with
        different rounding must fall in one cell for both."""
        return (int(math.floor(round((z - self.origin[1]) / self.cell_size, 6) + 0.5)),
                int(math.floor(round((x - self.origin[0]) / self.cell_size, 6) + 0.5)))

    def span_of(self, p, max_dist: float | None = None) -> int:
        """The navigable span under ``p`` (xyz), or the nearest one within ``max_dist`` metres in xz (default
        ``config.max_goal_snap``) whose height is within half the agent's height of ``p``'s; -1 if none."""
        p = _points(p, "point")
        if self._tree is None:
            return -1
        limit = self.config.max_goal_snap if max_dist is None else float(max_dist)
        i, j = self._cell_ij(float(p[0]), float(p[2]))
        if 0 <= i < self.shape[0] and 0 <= j < self.shape[1]:
            c = i * self.shape[1] + j
            own = np.arange(self._start[c], self._start[c] + self._count[c])
            own = own[self.navigable[own] & (np.abs(self.height[own] - p[1]) <= self.config.agent_height / 2)]
            if len(own):
                return int(own[np.argmin(np.abs(self.height[own] - p[1]))])
        k = min(64, len(self._nav))
        _, idx = self._tree.query([p[0], p[2], 4.0 * p[1]], k=k)
        for i in np.atleast_1d(idx):
            s = int(self._nav[i])
            xz = self.xz(self.cell[s])
            if abs(self.height[s] - p[1]) <= self.config.agent_height / 2 and \
                    math.hypot(xz[0] - p[0], xz[1] - p[2]) <= limit + 0.75 * self.cell_size:
                return s
        return -1

    def position(self, span: int) -> np.ndarray:
        xz = self.xz(self.cell[span])
        return np.array([xz[0], self.height[span], xz[1]])

    def connected(self, a, b) -> bool:
        """Whether points ``a`` and ``b`` stand on one joined walkable surface."""
        sa, sb = self.span_of(a), self.span_of(b)
        return sa >= 0 and sb >= 0 and self.component[sa] == self.component[sb]

    def reaches_any(self, start, points) -> bool:
        """Whether any of ``points`` ((N, 3)) stands on the surface ``start`` stands on."""
        s = self.span_of(start)
        if s < 0:
            return False
        comp = self.component[s]
        return any(t >= 0 and self.component[t] == comp for t in (self.span_of(p) for p in _points(points, "points")
                                                                 .reshape(-1, 3)))

    def distances(self, goals) -> np.ndarray:
        """Geodesic distance (m) from every span to the nearest of ``goals`` ((3,) or (N, 3)); inf where none
        is reachable. A goal counts from its own point: its span starts at the straight distance to it (a
        goal off the navigable surface counts from its snapped span, with nothing added)."""
        g = _points(goals, "goals").reshape(-1, 3)
        spans = np.array([self.span_of(p) for p in g], np.int64)
        keep = spans >= 0
        n = len(self.cell)
        if not keep.any():
            return np.full(n, np.inf)
        spans, g = spans[keep], g[keep]
        xz = self.xz(self.cell[spans])
        on = np.hypot(xz[:, 0] - g[:, 0], xz[:, 1] - g[:, 1]) <= self.cell_size  # the goal's own cell
        offset = np.where(on, np.hypot(xz[:, 0] - g[:, 0], xz[:, 1] - g[:, 1]), 0.0)
        # A virtual source joined to each goal's span by its offset (Dijkstra's weights must be > 0).
        src = sparse.csr_matrix((np.maximum(offset, 1e-12), (np.full(len(spans), n, np.int64), spans)),
                                shape=(n + 1, n + 1))
        graph = sparse.bmat([[self.graph, None], [None, sparse.csr_matrix((1, 1))]], format="csr") + src
        return csgraph.dijkstra(graph, indices=n, directed=True)[:n]

    def geodesic_distance(self, start, goals) -> float:
        """Shortest path length on the walkable surface from ``start`` to the nearest of ``goals``; ``inf`` if
        no goal is on the start's surface component. Measured between span centres; the start's own
        half-cell offset is bridged by a straight segment to the best of its span's joined neighbours."""
        s = self.span_of(start)
        if s < 0:
            return math.inf
        d = self.distances(goals)
        p = _points(start, "start")
        best = d[s] + vector_length(self.position(s)[[0, 2]] - p[[0, 2]])
        row = self.graph.getrow(s)
        for t in row.indices:
            q = self.position(t)
            best = min(best, d[t] + math.hypot(q[0] - p[0], q[2] - p[2], self.smooth[t] - self.smooth[s]))
        return float(best)

    def levels(self) -> np.ndarray:
        """Distinct heights (to 5 cm) of the navigable spans, bottom-up: the storeys, landings and treads."""
        return np.unique(np.round(self.height[self.navigable] / 0.05) * 0.05)

    def storeys(self) -> np.ndarray:
        """Floor heights of the storeys, bottom-up: the navigable spans' heights grouped into levels by the
        grid's rule (:func:`~navbench.scene.navigability.storey_floors`), the levels holding at least 5% of the
        largest one's spans, each level's median. Treads, landings, a ramp's slope and furniture tops hold too
        few spans to be a storey."""
        return storey_floors(self.height[self.navigable], self.config)

    def storey_spans(self) -> np.ndarray:
        """Navigable spans standing on a storey's floor (within half ``max_climb`` of one of :meth:`storeys`)."""
        floors = self.storeys()
        idx = np.flatnonzero(self.navigable)
        if len(floors) == 0:
            return idx
        near = np.abs(self.height[idx][:, None] - floors[None, :]).min(axis=1) <= self.config.max_climb / 2
        return idx[near]

    def walkable(self) -> np.ndarray:
        """Navigable spans joined to a storey's floor (its stairs and ramps included): the surfaces an agent can
        be on. A furniture top or a ledge nothing joins to a floor is navigable but no place to walk."""
        comps = np.unique(self.component[self.storey_spans()])
        return np.flatnonzero(self.navigable & np.isin(self.component, comps))

    def storey_band(self, y: float) -> tuple[float, float]:
        """(lowest, highest) surface height on the storey a point at height ``y`` stands on: that storey's floor
        is the highest at most ``max_climb`` above ``y`` (else the lowest); the band runs from half the agent's
        height below it to ``max_climb`` below the next floor more than the agent's height up (the NavGrid's
        storey test, :meth:`~navbench.scene.navigability.NavGrid.on_storey`, on the layered surfaces)."""
        floors = self.storeys()
        if len(floors) == 0:
            return -math.inf, math.inf
        below = floors[floors <= y + self.config.max_climb]
        floor = float(below.max()) if len(below) else float(floors.min())
        above = floors[floors > floor + self.config.agent_height]
        top = float(above.min()) - self.config.max_climb if len(above) else math.inf
        return floor - self.config.agent_height / 2, top

    # ------------------------------------------------------------------ the env's interface (NavGrid's)

    def is_navigable(self, p) -> bool:
        """Whether ``p`` stands on a navigable span of its own cell (within half the agent's height)."""
        return self.span_of(p, max_dist=0.0) >= 0

    def snap_point(self, p, max_dist: float | None = None) -> np.ndarray:
        """The navigable span centre ``span_of`` finds for ``p`` (its surface height as y); NaN if none."""
        s = self.span_of(p, math.inf if max_dist is None else max_dist)
        return self.position(s) if s >= 0 else np.full(3, np.nan)

    def distance_field(self, goals) -> LayeredField:
        g = _points(goals, "goals").reshape(-1, 3)
        key = np.round(g * 1000.0).astype(np.int64).tobytes()
        cache = self.__dict__.setdefault("_fields", {})
        if key not in cache:
            if len(cache) >= self.config.field_cache_size:
                cache.pop(next(iter(cache)))
            cache[key] = LayeredField(self, g)
        return cache[key]

    def _step_span(self, span: int, x: float, z: float) -> int:
        """The navigable span of the cell at (x, z) the agent on ``span`` can step onto (-1: none)."""
        i, j = self._cell_ij(x, z)
        if not (0 <= i < self.shape[0] and 0 <= j < self.shape[1]):
            return -1
        c = i * self.shape[1] + j
        if c == self.cell[span]:
            return span
        own = np.arange(self._start[c], self._start[c] + self._count[c])
        dh = np.abs(self.height[own] - self.height[span])
        ok = self.navigable[own] & (dh <= self.config.max_climb + 1e-9)
        return int(own[ok][np.argmin(dh[ok])]) if ok.any() else -1

    def _straight(self, span: int, x0: float, z0: float, x1: float, z1: float) -> tuple[int, float, float, bool]:
        length = math.hypot(x1 - x0, z1 - z0)
        n = max(1, int(math.ceil(length / (0.25 * self.cell_size))))
        for k in range(1, n + 1):
            t = k / n
            nxt = self._step_span(span, x0 + t * (x1 - x0), z0 + t * (z1 - z0))
            if nxt < 0:
                t0 = (k - 1) / n
                return span, x0 + t0 * (x1 - x0), z0 + t0 * (z1 - z0), True
            span = nxt
        return span, x1, z1, False

    def try_step(self, position, target, sliding: bool = False) -> tuple[np.ndarray, bool]:
        """Move from ``position`` towards ``target`` (xz) over the joined surface, up and down steps within
        ``max_climb``; returns (new position, its y the surface height there, collided). With sliding the
        rest of a blocked step is re-tried along each axis; the candidate that gets furthest is taken."""
        p, q = _points(position, "position"), _points(target, "target")
        span = self.span_of(p, max_dist=self.cell_size)
        if span < 0:
            return p.copy(), True
        span, x, z, collided = self._move(span, float(p[0]), float(p[2]), float(q[0]), float(q[2]), sliding)
        return np.array([x, self.height[span], z]), collided

    def _move(self, span: int, x0: float, z0: float, x1: float, z1: float,
              sliding: bool) -> tuple[int, float, float, bool]:
        span, x, z, collided = self._straight(span, x0, z0, x1, z1)
        if collided and sliding:
            best, best_d = (span, x, z), 0.0
            for dx, dz in ((x1 - x, 0.0), (0.0, z1 - z)):
                s2, x2, z2, _ = self._straight(span, x, z, x + dx, z + dz)
                d = math.hypot(x2 - x, z2 - z)
                if d > best_d + 1e-12:
                    best, best_d = (s2, x2, z2), d
            span, x, z = best
        return span, x, z, collided


class LayeredField:
    """Geodesic distance over a :class:`LayeredNav` to the nearest of a goal set (``inf`` off its surfaces).

    Values are shortest lattice paths between span centres (see the module docstring); a query point is
    joined to the best of its span's lattice neighbours by a straight segment, and within twice the agent's
    radius of a goal on its own surface (joined, and within a step's height) the straight xz distance to the
    goal is used, as the NavGrid's field does near its goals, so success is decided exactly.
    """

    def __init__(self, nav: LayeredNav, goals: np.ndarray):
        self.nav = nav
        spans = np.array([nav.span_of(g) for g in goals], np.int64)
        keep = spans >= 0
        self.goals = goals[keep].reshape(-1, 3)  # goals on a navigable surface (or within snapping of one)
        self._goal_spans = spans[keep]
        self.values = nav.distances(goals) if keep.any() else np.full(len(nav.cell), np.inf)

    def distance(self, p) -> float:
        p = _points(p, "point")
        return self.distance_on(self.nav.span_of(p, max_dist=self.nav.cell_size), p)

    def distance_on(self, s: int, p: np.ndarray) -> float:
        """Distance from point ``p`` standing on span ``s`` (inf if ``s`` < 0)."""
        nav = self.nav
        if s < 0:
            return math.inf
        row = nav.graph.indices[nav.graph.indptr[s]:nav.graph.indptr[s + 1]]
        cand = np.concatenate([[s], row])
        xz = nav.xz(nav.cell[cand])
        legs = np.sqrt((xz[:, 0] - p[0]) ** 2 + (xz[:, 1] - p[2]) ** 2 + (nav.smooth[cand] - nav.smooth[s]) ** 2)
        best = float(np.min(self.values[cand] + legs))
        if math.isfinite(best) and len(self.goals):
            # Two navigable points this close have nothing between them (an obstacle and the clearance on
            # either side of it span more), so the straight distance is the geodesic one.
            near = np.linalg.norm(self.goals[:, [0, 2]] - p[[0, 2]], axis=1) <= 2 * nav.config.agent_radius
            # On the agent's own surface: joined to it, and not a storey above or below the same xz.
            comp = (nav.component[self._goal_spans] == nav.component[s]) & \
                (np.abs(nav.height[self._goal_spans] - nav.height[s]) <= nav.config.max_climb)
            if (near & comp).any():
                g = self.goals[near & comp]
                best = float(np.min(np.hypot(g[:, 0] - p[0], g[:, 2] - p[2])))
        return best


class LayerView:
    """A :class:`LayeredNav` seen through the xz interface the geodesic follower plans with.

    The follower knows the agent's xz (GPS), not which surface it stands on; the view keeps that: the agent's
    span is the one of its cell nearest in height to where it last stood (storeys over one another are at
    least the agent's height apart, a step at most ``max_climb``), and every position the follower simulates
    remembers the span it reached, so look-ahead over stairs follows the surface.
    """

    def __init__(self, nav: LayeredNav, start):
        self.nav = nav
        self.config = nav.config
        self.cell_size = nav.cell_size
        self._y = float(_points(start, "start")[1])
        self._at: dict[tuple[float, float], int] = {}

    def track(self, position) -> None:
        """Take in the agent's reported position (its y is ignored): the span under it becomes the context."""
        p = _points(position, "position")
        s = self._nearest(float(p[0]), float(p[2]))
        if s >= 0:
            self._y = float(self.nav.height[s])
        self._at.clear()

    @property
    def surface_height(self) -> float:
        """Height of the surface the agent stood on when last tracked (its start's, before that)."""
        return self._y

    def _nearest(self, x: float, z: float) -> int:
        return self.nav.span_of((x, self._y, z), max_dist=self.nav.cell_size)

    def locate(self, x: float, z: float) -> int:
        s = self._at.get((x, z))
        return self._nearest(x, z) if s is None else s

    def _straight(self, x: float, z: float, tx: float, tz: float) -> tuple[float, float, bool]:
        s = self.locate(x, z)
        if s < 0:
            return x, z, True
        s, x1, z1, stopped = self.nav._straight(s, x, z, tx, tz)
        self._at[(x1, z1)] = s
        return x1, z1, stopped

    def try_step(self, position, target, sliding: bool = False) -> tuple[np.ndarray, bool]:
        p, q = _points(position, "position"), _points(target, "target")
        s = self.locate(float(p[0]), float(p[2]))
        if s < 0:
            return p.copy(), True
        s, x, z, collided = self.nav._move(s, float(p[0]), float(p[2]), float(q[0]), float(q[2]), sliding)
        self._at[(x, z)] = s
        return np.array([x, self.nav.height[s], z]), collided

    def distance_field(self, goals, margin: float = 0.0) -> _FieldView:
        """The layered field of ``goals`` seen in xz (``margin`` is not supported on layered surfaces: 0)."""
        return _FieldView(self, self.nav.distance_field(goals))


class _FieldView:
    def __init__(self, view: LayerView, field: LayeredField):
        self._view, self._field = view, field
        self.goals = field.goals

    def _distance_xz(self, x: float, z: float) -> float:
        s = self._view.locate(x, z)
        if s < 0:
            return math.inf
        return self._field.distance_on(s, np.array([x, self._view.nav.height[s], z]))

    def distance(self, p) -> float:
        p = _points(p, "point")
        return self._distance_xz(float(p[0]), float(p[2]))
