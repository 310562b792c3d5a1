"""Depth frame -> voxel updates: the rays of a frame (compiled, with its numpy reference) and the traversal that marks free and occupied voxels.

What :class:`perception.occupancy_map.OccupancyMap` calls per frame; the stride-4 grid of whole rays and the
stride-2 ray tails are its ``MapConfig.clear_stride`` and ``clear_tail_voxels``
(docs/results/realtime.md#the-map-the-esdf-and-the-planners).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit
from scipy.ndimage import minimum_filter

from perception.map_config import MapConfig
from perception.types import Detection
from sim.types import RgbdFrame

__all__ = ["camera_rays", "integrate_rays", "rays_camera_numpy", "shifted_window"]


def rays_camera_numpy(config: MapConfig, frame: RgbdFrame, detections: Sequence[Detection]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised numpy reference of :meth:`perception.occupancy_map.OccupancyMap._rays_camera` (same rays, same order)."""
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
def camera_rays(
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


def shifted_window(a: np.ndarray, shift: np.ndarray, fill: float | bool) -> np.ndarray:
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
def _axis_step(i, step, n, t_max, t_delta, lin, lin_step, t1):
    """One Amanatides-Woo step into the next cell along an axis: (moved, i, t_max, lin).

    ``i`` is the cell index on the axis (0..n-1), ``step`` its direction (+-1), ``t_max`` the ray
    parameter of the next boundary crossing, ``t_delta`` that between crossings, ``lin`` the flat
    index and ``lin_step`` its change per step. moved is False (and the traversal ends) when the
    crossing lies beyond ``t1`` or leaves the window.
    """
    if t_max > t1:
        return False, i, t_max, lin
    i += step
    if i < 0 or i >= n:
        return False, i, t_max, lin
    return True, i, t_max + t_delta, lin + lin_step


@njit(cache=True)
def integrate_rays(
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
    touched = np.empty(lo_flat.shape[0], np.int64)  # a voxel enters once per call (mark), so the window bounds it
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
                touched[n_touched] = lin
                n_touched += 1
            if tmx <= tmy and tmx <= tmz:
                moved, ix, tmx, lin = _axis_step(ix, sx, nx, tmx, tdx, lin, sx * ny * nz, t1)
            elif tmy <= tmz:
                moved, iy, tmy, lin = _axis_step(iy, sy, ny, tmy, tdy, lin, sy * nz, t1)
            else:
                moved, iz, tmz, lin = _axis_step(iz, sz, nz, tmz, tdz, lin, sz, t1)
            if not moved:
                break
        if end_inside and 0 <= ex < nx and 0 <= ey < ny and 0 <= ez < nz:
            if mk[end_lin] == 0:
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
