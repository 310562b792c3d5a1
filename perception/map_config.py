"""Settings of a drone's local occupancy map and its ESDF (frozen, validated)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from sim.checks import ConfigError

__all__ = ["MapConfig"]


@dataclass(frozen=True)
class MapConfig:
    """Occupancy window, ray casting and ESDF settings.

    Log-odds defaults are OctoMap's (Hornung et al. 2013): hit probability 0.7,
    miss 0.4, clamping at 0.12 / 0.97.

    Class constants (:data:`typing.ClassVar`, not fields: no scenario, sweep or
    preset sets them, so a scenario file that names one is refused as an
    unknown key; docs/design.md section 7): ``min_range_m``,
    ``clear_invalid_m``, ``invalid_neighborhood_px``, ``pixel_stride``,
    ``clear_stride``, ``clear_tail_voxels``, ``detection_margin_px``, the
    ``log_odds_*`` and ``esdf_max_m``. A test or benchmark that needs another
    value overrides one in a subclass.

    Attributes:
        voxel_m: voxel edge [m], 0.1 to 0.2 (default 0.15).
        window_size_m: (3,) edge lengths [m] of the rolling window centred on
            the drone, x y z in world (default 10 x 10 x 4). Rounded up to whole
            voxels.
        min_range_m: depth readings nearer than this [m] are ignored (sensor
            minimum, D435i 0.2 m).
        max_range_m: depth readings farther than this [m] are not integrated as
            hits; their ray is cleared as free up to this range (default 10 m,
            the simulated camera's range).
        clear_invalid_m: range [m] up to which a ray through an invalid (NaN)
            pixel is cleared as free; 0 skips such rays. The simulated camera
            reports NaN for surfaces beyond ``max_range_m`` (open sky, open
            corridors: clearing lets them become verified free), for surfaces
            nearer than ``min_range_m`` (inside the drone's own collision
            radius: a collision has already happened, clearing loses nothing
            the planner could still act on) and for random stereo holes
            (``sim.camera.CameraConfig.invalid_pixel_fraction``). A hole must
            not clear through the surface around it, so a NaN ray is cleared
            only up to the nearest valid depth within
            ``invalid_neighborhood_px`` pixels, less one voxel (default 10 m;
            values above ``max_range_m`` act as ``max_range_m``).
        invalid_neighborhood_px: half-width [px] of the square neighbourhood
            whose nearest valid depth bounds the clearing of a NaN pixel
            (default 3, i.e. 7 x 7 px: an isolated hole of up to 6 px is never
            cleared through; 0 clears every NaN ray to ``clear_invalid_m``).
        pixel_stride: integrate every ``pixel_stride``-th pixel in u and v
            (1 = full resolution; default 2, i.e. a quarter of the rays; at
            0.15 m voxels and 320 x 240 px the skipped rays are redundant beyond
            about 1.5 m).
        clear_stride: traverse (clear the voxels along) the rays of every
            ``clear_stride``-th pixel in u and v whole; the other hit rays of
            the ``pixel_stride`` grid are traversed over their last
            ``clear_tail_voxels`` before the surface only (default
            4; ``pixel_stride`` or less traverses every ray). At 320 x 240 px
            and 85 deg, neighbouring rays of a stride-4 grid are 1.06 deg
            apart, 0.13 m at 7 m (the far corner of the 10 m window), less
            than a 0.15 m voxel, so the traversed rays still sweep every voxel
            column of the window; a quarter of the traversals costs a quarter
            of the time (``benchmarks/bench_map.py``; what it changes in the
            map: ``docs/results/realtime.md#the-map-the-esdf-and-the-planners``).
        clear_tail_voxels: length [voxels] of the traversed tail of a hit ray
            that is not traversed whole (default 2: the space just in front of
            a surface is cleared by every ray).
        detection_margin_px: margin [px] added on each side of a detection box
            before its pixels are masked out.
        neighbour_exclusion_m: depth hits within this distance [m] of a
            neighbour's predicted position (``OccupancyMap.update``'s
            ``neighbours_world``: its tracks and radio plans) are masked out
            like detection pixels (0.4 is the 0.1 m robot radius plus
            prediction error). Without it a neighbour the detector misses at
            close range (it fills the image) is mapped as an obstacle, and a
            trail of phantom voxels follows its path, which can block a
            follower's every plan. Default 0 (off): together with MINCO's
            ``swarm_recovery_mps`` it does not reduce collisions
            (docs/results/occupancy_map.md#neighbour_exclusion_m-on-radio_outage-seeds-0-5).
        log_odds_hit: log-odds increment [-] of the end voxel of a ray
            (logit 0.7 = 0.847).
        log_odds_miss: log-odds increment [-] of a voxel a ray passes through
            (logit 0.4 = -0.405).
        log_odds_min: lower clamp [-] (logit 0.12 = -1.99).
        log_odds_max: upper clamp [-] (logit 0.97 = 3.48).
        log_odds_occupied: a voxel is occupied above this log-odds [-] and free
            at or below it (once observed). Default 0 (probability 0.5).
        esdf_max_m: truncation distance [m]: ESDF values are clipped to
            ``[-esdf_max_m, esdf_max_m]`` (default 3 m; nothing farther matters
            to a clearance of about 1 m).
    """

    voxel_m: float = 0.15
    window_size_m: tuple[float, float, float] = (10.0, 10.0, 4.0)
    min_range_m: ClassVar[float] = 0.2
    max_range_m: float = 10.0
    clear_invalid_m: ClassVar[float] = 10.0
    invalid_neighborhood_px: ClassVar[int] = 3
    pixel_stride: ClassVar[int] = 2
    clear_stride: ClassVar[int] = 4
    clear_tail_voxels: ClassVar[float] = 2.0
    detection_margin_px: ClassVar[int] = 4
    neighbour_exclusion_m: float = 0.0
    log_odds_hit: ClassVar[float] = 0.847
    log_odds_miss: ClassVar[float] = -0.405
    log_odds_min: ClassVar[float] = -1.99
    log_odds_max: ClassVar[float] = 3.48
    log_odds_occupied: ClassVar[float] = 0.0
    esdf_max_m: ClassVar[float] = 3.0

    def __post_init__(self) -> None:
        if not 0.1 <= self.voxel_m <= 0.2:
            raise ConfigError("voxel_m", self.voxel_m, "allowed 0.1 to 0.2 m")
        w = tuple(self.window_size_m)
        if len(w) != 3 or not all(np.isfinite(x) and x >= 2 * self.voxel_m for x in w):
            raise ConfigError("window_size_m", self.window_size_m, "allowed three finite lengths >= 2 voxels")
        if not 0.0 <= self.min_range_m:
            raise ConfigError("min_range_m", self.min_range_m, "allowed >= 0 m")
        if not (np.isfinite(self.max_range_m) and self.max_range_m > self.min_range_m):
            raise ConfigError("max_range_m", self.max_range_m, f"allowed finite > min_range_m = {self.min_range_m!r} m")
        if not (np.isfinite(self.clear_invalid_m) and self.clear_invalid_m >= 0.0):
            raise ConfigError("clear_invalid_m", self.clear_invalid_m, "allowed finite >= 0 (0 = skip invalid pixels)")
        if not (isinstance(self.invalid_neighborhood_px, (int, np.integer)) and self.invalid_neighborhood_px >= 0):
            raise ConfigError("invalid_neighborhood_px", self.invalid_neighborhood_px, "allowed integer >= 0")
        if not (isinstance(self.pixel_stride, (int, np.integer)) and self.pixel_stride >= 1):
            raise ConfigError("pixel_stride", self.pixel_stride, "allowed integer >= 1")
        if not (isinstance(self.clear_stride, (int, np.integer)) and self.clear_stride >= 1):
            raise ConfigError("clear_stride", self.clear_stride, "allowed integer >= 1")
        if not (np.isfinite(self.clear_tail_voxels) and self.clear_tail_voxels >= 0.0):
            raise ConfigError("clear_tail_voxels", self.clear_tail_voxels, "allowed finite >= 0")
        if not (isinstance(self.detection_margin_px, (int, np.integer)) and self.detection_margin_px >= 0):
            raise ConfigError("detection_margin_px", self.detection_margin_px, "allowed integer >= 0")
        if not (np.isfinite(self.neighbour_exclusion_m) and self.neighbour_exclusion_m >= 0.0):
            raise ConfigError("neighbour_exclusion_m", self.neighbour_exclusion_m, "allowed finite >= 0 m")
        if not self.log_odds_hit > 0.0:
            raise ConfigError("log_odds_hit", self.log_odds_hit, "allowed > 0")
        if not self.log_odds_miss < 0.0:
            raise ConfigError("log_odds_miss", self.log_odds_miss, "allowed < 0")
        if not self.log_odds_min < self.log_odds_occupied < self.log_odds_max:
            raise ConfigError("log_odds_occupied", self.log_odds_occupied, "allowed log_odds_min < log_odds_occupied < log_odds_max")
        if not self.esdf_max_m > 0.0:
            raise ConfigError("esdf_max_m", self.esdf_max_m, "allowed > 0")

    @property
    def window_shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz) voxels of the window."""
        return tuple(int(np.ceil(x / self.voxel_m - 1e-9)) for x in self.window_size_m)  # type: ignore[return-value]
