"""Faults a scenario injects into the world: lost camera frames, detector misses and false boxes, drones that fail.

The design names these faults (``../shared/DESIGN.md`` section 5); the radio's
own faults (jamming, range, line of sight, loss, delay) live in
:mod:`sim.radio`, depth holes in :mod:`sim.camera` (``invalid_pixel_fraction``)
and pose drift in :mod:`sim.pose_estimate`. A flight survives every one and
reports it (``metrics.json`` ``faults``, :meth:`FaultInjector.report`).

* **Frame drops** (per drone): a frame is lost with ``frame_drop_probability``;
  a loss lasts ``frame_drop_burst_frames`` consecutive frames of that drone
  (a burst); inside a ``frame_drop_windows_s`` entry ``(drone, start_s,
  end_s)`` every frame of that drone (-1: of every drone) is lost. A lost
  frame never reaches the drone: no detections, no map update.
* **Detector faults**: each detection the detector returns is removed with
  ``detector_miss_probability``; ``detector_false_positive_rate`` false boxes
  per frame (Poisson mean) are added at random places (8-40 px, score
  0.5-1), as a detector fooled by clutter would.
* **Drone failures** ``(drone, time_s)``: at that time the drone's motors stop
  and it falls (:meth:`sim.world.World.fail_drone`); it stops broadcasting
  and detecting, and the others must avoid it by what they sense.

Every random decision comes from one generator seeded by the run's seed, in
the loop's fixed order, and is drawn only while its fault is enabled, so a
scenario without faults flies exactly as before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.checks import ConfigError, require_in, require_integer_at_least

__all__ = ["FaultInjector", "FaultsConfig"]


@dataclass(frozen=True)
class FaultsConfig:
    """The faults of a scenario (all off by default).

    Attributes:
        frame_drop_probability: chance that a drone's frame starts a loss, in [0, 1].
        frame_drop_burst_frames: consecutive frames a loss lasts (>= 1).
        frame_drop_windows_s: (drone, start_s, end_s) spans in which that drone
            (-1: every drone) loses every frame [s].
        detector_miss_probability: chance that each detection is removed, in [0, 1].
        detector_false_positive_rate: mean false boxes added per frame (Poisson), >= 0.
        drone_failures: (drone, time_s): the drone's motors stop at that time [s].
    """

    frame_drop_probability: float = 0.0
    frame_drop_burst_frames: int = 1
    frame_drop_windows_s: tuple[tuple[float, float, float], ...] = ()
    detector_miss_probability: float = 0.0
    detector_false_positive_rate: float = 0.0
    drone_failures: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        require_in("frame_drop_probability", self.frame_drop_probability, 0.0, 1.0)
        require_integer_at_least("frame_drop_burst_frames", self.frame_drop_burst_frames, 1)
        require_in("detector_miss_probability", self.detector_miss_probability, 0.0, 1.0)
        require_in("detector_false_positive_rate", self.detector_false_positive_rate, 0.0, 50.0)
        for i, (drone, start, end) in enumerate(self.frame_drop_windows_s):
            if drone != int(drone) or drone < -1 or not start < end:
                raise ConfigError(f"frame_drop_windows_s[{i}]", [drone, start, end], "[drone (-1: every drone), start_s, end_s] with start_s < end_s")
        for i, (drone, time_s) in enumerate(self.drone_failures):
            if drone != int(drone) or drone < 0 or not time_s >= 0:
                raise ConfigError(f"drone_failures[{i}]", [drone, time_s], "[drone index >= 0, time_s >= 0]")

    def check_drones(self, n_drones: int) -> None:
        """Refuse a fault naming a drone the scenario does not have (field names as in a scenario's ``faults``)."""
        for i, (drone, start, end) in enumerate(self.frame_drop_windows_s):
            if drone >= n_drones:
                raise ConfigError(f"frame_drop_windows_s[{i}]", [drone, start, end], f"a drone index below {n_drones} (or -1)")
        for i, (drone, time_s) in enumerate(self.drone_failures):
            if drone >= n_drones:
                raise ConfigError(f"drone_failures[{i}]", [drone, time_s], f"a drone index below {n_drones}")

    @property
    def any(self) -> bool:
        """Whether any fault is set."""
        return bool(
            self.frame_drop_probability or self.frame_drop_windows_s or self.detector_miss_probability
            or self.detector_false_positive_rate or self.drone_failures
        )  # fmt: skip


class FaultInjector:
    """Decides, in the loop's order, which frames are lost, which detections change and when drones fail; counts all of it.

    Args:
        config: the scenario's faults.
        n_drones: drones flown.
        seed: the run's seed.
        image_size_px: (width, height) of the camera [px] (where false boxes may fall).
    """

    def __init__(self, config: FaultsConfig, n_drones: int, seed: int, image_size_px: tuple[int, int]) -> None:
        self.config = config
        self.n = n_drones
        self.width, self.height = image_size_px
        self.rng = np.random.default_rng([seed, 0xFA17])
        self.burst_left = np.zeros(n_drones, int)
        self.frames_dropped = np.zeros(n_drones, int)
        self.frames_dropped_in_windows = 0
        self.detections_removed = 0
        self.false_positives_added = 0
        self.failures = sorted((float(t), int(d)) for d, t in config.drone_failures)
        self.failed_at: list[dict[str, float]] = []

    def frame_dropped(self, drone: int, time_s: float) -> bool:
        """Whether ``drone``'s frame captured at ``time_s`` [s] is lost (call once per frame, in drone order)."""
        c = self.config
        lost = False
        if any(d in (-1, drone) and start <= time_s < end for d, start, end in c.frame_drop_windows_s):
            self.frames_dropped_in_windows += 1
            lost = True
        elif self.burst_left[drone] > 0:
            self.burst_left[drone] -= 1
            lost = True
        elif c.frame_drop_probability > 0 and self.rng.uniform() < c.frame_drop_probability:
            self.burst_left[drone] = c.frame_drop_burst_frames - 1
            lost = True
        if lost:
            self.frames_dropped[drone] += 1
        return lost

    def corrupt(self, boxes: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One frame's detections (n, 4) [px] and scores (n,) with misses removed and false boxes added."""
        c = self.config
        if c.detector_miss_probability > 0 and len(boxes):
            keep = self.rng.uniform(size=len(boxes)) >= c.detector_miss_probability
            self.detections_removed += int((~keep).sum())
            boxes, scores = boxes[keep], scores[keep]
        if c.detector_false_positive_rate > 0:
            k = int(self.rng.poisson(c.detector_false_positive_rate))
            if k:
                size = self.rng.uniform(8.0, 40.0, size=(k, 2))
                u0 = self.rng.uniform(0.0, np.maximum(self.width - size[:, 0], 1.0))
                v0 = self.rng.uniform(0.0, np.maximum(self.height - size[:, 1], 1.0))
                extra = np.stack([u0, v0, u0 + size[:, 0], v0 + size[:, 1]], axis=1)
                boxes = np.concatenate([np.asarray(boxes, float).reshape(-1, 4), extra])
                scores = np.concatenate([np.asarray(scores, float), self.rng.uniform(0.5, 1.0, size=k)])
                self.false_positives_added += k
        return boxes, scores

    def failures_due(self, time_s: float) -> list[int]:
        """Drones whose failure time has come by ``time_s`` [s] (each returned once)."""
        due = []
        while self.failures and self.failures[0][0] <= time_s + 1e-9:
            t, drone = self.failures.pop(0)
            self.failed_at.append({"drone": drone, "time_s": round(time_s, 6), "scheduled_s": t})
            due.append(drone)
        return due

    def report(self) -> dict:
        """The counts for ``metrics.json`` ``faults``."""
        return {
            "frames_dropped": int(self.frames_dropped.sum()),
            "frames_dropped_per_drone": [int(v) for v in self.frames_dropped],
            "frames_dropped_in_windows": int(self.frames_dropped_in_windows),
            "detections_removed": int(self.detections_removed),
            "false_positives_added": int(self.false_positives_added),
            "drone_failures": list(self.failed_at),
        }
