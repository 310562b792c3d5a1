"""Occlusion-aware field-of-view sectors and the exploration metric E (MP-CDE Eq. 3).

A sector is the camera's horizontal field of view at the drone's altitude,
rendered with ``n_rays`` rays (MP-CDE: 72) out to ``sensing_range_m``; each
ray ends at the first occupied voxel it meets (occlusion), the occupied voxel
itself excluded. Rays pass through unknown voxels: what is unknown is what
the camera would observe.

How the area is measured. Every ray sample (spacing ds about ``ray_step_m``, at
range r) stands for the polar patch ``r dtheta ds`` [m^2], so a full sector of
radius R has area ``fov R^2 / 2``. The area counted
as *gain* is restricted to samples that are

* visible (before the first occupied voxel of the ray),
* unknown in the map (voxel state -1, or outside the map window): the metric
  "drives the system towards unknown areas" (Sec. IV-A), so known free or
  occupied space earns nothing however new the sector is,
* not covered by the coverage window W (below).

The lattice needs sectors for every candidate yaw at every layer. Instead of
casting them one by one, each layer casts one full-circle *fan* of
``R = round(2 pi / dtheta)`` rays (dtheta = fov / n_rays) from the drone's
position at that layer; a candidate's sector is the ``n_rays`` consecutive
fan rays centred on its yaw. The candidate yaws are the lattice's
``yaw0 + 2 pi k / m`` and the fan starts at ``yaw0 - n_rays dtheta / 2``, so
candidate k's sector starts at fan ray ``round(k R / m)``.

The window W and Eq. 3. E of an edge from candidate j (layer i - 1) to
candidate k (layer i) is the area of k's sector not covered by

* the sectors of the yaws executed within ``window_s`` before now (the current
  yaw included), each cast from where the drone was at the time, kept as the
  centres of the cells their visible samples fell in
  (:func:`visible_cells_xy`), marked on a 2-D grid of the map window's cells
  (:func:`past_coverage`), and
* the sector of the predecessor j on the path.

With only the predecessor from the path, E is a function of the edge, so the
shortest path on the lattice is exact (a window reaching further back along
the path would make the cost depend on the whole path). The predecessor's
sector is taken from layer i's position, not layer i - 1's: the drone moves at
most v_max t_y (0.1 m by default) between layers, less than a voxel. Then
k's sector minus j's is the strip of fan rays swept by the turn (width
``|yaw_k - yaw_j|``, at most yaw_rate_max t_y) and E is a difference of a
cumulative sum over the fan (:func:`edge_gains`).

Limitation of the predecessor-only path memory: a path that reverses
(turn left, then right) is credited again with the strip it swept two steps
before, so on a uniformly unknown map a back-and-forth tail of the path
scores as well as a continued sweep. The plan is receding-horizon (re-made
every t_y, and the yaws actually executed enter W), so only its first steps
are flown, and those head towards the unknown; the reversal credit matters
only near the end of the 1.2 s horizon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from perception.types import OccupancySnapshot
from planners.yaw.config import YawPlannerConfig

__all__ = ["FanCast", "FanGeometry", "cast_fans", "edge_gains", "past_coverage", "ray_gains", "visible_cells_xy"]


@dataclass(frozen=True)
class FanGeometry:
    """The full-circle ray fan of one configuration.

    Attributes:
        n_fan: R, rays in the full circle [-].
        dtheta_rad: angular spacing of the rays, 2 pi / R [rad].
        n_sector: rays per field-of-view sector (``n_rays``) [-].
        ranges_m: (S,) ranges of the samples along a ray, ``(s + 1/2) ds`` [m] with
            ``ds = sensing_range_m / S`` and ``S = round(sensing_range_m / ray_step_m)``.
        areas_m2: (S,) area each sample stands for, ``r dtheta ds`` [m^2].
    """

    n_fan: int
    dtheta_rad: float
    n_sector: int
    ranges_m: np.ndarray
    areas_m2: np.ndarray

    @staticmethod
    def from_config(config: YawPlannerConfig) -> "FanGeometry":
        """Fan for ``config`` (``n_rays``, ``fov_h_deg``, ``sensing_range_m``, ``ray_step_m``)."""
        n_fan = int(round(2.0 * math.pi * config.n_rays / config.fov_h_rad))
        dtheta = 2.0 * math.pi / n_fan
        n_samples = max(1, int(round(config.sensing_range_m / config.ray_step_m)))
        ds = config.sensing_range_m / n_samples  # the samples tile [0, sensing_range_m] exactly
        ranges = (np.arange(n_samples) + 0.5) * ds
        return FanGeometry(n_fan, dtheta, config.n_rays, ranges, ranges * dtheta * ds)

    def azimuths(self, yaw0: float) -> np.ndarray:
        """(R,) world azimuths [rad] of the fan's rays; rays 0 .. n_sector - 1 form the sector of ``yaw0``."""
        return yaw0 + (np.arange(self.n_fan) + 0.5 - 0.5 * self.n_sector) * self.dtheta_rad

    def sector_start(self, candidate: np.ndarray, n_candidates: int) -> np.ndarray:
        """First fan ray (integer, not wrapped) of the sector of candidate ``candidate`` (any shape, unwrapped)."""
        return np.rint(np.asarray(candidate) * (self.n_fan / n_candidates)).astype(np.int64)


@dataclass(frozen=True)
class FanCast:
    """Fans cast from L positions.

    Attributes:
        visible: (L, R, S) bool, the sample lies before the first occupied voxel of its ray.
        unknown: (L, R, S) bool, the sample's voxel is unknown (or outside the window).
        cell: (L, R, S) int32, flat index ``(ix + 1) * (ny + 2) + (iy + 1)`` of
            the sample's cell in the window's 2-D grid padded by one cell on
            every side; samples outside the window fall on the padding.
    """

    visible: np.ndarray
    unknown: np.ndarray
    cell: np.ndarray


def cast_fans(
    snapshot: OccupancySnapshot,
    positions_world: np.ndarray,
    azimuths_rad: np.ndarray,
    ranges_m: np.ndarray,
) -> FanCast:
    """Cast horizontal rays from each of ``positions_world`` (L, 3) [m] at ``azimuths_rad`` (R,) [rad].

    Samples lie at ``ranges_m`` (S,) [m] along each ray, in the voxel layer of
    the position's altitude. A sample is occluded when an earlier or the same
    sample of its ray is occupied (vectorised: a cumulative OR along the ray).
    Outside the window every voxel reads unknown (as in ``state_at``): each
    layer's 2-D slice is padded by one unknown cell and the sample indices are
    clipped onto the padding, so no per-sample bounds test is needed.
    """
    p = np.asarray(positions_world, float).reshape(-1, 3)
    v = snapshot.voxel_m
    nx, ny, nz = snapshot.shape
    rel = (p - snapshot.origin_world) / v + 1.0  # (L, 3) continuous voxel coordinates, +1 for the padding
    kz = np.floor(rel[:, 2] - 1.0).astype(np.int64)  # (L,) voxel layer of each position
    slices = np.full((len(p), nx + 2, ny + 2), OccupancySnapshot.UNKNOWN, dtype=np.int8)
    ok = (kz >= 0) & (kz < nz)
    slices[ok, 1:-1, 1:-1] = np.moveaxis(snapshot.state[:, :, kz[ok]], 2, 0)
    ux = np.outer(np.cos(azimuths_rad), ranges_m / v).astype(np.float32)  # (R, S) offsets in voxels
    uy = np.outer(np.sin(azimuths_rad), ranges_m / v).astype(np.float32)
    fx = rel[:, 0, None, None].astype(np.float32) + ux  # (L, R, S)
    fy = rel[:, 1, None, None].astype(np.float32) + uy
    # clip onto [0, n + 1] (the padding) and truncate: floor, as every value is >= 0
    ix = np.clip(fx, 0.0, nx + 1, out=fx).astype(np.int32)
    iy = np.clip(fy, 0.0, ny + 1, out=fy).astype(np.int32)
    cell = ix * np.int32(ny + 2) + iy
    layer = (np.arange(len(p), dtype=np.int32) * np.int32((nx + 2) * (ny + 2)))[:, None, None]
    state = np.ravel(slices)[cell + layer]
    visible = ~np.logical_or.accumulate(state == OccupancySnapshot.OCCUPIED, axis=2)
    unknown = state == OccupancySnapshot.UNKNOWN
    return FanCast(visible, unknown, cell)


def visible_cells_xy(snapshot: OccupancySnapshot, cast: FanCast, layer: int = 0) -> np.ndarray:
    """World xy (k, 2) [m] of the centres of the distinct window cells seen by the visible samples of ``layer``.

    What the coverage window W keeps of an executed yaw's sector (cast with
    only that sector's rays): cell centres, so a later snapshot whose window
    moved by whole voxels maps them back onto the same cells.
    """
    nx, ny, _ = snapshot.shape
    seen = np.zeros((nx + 2) * (ny + 2), dtype=bool)
    seen[cast.cell[layer][cast.visible[layer]]] = True
    ix, iy = np.divmod(np.flatnonzero(seen), ny + 2)
    inside = (ix >= 1) & (ix <= nx) & (iy >= 1) & (iy <= ny)
    centres = np.stack([ix[inside], iy[inside]], axis=1) - 0.5  # padded index - 1 + 1/2
    return centres * snapshot.voxel_m + snapshot.origin_world[:2]


def past_coverage(snapshot: OccupancySnapshot, points_xy: np.ndarray) -> np.ndarray:
    """((nx + 2) * (ny + 2),) bool: padded 2-D cells (as :attr:`FanCast.cell`) holding any of ``points_xy`` (k, 2).

    Points [m, world xy] outside the window are dropped, so the padding is never covered.
    """
    nx, ny, _ = snapshot.shape
    covered = np.zeros((nx + 2) * (ny + 2), dtype=bool)
    if len(points_xy):
        idx = np.floor((np.asarray(points_xy, float) - snapshot.origin_world[:2]) / snapshot.voxel_m).astype(np.int64)
        ok = (idx[:, 0] >= 0) & (idx[:, 0] < nx) & (idx[:, 1] >= 0) & (idx[:, 1] < ny)
        covered[(idx[ok, 0] + 1) * (ny + 2) + idx[ok, 1] + 1] = True
    return covered


def ray_gains(cast: FanCast, covered: np.ndarray, areas_m2: np.ndarray) -> np.ndarray:
    """(L, R) area [m^2] per ray that is visible, unknown and not in ``covered`` (:func:`past_coverage`)."""
    gain = cast.visible & cast.unknown & ~covered[cast.cell]
    return gain.astype(np.float32) @ areas_m2.astype(np.float32)


def edge_gains(gains: np.ndarray, fan: FanGeometry, n_candidates: int, max_hop: int) -> tuple[np.ndarray, float]:
    """Exploration gain E of every lattice edge (MP-CDE Eq. 3), and its upper bound.

    Args:
        gains: (n, R) ray gains [m^2] of the fans of layers 1 .. n (:func:`ray_gains`).
        fan: the fan geometry.
        n_candidates: m [-].
        max_hop: q [-].

    Returns:
        E: (n, m, 2q + 1) [m^2]; ``E[i - 1, j, h]`` is the area of the sector of
        candidate ``k = (j + h - q) mod m`` at layer i outside the sector of
        candidate j (and outside the coverage window, already removed from
        ``gains``), i.e. the sum of the fan rays swept by the turn j -> k.
        e_max: [m^2] the largest E any edge could have (the widest swept strip,
        all of it visible and unknown), to normalise E to [0, 1].
    """
    n, n_fan = gains.shape
    n_sector = fan.n_sector
    j = np.arange(n_candidates)[:, None]
    h = np.arange(-max_hop, max_hop + 1)[None, :]
    o_j = fan.sector_start(j, n_candidates)  # (m, 1) first ray of j's sector
    o_k = fan.sector_start(j + h, n_candidates)  # (m, 2q + 1), unwrapped
    # k sweeps left (o_k > o_j): new rays [o_j + N, o_k + N); right: [o_k, o_j)
    lo = np.where(o_k > o_j, o_j + n_sector, o_k)
    hi = np.where(o_k > o_j, o_k + n_sector, o_j)
    # cumulative sum over the fan tiled three times, so indices in [-R, 2R] need no wrapping
    cum = np.zeros((n, 3 * n_fan + 1))
    np.cumsum(np.tile(gains, (1, 3)), axis=1, out=cum[:, 1:])
    e = cum[:, hi + n_fan] - cum[:, lo + n_fan]
    e_max = float(np.max(hi - lo)) * float(np.sum(fan.areas_m2))
    return e, e_max
