"""ObjectNav view points: every navigable grid cell near an object from which the object is seen.

Habitat's ObjectNav view points are dense navigable positions around each goal object from which a
rendered view shows it. Here a cell qualifies when it lies within ``max_distance`` (1.0 m) of the
object's bounding box in the floor plane and, with the camera at agent height turned to face the
object, at least ``min_visible_fraction`` of points sampled on the object's surface are inside the
field of view and not hidden by other geometry. Visibility is decided by casting one ray per sample
point through the scene mesh (Embree): it is the same test a rendered instance-id image would make
at the samples, far cheaper than rendering every cell. The stored ``iou`` is that
visible fraction.

On a multi-storey scene (a :class:`~navbench.scene.layers.LayeredNav`) the candidates are the walkable
spans of every storey, stairs and ramps (not a furniture top nothing joins to a floor), each at its own
surface height, and a span counts only on the
object's storey (:meth:`~navbench.scene.layers.LayeredNav.storey_band` of the object's bottom: the band
the NavGrid's storey test keeps). A view point of an object upstairs therefore lies on the upper storey's
surface (or the top of the flight leading to it), never on the floor below, whatever the rays would see
through an opening; one of an object downstairs never lies on the floor above it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from navbench.scene.annotations import ObjectAnnotation
from navbench.scene.asset import SceneAsset
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import quat_from_yaw


@dataclass(frozen=True)
class ViewPointConfig:
    max_distance: float = 1.0  # m from the object's bounding box (xz)
    camera_height: float = 0.88
    hfov_deg: float = 79.0
    vfov_deg: float = 79.0  # square 224x224 sensor
    surface_samples: int = 48
    min_visible_fraction: float = 0.1


class ViewPointFinder:
    """Computes view points for objects of one scene (one ray intersector, reused)."""

    def __init__(self, asset: SceneAsset, navgrid: NavGrid | LayeredNav, config: ViewPointConfig = ViewPointConfig()):
        self.asset, self.navgrid, self.config = asset, navgrid, config
        self._rays = trimesh.ray.ray_pyembree.RayMeshIntersector(asset.mesh) \
            if trimesh.ray.has_embree else asset.mesh.ray
        if isinstance(navgrid, LayeredNav):
            spans = navgrid.walkable()
            xz = navgrid.xz(navgrid.cell[spans])
            self._cells = np.column_stack([xz[:, 0], navgrid.height[spans], xz[:, 1]])  # (N, 3) on their surfaces
        else:
            ii, jj = np.nonzero(navgrid.navigable)
            self._cells = navgrid.grid_to_world(np.stack([ii, jj], axis=1))  # (N, 3) at floor height

    def surface_points(self, obj: ObjectAnnotation) -> np.ndarray:
        faces = np.nonzero(self.asset.face_ids == obj.id)[0]
        sub = self.asset.mesh.submesh([faces], append=True)
        pts, _ = trimesh.sample.sample_surface(sub, self.config.surface_samples, seed=obj.id)
        return np.asarray(pts, np.float64)

    def find(self, obj: ObjectAnnotation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """-> (positions (M,3), rotations xyzw (M,4) facing the object, visible fractions (M,))."""
        c = self.config
        lo, hi = np.asarray(obj.aabb_min), np.asarray(obj.aabb_max)
        # xz distance from each navigable cell to the object's footprint rectangle
        dx = np.maximum(np.maximum(lo[0] - self._cells[:, 0], self._cells[:, 0] - hi[0]), 0.0)
        dz = np.maximum(np.maximum(lo[2] - self._cells[:, 2], self._cells[:, 2] - hi[2]), 0.0)
        near = np.hypot(dx, dz) <= c.max_distance
        if isinstance(self.navgrid, LayeredNav):  # the object's own storey (module docstring)
            low, high = self.navgrid.storey_band(float(lo[1]))
            near &= (self._cells[:, 1] >= low) & (self._cells[:, 1] < high)
        cand = self._cells[near]
        empty = (np.zeros((0, 3)), np.zeros((0, 4)), np.zeros(0))
        if len(cand) == 0:
            return empty
        pts = self.surface_points(obj)
        cams = cand + np.array([0.0, c.camera_height, 0.0])
        centre = obj.center
        yaw = np.arctan2(-(centre[0] - cams[:, 0]), -(centre[2] - cams[:, 2]))  # face the object's centre

        # Field of view: express every sample point in each candidate's camera frame.
        d = pts[None, :, :] - cams[:, None, :]                      # (M, P, 3)
        cy, sy = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        x_cam = cy * d[..., 0] - sy * d[..., 2]
        z_cam = sy * d[..., 0] + cy * d[..., 2]
        depth = -z_cam
        with np.errstate(divide="ignore", invalid="ignore"):
            in_fov = (depth > 0.05) & (np.abs(x_cam / depth) <= math.tan(math.radians(c.hfov_deg / 2))) & \
                     (np.abs(d[..., 1] / depth) <= math.tan(math.radians(c.vfov_deg / 2)))

        # Occlusion: the first hit along the ray to a sample point must be the object itself.
        m, p = in_fov.nonzero()
        visible = np.zeros_like(in_fov)
        if len(m):
            dirs = d[m, p]
            dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
            hit = self._rays.intersects_first(cams[m], dirs)
            ok = hit >= 0
            ok[ok] = self.asset.face_ids[hit[ok]] == obj.id
            visible[m, p] = ok
        frac = visible.mean(axis=1)
        keep = frac >= c.min_visible_fraction
        rots = np.array([quat_from_yaw(float(a)) for a in yaw[keep]]).reshape(-1, 4)
        return cand[keep], rots, frac[keep]
