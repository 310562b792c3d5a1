"""A drone's own occupancy map: a rolling log-odds voxel window fed by its depth frames.

Each :meth:`OccupancyMap.update` integrates one depth frame (DESIGN.md
section 4, perception: "Map"):

1. every ``pixel_stride``-th pixel ``(u, v)`` with depth ``d`` is
   back-projected, ``p_c = d K^-1 [u, v, 1]^T`` (MP-CDE Eq. 7), and taken to
   world, ``p_w = T_wc p_c`` (Eq. 8), with ``T_wc`` the frame's
   ``transform_camera_to_world`` (the drone's own pose estimate);
2. pixels inside a detected drone's box (plus ``detection_margin_px``) are
   dropped entirely, so a neighbour never becomes a wall and the space around
   it is not claimed either;
3. each ray camera -> ``p_w`` is traversed voxel by voxel (Amanatides & Woo
   1987, compiled with numba): the voxels it passes through get a miss, the
   voxel of a valid end point (``min_range_m <= d <= max_range_m``) a hit.
   Readings beyond ``max_range_m`` clear their ray up to ``max_range_m``
   without a hit; invalid (NaN) pixels clear theirs up to ``clear_invalid_m``
   but never beyond the nearest valid depth around them (a stereo hole does
   not see through the surface it sits in; see :class:`MapConfig`); readings
   nearer than ``min_range_m`` are skipped;
4. within one frame a voxel is updated once, and a hit wins over a miss
   (OctoMap's rule), so a wall seen at grazing angles is not eroded by the
   rays that pass next to it; the log-odds ``l`` is updated
   ``l <- clamp(l + l_hit or l_miss, l_min, l_max)``.

The window (``window_size_m``, aligned to a global grid of ``voxel_m``) is
recentred on the camera at every update; voxels that scroll in are unknown.
A voxel is unknown until a ray touches it, then occupied if
``l > log_odds_occupied``, else free; the frame time of the last ray that
touched it is kept too (``seen_s`` of the snapshot), so a planner can tell
free space seen just now from free space seen long ago (MP-CDE Eq. 1's
"temporally validated" segment, :mod:`planners.yaw.safety`). :meth:`OccupancyMap.snapshot` hands out an
immutable :class:`perception.types.OccupancySnapshot` whose ESDF (see
:mod:`perception.esdf`) is computed only when a planner reads it;
:meth:`OccupancyMap.clearance` answers the per-frame "is the plan still
clear?" from the newest ESDF and the voxels occupied since, without a
transform.

Back-projection is plain numpy: open3d's ``PointCloud.create_from_depth_image``
costs about the same and is small next to the ray casting (measured:
docs/results/occupancy_map.md#back-projection-numpy-against-open3d), and it offers neither the detection mask nor
the clearing rays of invalid pixels.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
from numba import njit

from perception.esdf import signed_distance, verified_free_distance
from perception.map_config import MapConfig
from perception.ray_integration import camera_rays, integrate_rays, shifted_window
from perception.types import Detection, OccupancySnapshot, trilinear, trilinear_compiled
from sim.types import RgbdFrame

__all__ = ["OccupancyMap"]


class OccupancyMap:
    """Rolling-window log-odds occupancy map of one drone.

    Args:
        config: map settings.
        center_world: (3,) initial window centre [m]; by default the window is
            placed around the camera of the first frame.
        on_esdf: called with the wall time [s] of every distance transform
            (the flight's compute budget).
    """

    def __init__(
        self, config: MapConfig = MapConfig(), center_world: np.ndarray | None = None,
        on_esdf: Callable[[float], None] | None = None,
    ) -> None:
        self.config = config
        self._shape = np.asarray(config.window_shape, np.int64)
        self._log_odds = np.zeros(config.window_shape, np.float32)
        self._observed = np.zeros(config.window_shape, np.bool_)
        self._seen_s = np.full(config.window_shape, -np.inf, np.float32)  # time a ray last touched each voxel [s]
        self._mark = np.zeros(config.window_shape, np.int8)  # per-frame scratch, always zero between calls
        self._origin_index: np.ndarray | None = None  # global index of voxel (0, 0, 0)
        self._time_s = -np.inf
        self._snapshot: OccupancySnapshot | None = None
        self._update_seq = 0  # frames integrated
        # (update number, (k, 3) global voxel indices) of voxels that became occupied, for clearance()
        self._became_occupied: deque[tuple[int, np.ndarray]] = deque()
        self._esdf_base: tuple[int, np.ndarray, np.ndarray] | None = None  # (update number, origin, ESDF) of the newest ESDF
        self.esdf_count = 0  # distance transforms computed
        self.on_esdf: Callable[[float], None] | None = on_esdf
        if center_world is not None:
            self.recenter(np.asarray(center_world, float))

    @property
    def origin_world(self) -> np.ndarray:
        """(3,) world position [m] of the window's minimum corner (zeros before the first frame)."""
        if self._origin_index is None:
            return np.zeros(3)
        return self._origin_index * self.config.voxel_m

    def state(self) -> np.ndarray:
        """(nx, ny, nz) int8 voxel states: -1 unknown, 0 free, 1 occupied."""
        out = np.where(self._log_odds > self.config.log_odds_occupied, 1, 0).astype(np.int8)
        out[~self._observed] = OccupancySnapshot.UNKNOWN
        return out

    def recenter(self, center_world: np.ndarray) -> None:
        """Move the window so that ``center_world`` (3,) [m] lies in its central voxel; keeps the overlap."""
        center_index = np.floor(np.asarray(center_world, float) / self.config.voxel_m).astype(np.int64)
        new_origin = center_index - self._shape // 2
        if self._origin_index is not None and np.array_equal(new_origin, self._origin_index):
            return
        if self._origin_index is not None:
            shift = new_origin - self._origin_index  # old index = new index + shift
            self._log_odds = shifted_window(self._log_odds, shift, 0.0)
            self._observed = shifted_window(self._observed, shift, False)
            self._seen_s = shifted_window(self._seen_s, shift, -np.inf)
        self._origin_index = new_origin
        self._snapshot = None

    def update(
        self, frame: RgbdFrame, detections: Sequence[Detection] = (), neighbours_world: np.ndarray | None = None
    ) -> None:
        """Integrate one depth frame.

        Pixels inside ``detections`` boxes are ignored, and so are rays that hit
        within ``config.neighbour_exclusion_m`` of a row of ``neighbours_world``
        ((n, 3) [m], world frame: where the drone believes its neighbours are at
        the frame time), so a neighbour the detector missed is not mapped.
        """
        cfg = self.config
        T_wc = np.asarray(frame.transform_camera_to_world, float)
        cam_world = T_wc[:3, 3]
        self.recenter(cam_world)
        ends_cam, is_hit, start = self._rays_camera(frame, detections)
        ends_world = ends_cam @ T_wc[:3, :3].T + cam_world  # p_w = R_wc p_c + t_wc (MP-CDE Eq. 8)
        if neighbours_world is not None and cfg.neighbour_exclusion_m > 0.0 and len(neighbours_world):
            centres = np.asarray(neighbours_world, float).reshape(-1, 3)
            r2 = cfg.neighbour_exclusion_m**2
            on_nb = np.zeros(is_hit.shape, bool)
            for c in centres:
                on_nb |= np.einsum("ij,ij->i", ends_world - c, ends_world - c) < r2
            keep = ~(is_hit & on_nb)
            ends_world, is_hit, start = (np.ascontiguousarray(a[keep]) for a in (ends_world, is_hit, start))
        origin = self.origin_world
        became = integrate_rays(
            (cam_world - origin) / cfg.voxel_m,
            np.ascontiguousarray((ends_world - origin) / cfg.voxel_m),
            is_hit,
            start,
            self._log_odds,
            self._observed,
            self._seen_s,
            np.float32(frame.time_s),
            self._mark,
            cfg.log_odds_hit,
            cfg.log_odds_miss,
            cfg.log_odds_min,
            cfg.log_odds_max,
            cfg.log_odds_occupied,
        )
        self._time_s = float(frame.time_s)
        self._snapshot = None
        self._update_seq += 1
        if became.size:
            idx = np.stack(np.unravel_index(became, self._log_odds.shape), axis=1) + self._origin_index
            self._became_occupied.append((self._update_seq, idx))

    def snapshot(self) -> OccupancySnapshot:
        """Immutable copy of the window (cached until the next update).

        Its distance layers are deferred: the ESDF is computed the first time a
        planner reads ``distance_m`` (``free_distance_m`` likewise, on its own),
        so the frames nobody plans on cost no transform (DESIGN.md section 3:
        the planners ask for the ESDF at their rates, never per frame).
        """
        if self._snapshot is None:
            cfg = self.config
            state = self.state()
            state.flags.writeable = False
            seen_s = self._seen_s.copy()
            seen_s.flags.writeable = False
            origin = self.origin_world
            origin.flags.writeable = False
            seq = self._update_seq

            def esdf() -> np.ndarray:
                t0 = time.perf_counter()
                d = signed_distance(state == OccupancySnapshot.OCCUPIED, cfg.voxel_m, cfg.esdf_max_m)
                self._esdf_done(seq, origin, d, time.perf_counter() - t0)
                return d

            def free_distance() -> np.ndarray:
                t0 = time.perf_counter()
                d = verified_free_distance(state == OccupancySnapshot.FREE, cfg.voxel_m, cfg.esdf_max_m)
                self._esdf_done(None, origin, None, time.perf_counter() - t0)
                return d

            self._snapshot = OccupancySnapshot(self._time_s, origin, cfg.voxel_m, state, esdf, free_distance, seen_s)
        return self._snapshot

    def clearance(self, points_world: np.ndarray) -> np.ndarray:
        """Distance (n,) [m] from ``points_world`` (n, 3) to the mapped obstacles, without a fresh transform.

        The cheap check of the hot path ("is the current trajectory still
        clear?"): the newest ESDF computed (trilinear, as
        :meth:`OccupancySnapshot.distance_and_gradient`), lowered to the
        distance from each point to every voxel that became occupied since
        that ESDF (centre distance less half a voxel, the ESDF's own
        convention). Voxels freed since are not credited, so the value errs on
        the safe side. Before any ESDF exists, one is computed.
        """
        p = np.asarray(points_world, float).reshape(-1, 3)
        if self._esdf_base is None:
            self.snapshot().distance_m
        _, origin, dist = self._esdf_base
        v = self.config.voxel_m
        if self._became_occupied:  # only those after the base (_esdf_done drops the older)
            centres = (np.concatenate([idx for _, idx in self._became_occupied]) + 0.5) * v
        else:
            centres = np.empty((0, 3))
        return _clearance(dist, np.asarray(origin, float), float(v), p, centres)

    def _esdf_done(self, seq: int | None, origin: np.ndarray, distance_m: np.ndarray | None, seconds: float) -> None:
        """Book a finished transform: its time, and (for the ESDF) the newest base of :meth:`clearance`."""
        self.esdf_count += 1
        if self.on_esdf is not None:
            self.on_esdf(seconds)
        if seq is not None and (self._esdf_base is None or seq > self._esdf_base[0]):
            self._esdf_base = (seq, origin, distance_m)
            while self._became_occupied and self._became_occupied[0][0] <= seq:
                self._became_occupied.popleft()

    def _rays_camera(self, frame: RgbdFrame, detections: Sequence[Detection]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ray end points in camera frame (n, 3) [m], whether each ends on a surface (n,) bool, and where its traversal starts (n,) in [0, 1].

        Steps 1-2 of the module docstring, in one compiled pass over the
        ``pixel_stride`` grid (:func:`camera_rays`; :func:`perception.ray_integration.rays_camera_numpy`
        is the vectorised reference the tests compare it with).
        """
        cfg = self.config
        depth = np.ascontiguousarray(frame.depth_m)
        boxes = np.array([np.asarray(d.box_xyxy, float) for d in detections], float).reshape(-1, 4)
        return camera_rays(
            depth, cfg.pixel_stride, boxes, float(cfg.detection_margin_px), cfg.min_range_m, cfg.max_range_m,
            min(cfg.clear_invalid_m, cfg.max_range_m), cfg.invalid_neighborhood_px, cfg.voxel_m, depth.dtype.type(cfg.voxel_m), depth.dtype.type(np.inf),
            np.linalg.inv(np.asarray(frame.K, float)), max(cfg.clear_stride // cfg.pixel_stride, 1), cfg.clear_tail_voxels,
        )


@njit(cache=True)
def _clearance(dist, origin, v, p, centres):  # pragma: no cover - compiled
    """:meth:`OccupancyMap.clearance`'s arithmetic for points ``p`` (n, 3) [m]: the trilinear value of ``dist``
    (:func:`perception.types.trilinear_compiled`), lowered to the distance to the nearest of ``centres`` (k, 3) [m]
    less half a voxel ``v``; NaN for a non-finite point. :func:`clearance_numpy` is the reference the tests
    compare it with."""
    out = trilinear_compiled(dist, origin, v, p)[0]
    if centres.shape[0] == 0:
        return out
    for k in range(p.shape[0]):
        if np.isnan(out[k]):
            continue
        best = np.inf
        for m in range(centres.shape[0]):
            dx = p[k, 0] - centres[m, 0]
            dy = p[k, 1] - centres[m, 1]
            dz = p[k, 2] - centres[m, 2]
            q = dx * dx + dy * dy + dz * dz
            if q < best:
                best = q
        out[k] = min(out[k], np.sqrt(best) - 0.5 * v)
    return out


def clearance_numpy(dist: np.ndarray, origin: np.ndarray, v: float, p: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Vectorised numpy reference of the compiled clearance arithmetic (same arguments, same result)."""
    d = trilinear(dist, origin, v, p)[0]
    if centres.shape[0]:
        near = np.sqrt(np.min(np.sum((p[:, None, :] - centres[None, :, :]) ** 2, axis=-1), axis=1)) - 0.5 * v
        d = np.minimum(d, near)
    return d
