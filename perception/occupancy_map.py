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
docs/results/occupancy_map.md), and it offers neither the detection mask nor
the clearing rays of invalid pixels.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np
from numba import njit
from scipy.ndimage import minimum_filter

from perception.esdf import signed_distance, verified_free_distance
from perception.map_config import MapConfig
from perception.types import Detection, OccupancySnapshot, trilinear
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
            self._log_odds = _shifted(self._log_odds, shift, 0.0)
            self._observed = _shifted(self._observed, shift, False)
            self._seen_s = _shifted(self._seen_s, shift, -np.inf)
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
        became = _integrate_rays(
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
        d = trilinear(dist, origin, v, p)[0]
        if self._became_occupied:  # only those after the base (_esdf_done drops the older)
            centres = (np.concatenate([idx for _, idx in self._became_occupied]) + 0.5) * v
            near = np.sqrt(np.min(np.sum((p[:, None, :] - centres[None, :, :]) ** 2, axis=-1), axis=1)) - 0.5 * v
            d = np.minimum(d, near)
        return d

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
        ``pixel_stride`` grid (:func:`_camera_rays`; :func:`rays_camera_numpy`
        is the vectorised reference the tests compare it with).
        """
        cfg = self.config
        depth = np.ascontiguousarray(frame.depth_m)
        boxes = np.array([np.asarray(d.box_xyxy, float) for d in detections], float).reshape(-1, 4)
        return _camera_rays(
            depth, cfg.pixel_stride, boxes, float(cfg.detection_margin_px), cfg.min_range_m, cfg.max_range_m,
            min(cfg.clear_invalid_m, cfg.max_range_m), cfg.invalid_neighborhood_px, cfg.voxel_m, depth.dtype.type(cfg.voxel_m), depth.dtype.type(np.inf),
            np.linalg.inv(np.asarray(frame.K, float)), max(cfg.clear_stride // cfg.pixel_stride, 1), cfg.clear_tail_voxels,
        )


def rays_camera_numpy(config: MapConfig, frame: RgbdFrame, detections: Sequence[Detection]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised numpy reference of :meth:`OccupancyMap._rays_camera` (same rays, same order)."""
    cfg = config
    depth_m = np.asarray(frame.depth_m)
    h, w = depth_m.shape
    s = cfg.pixel_stride
    v_px = np.arange(s // 2, h, s)
    u_px = np.arange(s // 2, w, s)
    d = depth_m[np.ix_(v_px, u_px)].astype(np.float64)
    keep = np.ones(d.shape, bool)
    m = cfg.detection_margin_px
    for det in detections:  # mask neighbours: their pixels are neither hits nor misses
        u0, v0, u1, v1 = np.asarray(det.box_xyxy, float)
        keep[np.ix_((v_px >= v0 - m) & (v_px <= v1 + m), (u_px >= u0 - m) & (u_px <= u1 + m))] = False
    finite = np.isfinite(d)
    hit = finite & (d >= cfg.min_range_m) & (d <= cfg.max_range_m)
    far = finite & (d > cfg.max_range_m)
    clear_nan = np.full(d.shape, min(cfg.clear_invalid_m, cfg.max_range_m))
    if cfg.invalid_neighborhood_px > 0 and not finite.all():
        # a hole in a surface clears only up to the surface around it, less one voxel
        near = minimum_filter(
            np.where(np.isfinite(depth_m), depth_m, np.inf), size=2 * cfg.invalid_neighborhood_px + 1, mode="nearest"
        )[np.ix_(v_px, u_px)]
        clear_nan = np.minimum(clear_nan, near - cfg.voxel_m)
    nan_ray = ~finite & (clear_nan > cfg.voxel_m)
    # which rays are traversed whole: every clear_stride-th pixel; the others only their last voxels before a hit
    c = max(cfg.clear_stride // s, 1)
    trace = np.zeros(d.shape, bool)
    trace[::c, ::c] = True
    use = keep & (hit | ((far | nan_ray) & trace))
    depth_end = np.where(hit, d, np.where(far, cfg.max_range_m, clear_nan))[use]
    K_inv = np.linalg.inv(np.asarray(frame.K, float))
    uu, vv = np.meshgrid(u_px.astype(float), v_px.astype(float))
    pix = np.stack([uu[use], vv[use], np.ones(depth_end.size)], axis=1)
    ends_cam = (pix @ K_inv.T) * depth_end[:, None]  # p_c = d K^-1 [u, v, 1]^T (MP-CDE Eq. 7)
    # an untraversed hit ray still clears its last clear_tail_voxels before the surface
    length = np.linalg.norm(ends_cam, axis=1)
    tail = np.clip(1.0 - cfg.clear_tail_voxels * cfg.voxel_m / np.maximum(length, 1e-9), 0.0, 1.0)
    start = np.where(trace[use], 0.0, tail)
    return ends_cam, np.ascontiguousarray(hit[use]), np.ascontiguousarray(start)


@njit(cache=True)
def _camera_rays(
    depth, stride, boxes, margin, min_r, max_r, clear_cap, nbhd, voxel, voxel_depth_dtype, inf_depth_dtype, K_inv, clear_every, tail_voxels
):  # pragma: no cover - compiled
    """The rays of one depth frame (see :func:`rays_camera_numpy`, the reference): ends (n, 3), is_hit (n,), start (n,).

    ``voxel_depth_dtype`` is ``voxel`` in the depth image's dtype: the hole
    bound ``near - voxel`` is computed in that precision, as numpy does.
    """
    h, w = depth.shape
    nv = (h - stride // 2 + stride - 1) // stride
    nu = (w - stride // 2 + stride - 1) // stride
    ends = np.empty((nv * nu, 3))
    is_hit = np.empty(nv * nu, np.bool_)
    start = np.empty(nv * nu)
    n = 0
    for iv in range(nv):
        v = stride // 2 + iv * stride
        for iu in range(nu):
            u = stride // 2 + iu * stride
            masked = False
            for b in range(boxes.shape[0]):
                if boxes[b, 1] - margin <= v <= boxes[b, 3] + margin and boxes[b, 0] - margin <= u <= boxes[b, 2] + margin:
                    masked = True
                    break
            if masked:
                continue
            d = float(depth[v, u])
            trace = iv % clear_every == 0 and iu % clear_every == 0
            hit = False
            if np.isfinite(d):
                if min_r <= d <= max_r:
                    hit = True
                    end = d
                elif d > max_r and trace:
                    end = max_r
                else:
                    continue
            else:
                if not trace:
                    continue
                end = clear_cap
                if nbhd > 0:  # a hole clears only up to the nearest valid depth around it, less one voxel
                    near = inf_depth_dtype
                    for y in range(max(v - nbhd, 0), min(v + nbhd, h - 1) + 1):
                        for x in range(max(u - nbhd, 0), min(u + nbhd, w - 1) + 1):
                            z = depth[y, x]
                            if np.isfinite(z) and z < near:
                                near = z
                    end = min(end, float(near - voxel_depth_dtype))
                if not end > voxel:
                    continue
            x = (K_inv[0, 0] * u + K_inv[0, 1] * v + K_inv[0, 2]) * end  # p_c = d K^-1 [u, v, 1]^T (MP-CDE Eq. 7)
            y = (K_inv[1, 0] * u + K_inv[1, 1] * v + K_inv[1, 2]) * end
            z = (K_inv[2, 0] * u + K_inv[2, 1] * v + K_inv[2, 2]) * end
            ends[n, 0], ends[n, 1], ends[n, 2] = x, y, z
            is_hit[n] = hit
            if trace:
                start[n] = 0.0
            else:
                length = max(np.sqrt(x * x + y * y + z * z), 1e-9)
                start[n] = min(max(1.0 - tail_voxels * voxel / length, 0.0), 1.0)
            n += 1
    return ends[:n], is_hit[:n], start[:n]


def _shifted(a: np.ndarray, shift: np.ndarray, fill: float | bool) -> np.ndarray:
    """``out[i] = a[i + shift]`` where that index exists, ``fill`` elsewhere; same shape as ``a`` (nx, ny, nz)."""
    out = np.full_like(a, fill)
    n = np.asarray(a.shape)
    dst_lo = np.clip(-shift, 0, n)
    dst_hi = np.clip(n - shift, 0, n)
    if np.any(dst_hi <= dst_lo):
        return out
    src_lo, src_hi = dst_lo + shift, dst_hi + shift
    out[dst_lo[0] : dst_hi[0], dst_lo[1] : dst_hi[1], dst_lo[2] : dst_hi[2]] = a[
        src_lo[0] : src_hi[0], src_lo[1] : src_hi[1], src_lo[2] : src_hi[2]
    ]
    return out


@njit(cache=True)
def _axis_setup(o, dv, i):
    """DDA set-up along one axis: (step, t_delta, t_max) for a ray o + t dv currently in cell i."""
    if dv > 0.0:
        return 1, 1.0 / dv, (i + 1 - o) / dv
    if dv < 0.0:
        return -1, -1.0 / dv, (i - o) / dv
    return 0, np.inf, np.inf


@njit(cache=True)
def _integrate_rays(
    origin_vox, ends_vox, is_hit, start, log_odds, observed, seen_s, time_s, mark, l_hit, l_miss, l_min, l_max, l_occupied
):  # pragma: no cover - compiled
    """Cast rays from ``origin_vox`` (3,) to ``ends_vox`` (n, 3) (window voxel units) and update log-odds.

    Every voxel a ray touches is marked observed and stamped ``seen_s = time_s`` (the frame time [s]).
    Returns the flat indices (k,) int64 of the voxels that became occupied
    (unknown or free before, log-odds above ``l_occupied`` after).

    Ray ``r`` is traversed from ``origin + start[r] (end - origin)`` (``start``
    in [0, 1]: 0 for a whole ray, near 1 for the last voxels before a hit).
    Amanatides-Woo traversal on the flattened window. ``mark`` (nx, ny, nz)
    int8 must be zero on entry and is zero on return; within the call
    1 = passed through (miss), 2 = end point (hit wins).
    """
    nx, ny, nz = log_odds.shape
    lo_flat = log_odds.reshape(-1)
    obs_flat = observed.reshape(-1)
    seen_flat = seen_s.reshape(-1)
    mk = mark.reshape(-1)
    touched = np.empty(4096, np.int64)
    n_touched = 0
    ox, oy, oz = origin_vox[0], origin_vox[1], origin_vox[2]
    for r in range(ends_vox.shape[0]):
        ex_f, ey_f, ez_f = ends_vox[r, 0], ends_vox[r, 1], ends_vox[r, 2]
        dx, dy, dz = ex_f - ox, ey_f - oy, ez_f - oz
        # clip the segment origin + t d, t in [0, 1], to the box [0, n) (slab method)
        t0 = start[r]
        t1 = 1.0
        for o, dv, n in ((ox, dx, nx), (oy, dy, ny), (oz, dz, nz)):
            if dv != 0.0:
                ta = -o / dv
                tb = (n - o) / dv
                if ta > tb:
                    ta, tb = tb, ta
                t0 = max(t0, ta)
                t1 = min(t1, tb)
            elif o < 0.0 or o >= n:
                t1 = -1.0
        if t0 >= t1:
            continue
        end_inside = is_hit[r] and t1 >= 1.0
        ix = min(max(int(np.floor(ox + t0 * dx)), 0), nx - 1)
        iy = min(max(int(np.floor(oy + t0 * dy)), 0), ny - 1)
        iz = min(max(int(np.floor(oz + t0 * dz)), 0), nz - 1)
        sx, tdx, tmx = _axis_setup(ox, dx, ix)
        sy, tdy, tmy = _axis_setup(oy, dy, iy)
        sz, tdz, tmz = _axis_setup(oz, dz, iz)
        ex = int(np.floor(ex_f))
        ey = int(np.floor(ey_f))
        ez = int(np.floor(ez_f))
        end_lin = (ex * ny + ey) * nz + ez if end_inside else -1
        lin = (ix * ny + iy) * nz + iz
        while lin != end_lin:
            if mk[lin] == 0:
                mk[lin] = 1
                if n_touched == touched.shape[0]:
                    grown = np.empty(2 * n_touched, np.int64)
                    grown[:n_touched] = touched
                    touched = grown
                touched[n_touched] = lin
                n_touched += 1
            if tmx <= tmy and tmx <= tmz:
                if tmx > t1:
                    break
                ix += sx
                if ix < 0 or ix >= nx:
                    break
                tmx += tdx
                lin += sx * ny * nz
            elif tmy <= tmz:
                if tmy > t1:
                    break
                iy += sy
                if iy < 0 or iy >= ny:
                    break
                tmy += tdy
                lin += sy * nz
            else:
                if tmz > t1:
                    break
                iz += sz
                if iz < 0 or iz >= nz:
                    break
                tmz += tdz
                lin += sz
        if end_inside and 0 <= ex < nx and 0 <= ey < ny and 0 <= ez < nz:
            if mk[end_lin] == 0:
                if n_touched == touched.shape[0]:
                    grown = np.empty(2 * n_touched, np.int64)
                    grown[:n_touched] = touched
                    touched = grown
                touched[n_touched] = end_lin
                n_touched += 1
            mk[end_lin] = 2
    became = np.empty(n_touched, np.int64)
    n_became = 0
    for k in range(n_touched):
        lin = touched[k]
        was_occupied = obs_flat[lin] and lo_flat[lin] > l_occupied
        l_new = lo_flat[lin] + (l_hit if mk[lin] == 2 else l_miss)  # l <- l + l_hit / l_miss
        lo_flat[lin] = min(max(l_new, l_min), l_max)  # clamp to [l_min, l_max]
        if not was_occupied and lo_flat[lin] > l_occupied:
            became[n_became] = lin
            n_became += 1
        obs_flat[lin] = True
        seen_flat[lin] = time_s
        mk[lin] = 0
    return became[:n_became]
