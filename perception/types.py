"""Types that leave perception/ (frozen dataclasses, and the immutable map snapshot).

:class:`NeighborPrediction` is the one type the planners consume about other
drones (DESIGN.md section 4, planners). It comes from either source:

* a received radio plan: samples of the neighbour's planned trajectory, exact
  (zero covariance), with the message's age;
* a perception track: a single sample (the filter's posterior at its last
  update ``t_k``) extrapolated at constant velocity, MP-CDE Eq. 12::

      p(t) = p_k + v_k (t - t_k),   P(t) = F(t - t_k) P_k F(t - t_k)^T

so the same planners run on either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np
from numba import njit

__all__ = ["Detection", "DistanceField", "NeighborPrediction", "OccupancySnapshot", "trilinear"]


@dataclass(frozen=True)
class Detection:
    """One detected drone in one image.

    Attributes:
        box_xyxy: (4,) box corners ``[u_min, v_min, u_max, v_max]`` in [px].
        score: detector confidence in [0, 1].
    """

    box_xyxy: np.ndarray
    score: float


@runtime_checkable
class DistanceField(Protocol):
    """Anything the planners can ask for obstacle clearance (an ESDF, an analytic field).

    ``distance_and_gradient(points_world)`` takes (n, 3) points in world [m]
    and returns the signed distance to the nearest obstacle (n,) in [m]
    (negative inside) and its gradient (n, 3) with respect to the points.
    """

    def distance_and_gradient(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class NeighborPrediction:
    """Predicted position of one neighbour as a function of absolute time.

    Attributes:
        neighbor_id: the neighbour's identity (drone index for radio plans,
            track id for perception tracks).
        source: ``"radio"`` or ``"perception"``.
        stamp_s: time [s] of the information (message send time, or the track's
            last measurement time ``t_k``).
        times_s: (K,) increasing absolute sample times [s], K >= 1.
        pos_world: (K, 3) positions [m] at ``times_s``.
        vel_world: (K, 3) velocities [m/s] at ``times_s``.
        cov_world: (6, 6) covariance of ``[p, v]`` at ``times_s[-1]`` in
            [m^2, m^2/s, m^2/s^2]; zeros for an exact radio plan.

    Between samples the position is the cubic Hermite interpolant of
    (pos, vel); outside ``[times_s[0], times_s[-1]]`` it is extrapolated at
    constant velocity from the nearest sample (MP-CDE Eq. 12 for K = 1).
    """

    neighbor_id: int
    source: str
    stamp_s: float
    times_s: np.ndarray
    pos_world: np.ndarray
    vel_world: np.ndarray
    cov_world: np.ndarray

    def __post_init__(self) -> None:
        if self.source not in ("radio", "perception"):
            raise ValueError(f"NeighborPrediction.source={self.source!r}: allowed 'radio' or 'perception'")
        k = np.shape(self.times_s)[0]
        if k < 1 or np.shape(self.pos_world) != (k, 3) or np.shape(self.vel_world) != (k, 3):
            raise ValueError("NeighborPrediction: times_s (K,), pos_world (K, 3), vel_world (K, 3) with K >= 1")
        if np.shape(self.cov_world) != (6, 6):
            raise ValueError("NeighborPrediction.cov_world must be (6, 6)")

    @staticmethod
    def constant_velocity(
        neighbor_id: int, source: str, t_k: float, pos_world: np.ndarray, vel_world: np.ndarray, cov_world: np.ndarray
    ) -> "NeighborPrediction":
        """A single-sample prediction (a track's posterior at ``t_k``), MP-CDE Eq. 12."""
        return NeighborPrediction(
            neighbor_id=int(neighbor_id),
            source=source,
            stamp_s=float(t_k),
            times_s=np.array([float(t_k)]),
            pos_world=np.asarray(pos_world, float).reshape(1, 3),
            vel_world=np.asarray(vel_world, float).reshape(1, 3),
            cov_world=np.asarray(cov_world, float).reshape(6, 6),
        )

    def age_s(self, t_now: float) -> float:
        """Age [s] of the information at ``t_now`` [s]."""
        return float(t_now) - self.stamp_s

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """Predicted position [m] at absolute times ``t`` (n,) -> (n, 3) (scalar -> (3,))."""
        scalar = np.ndim(t) == 0
        t = np.atleast_1d(np.asarray(t, float))
        ts, p, v = self.times_s, self.pos_world, self.vel_world
        if ts.size == 1:  # a track's constant-velocity prediction (Eq. 12): both ends are the one sample
            out = p[0] + v[0] * (t - ts[0])[:, None]
            return out[0] if scalar else out
        out = np.empty((t.size, 3))
        lo = t <= ts[0]
        hi = t >= ts[-1]
        out[lo] = p[0] + v[0] * (t[lo] - ts[0])[:, None]
        out[hi] = p[-1] + v[-1] * (t[hi] - ts[-1])[:, None]
        mid = ~(lo | hi)
        if np.any(mid):
            i = np.clip(np.searchsorted(ts, t[mid]) - 1, 0, ts.size - 2)
            h = (ts[i + 1] - ts[i])[:, None]
            s = (t[mid] - ts[i])[:, None] / h
            h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
            h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
            out[mid] = h00 * p[i] + h10 * h * v[i] + h01 * p[i + 1] + h11 * h * v[i + 1]
        return out[0] if scalar else out

    def position_cov(self, t: np.ndarray | float) -> np.ndarray:
        """Position covariance (n, 3, 3) [m^2] at times ``t`` (n,).

        Beyond the last sample: the position block of F P F^T with
        F = [[I, dt I], [0, I]] (MP-CDE Eq. 12); before it, the block of P.
        """
        t = np.atleast_1d(np.asarray(t, float))
        dt = np.maximum(t - self.times_s[-1], 0.0)[:, None, None]
        P = self.cov_world
        Ppp, Ppv, Pvv = P[:3, :3], P[:3, 3:], P[3:, 3:]
        # P_pos(t) = Ppp + dt (Ppv + Ppv^T) + dt^2 Pvv
        return Ppp + dt * (Ppv + Ppv.T) + dt**2 * Pvv

    def uncertainty_radius(self, t: np.ndarray | float, n_sigma: float = 1.0) -> np.ndarray:
        """Conservative radius [m] ``n_sigma * sqrt(trace P_pos(t))`` at times ``t`` (n,) -> (n,)."""
        cov = self.position_cov(t)
        return n_sigma * np.sqrt(np.maximum(np.trace(cov, axis1=1, axis2=2), 0.0))


class OccupancySnapshot:
    """What a drone's map hands to the planners: one immutable copy of its local window.

    The window is a regular grid of ``(nx, ny, nz)`` cubic voxels of edge
    ``voxel_m``; voxel ``(i, j, k)`` spans ``origin_world + voxel_m * [i, i+1) x ...``
    and its centre is ``origin_world + voxel_m * ([i, j, k] + 0.5)``.

    ``distance_m`` and ``free_distance_m`` may be given as arrays or as
    zero-argument callables that compute them; a callable runs the first time
    the layer is read and its result is kept (the map hands out snapshots
    whose distance transforms are computed only if a planner reads them, so a
    frame that nobody plans on costs no ESDF). The snapshot is immutable:
    attributes cannot be set and every array is read-only.

    Attributes:
        time_s: time [s] of the last depth frame integrated.
        origin_world: (3,) world position [m] of the minimum corner of voxel (0, 0, 0).
        voxel_m: voxel edge [m].
        state: (nx, ny, nz) int8; ``-1`` unknown (never observed), ``0`` free,
            ``1`` occupied.
        distance_m: (nx, ny, nz) float32 signed Euclidean distance [m] from each
            voxel centre to the nearest *occupied* voxel surface; negative inside
            obstacles, clipped at the map's truncation distance.
        free_distance_m: (nx, ny, nz) float32 distance [m] from each voxel centre
            to the nearest voxel that is *not verified free* (unknown or
            occupied), 0 outside verified free space; MP-CDE Eq. 1's
            ``d_free`` for the yaw planner's safety margin.
        seen_s: (nx, ny, nz) float32 frame time [s] at which a ray last touched
            each voxel (``-inf``: never), or None when the map did not record it
            (then observed free space never ages); read by
            :meth:`is_verified_free` with ``max_age_s``.

    How unknown space counts: for ``distance_m`` (the ESDF the trajectory
    optimiser reads through :class:`DistanceField`) unknown counts as free.
    Counting it as occupied would wall the drone in at the edges of its
    camera's field of view and behind every obstacle, so no trajectory could
    ever leave the seen region towards a goal. Safety in unknown space comes
    from the other two layers instead: the front-end path search penalises
    unknown voxels so the initial path prefers seen free space, and the yaw
    planner keeps the drone within ``free_distance_m`` of verified free space
    (MP-CDE Sec. IV-A, Eq. 1). Outside the window every query returns the
    value of the nearest boundary voxel (``state_at`` returns unknown).
    """

    UNKNOWN: ClassVar[int] = -1
    FREE: ClassVar[int] = 0
    OCCUPIED: ClassVar[int] = 1
    __slots__ = ("time_s", "origin_world", "voxel_m", "state", "seen_s", "_distance_m", "_free_distance_m")

    def __init__(
        self,
        time_s: float,
        origin_world: np.ndarray,
        voxel_m: float,
        state: np.ndarray,
        distance_m: np.ndarray | Callable[[], np.ndarray],
        free_distance_m: np.ndarray | Callable[[], np.ndarray],
        seen_s: np.ndarray | None = None,
    ) -> None:
        init = object.__setattr__
        init(self, "time_s", time_s)
        init(self, "origin_world", origin_world)
        init(self, "voxel_m", voxel_m)
        init(self, "state", state)
        init(self, "seen_s", seen_s)
        init(self, "_distance_m", distance_m)
        init(self, "_free_distance_m", free_distance_m)
        if np.shape(self.origin_world) != (3,):
            raise ValueError(f"OccupancySnapshot.origin_world shape={np.shape(self.origin_world)}: allowed (3,)")
        if not self.voxel_m > 0.0:
            raise ValueError(f"OccupancySnapshot.voxel_m={self.voxel_m!r}: allowed > 0")
        shape = np.shape(self.state)
        if len(shape) != 3 or min(shape) < 2:
            raise ValueError(f"OccupancySnapshot.state shape={shape}: allowed (nx, ny, nz) with every n >= 2")
        for name in ("_distance_m", "_free_distance_m", "seen_s"):
            value = getattr(self, name)
            if value is not None and not callable(value) and np.shape(value) != shape:
                raise ValueError(f"OccupancySnapshot.{name.lstrip('_')} shape={np.shape(value)}: allowed {shape}")

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"OccupancySnapshot is immutable: cannot set {name!r}")

    def _layer(self, name: str) -> np.ndarray:
        value = getattr(self, name)
        if callable(value):
            value = np.asarray(value())
            if value.shape != self.state.shape:
                raise ValueError(f"OccupancySnapshot.{name.lstrip('_')} shape={value.shape}: allowed {self.state.shape}")
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        return value

    @property
    def distance_m(self) -> np.ndarray:
        """(nx, ny, nz) float32 signed ESDF [m] (computed on first read when the map deferred it)."""
        return self._layer("_distance_m")

    @property
    def free_distance_m(self) -> np.ndarray:
        """(nx, ny, nz) float32 verified-free distance [m] (computed on first read when deferred)."""
        return self._layer("_free_distance_m")

    @property
    def distance_ready(self) -> bool:
        """Whether :attr:`distance_m` is computed already (reading it costs nothing more)."""
        return not callable(self._distance_m)

    def with_distance(self, distance_m: np.ndarray) -> "OccupancySnapshot":
        """The same snapshot with another ESDF layer (nx, ny, nz) [m] (e.g. with neighbours added as obstacles)."""
        return OccupancySnapshot(
            self.time_s, self.origin_world, self.voxel_m, self.state, distance_m, self._free_distance_m, self.seen_s
        )

    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz) voxels."""
        return tuple(int(n) for n in self.state.shape)  # type: ignore[return-value]

    @property
    def upper_world(self) -> np.ndarray:
        """(3,) world position [m] of the maximum corner of the window."""
        return self.origin_world + self.voxel_m * np.asarray(self.state.shape, float)

    def world_to_index(self, points_world: np.ndarray) -> np.ndarray:
        """Voxel indices (n, 3) int64 containing ``points_world`` (n, 3) [m]; may lie outside the window."""
        p = np.asarray(points_world, float).reshape(-1, 3)
        return np.floor((p - self.origin_world) / self.voxel_m).astype(np.int64)

    def index_to_world(self, index: np.ndarray) -> np.ndarray:
        """Voxel centres (n, 3) [m] of integer indices ``index`` (n, 3)."""
        idx = np.asarray(index, float).reshape(-1, 3)
        return self.origin_world + self.voxel_m * (idx + 0.5)

    def contains(self, points_world: np.ndarray) -> np.ndarray:
        """(n,) bool: which of ``points_world`` (n, 3) [m] lie inside the window."""
        idx = self.world_to_index(points_world)
        return np.all((idx >= 0) & (idx < np.asarray(self.state.shape)), axis=1)

    def state_at(self, points_world: np.ndarray) -> np.ndarray:
        """(n,) int8 state of the voxels holding ``points_world`` (n, 3) [m]; unknown outside the window."""
        idx = self.world_to_index(points_world)
        inside = np.all((idx >= 0) & (idx < np.asarray(self.state.shape)), axis=1)
        out = np.full(idx.shape[0], self.UNKNOWN, dtype=np.int8)
        i = idx[inside]
        out[inside] = self.state[i[:, 0], i[:, 1], i[:, 2]]
        return out

    def is_verified_free(self, points_world: np.ndarray, max_age_s: float = math.inf) -> np.ndarray:
        """(n,) bool: the voxel holding each of ``points_world`` (n, 3) [m] was observed free.

        With a finite ``max_age_s`` [s] it must also have been seen (touched by
        a ray) at most that long before the snapshot's ``time_s`` (needs ``seen_s``).
        """
        free = self.state_at(points_world) == self.FREE
        if not math.isfinite(max_age_s) or self.seen_s is None:
            return free
        idx = self.world_to_index(points_world)[free]  # free voxels lie inside the window
        fresh = self.seen_s[idx[:, 0], idx[:, 1], idx[:, 2]] >= self.time_s - max_age_s
        out = np.zeros_like(free)
        out[free] = fresh
        return out

    def distance_and_gradient(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed ESDF (n,) [m] and its gradient (n, 3) at ``points_world`` (n, 3) [m].

        Trilinear interpolation between voxel centres; the gradient is the exact
        derivative of that interpolant (zero along an axis where the point is
        clamped to the window).
        """
        return trilinear(self.distance_m, self.origin_world, self.voxel_m, points_world)

    def free_distance(self, points_world: np.ndarray) -> np.ndarray:
        """Distance (n,) [m] to the nearest not-verified-free voxel at ``points_world`` (n, 3), trilinear."""
        return trilinear(self.free_distance_m, self.origin_world, self.voxel_m, points_world)[0]


def trilinear(
    field: np.ndarray, origin_world: np.ndarray, voxel_m: float, points_world: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Trilinear value (n,) and gradient (n, 3) of ``field`` (nx, ny, nz) sampled at voxel centres."""
    p = np.asarray(points_world, float).reshape(-1, 3)
    n_vox = np.asarray(field.shape)
    c = (p - origin_world) / voxel_m - 0.5  # continuous index of the voxel-centre lattice
    c_clamped = np.clip(c, 0.0, n_vox - 1.0)
    inside = c == c_clamped  # (n, 3) axes along which the gradient is not clamped away
    i0 = np.minimum(np.floor(c_clamped).astype(np.int64), n_vox - 2)
    f = c_clamped - i0  # (n, 3) fractions in [0, 1]
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    ny, nz = field.shape[1], field.shape[2]
    base = (i0[:, 0] * ny + i0[:, 1]) * nz + i0[:, 2]
    corner = np.array([0, nz, ny * nz, ny * nz + nz, 1, nz + 1, ny * nz + 1, ny * nz + nz + 1])
    # corners c_xyz in the order 000, 010, 100, 110, 001, 011, 101, 111, gathered without copying the field
    c = np.ravel(field)[base[:, None] + corner].astype(np.float64)
    c000, c010, c100, c110, c001, c011, c101, c111 = c.T
    c00 = c000 + fx * (c100 - c000)
    c10 = c010 + fx * (c110 - c010)
    c01 = c001 + fx * (c101 - c001)
    c11 = c011 + fx * (c111 - c011)
    c0 = c00 + fy * (c10 - c00)
    c1 = c01 + fy * (c11 - c01)
    value = c0 + fz * (c1 - c0)
    # d/dfx, d/dfy, d/dfz of the trilinear form
    d_fx = (1 - fy) * (1 - fz) * (c100 - c000) + fy * (1 - fz) * (c110 - c010)
    d_fx += (1 - fy) * fz * (c101 - c001) + fy * fz * (c111 - c011)
    d_fy = (1 - fz) * (c10 - c00) + fz * (c11 - c01)
    d_fz = c1 - c0
    grad = np.stack([d_fx, d_fy, d_fz], axis=1) / voxel_m
    grad[~inside] = 0.0
    return value, grad


@njit(cache=True)
def trilinear_compiled(field, origin_world, voxel_m, points_world):  # pragma: no cover - compiled
    """Compiled :func:`trilinear` for the hot paths (the optimiser's ESDF term, the map's per-frame clearance):
    value (n,) and gradient (n, 3) of ``field`` (nx, ny, nz) at ``points_world`` (n, 3) [m].

    The corners are read as float64, as :func:`trilinear` reads them, so a float32 field gives the same value
    to the bit. A point with a non-finite coordinate gets value NaN and a zero gradient (never an index).
    """
    n = points_world.shape[0]
    nx, ny, nz = field.shape
    dims = (nx, ny, nz)
    d = np.empty(n)
    g = np.zeros((n, 3))
    i0 = np.empty(3, np.int64)
    fr = np.empty(3)
    inside = np.empty(3, np.bool_)
    for k in range(n):
        if not (np.isfinite(points_world[k, 0]) and np.isfinite(points_world[k, 1]) and np.isfinite(points_world[k, 2])):
            d[k] = np.nan
            continue
        for a in range(3):
            c = (points_world[k, a] - origin_world[a]) / voxel_m - 0.5  # continuous index of the voxel-centre lattice
            cc = min(max(c, 0.0), dims[a] - 1.0)
            inside[a] = c == cc
            i0[a] = min(int(np.floor(cc)), dims[a] - 2)
            fr[a] = cc - i0[a]
        x0, y0, z0 = i0[0], i0[1], i0[2]
        fx, fy, fz = fr[0], fr[1], fr[2]
        c000, c100 = np.float64(field[x0, y0, z0]), np.float64(field[x0 + 1, y0, z0])
        c010, c110 = np.float64(field[x0, y0 + 1, z0]), np.float64(field[x0 + 1, y0 + 1, z0])
        c001, c101 = np.float64(field[x0, y0, z0 + 1]), np.float64(field[x0 + 1, y0, z0 + 1])
        c011, c111 = np.float64(field[x0, y0 + 1, z0 + 1]), np.float64(field[x0 + 1, y0 + 1, z0 + 1])
        c00 = c000 + fx * (c100 - c000)
        c10 = c010 + fx * (c110 - c010)
        c01 = c001 + fx * (c101 - c001)
        c11 = c011 + fx * (c111 - c011)
        c0 = c00 + fy * (c10 - c00)
        c1 = c01 + fy * (c11 - c01)
        d[k] = c0 + fz * (c1 - c0)
        if inside[0]:
            g[k, 0] = (
                (1 - fy) * (1 - fz) * (c100 - c000)
                + fy * (1 - fz) * (c110 - c010)
                + (1 - fy) * fz * (c101 - c001)
                + fy * fz * (c111 - c011)
            ) / voxel_m
        if inside[1]:
            g[k, 1] = ((1 - fz) * (c10 - c00) + fz * (c11 - c01)) / voxel_m
        if inside[2]:
            g[k, 2] = (c1 - c0) / voxel_m
    return d, g
