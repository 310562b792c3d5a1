"""Scores the onboard neighbour tracks of a flight against ground truth (metrics only).

At every frame delivery the loop hands the true state and each perceiving
agent's track predictions at that instant (what its planner would read). Per
observer, the predictions are matched one-to-one to the TRUE other drones by
the Hungarian algorithm on Euclidean distance (``scipy.optimize.linear_sum_assignment``);
a pair farther than ``match_gate_m`` is not a match. Reported (``metrics.json``):

* ``tracking_pos_rmse_m`` / ``tracking_vel_rmse_mps``: root mean square 3-D
  position / velocity error of matched predictions (DESIGN.md: "tracking RMSE
  of position and velocity");
* ``track_samples`` (matched) and ``false_track_samples`` (unmatched predictions);
* ``neighbours_tracked_within_m`` and ``neighbours_tracked_fraction``: of the
  (observer, neighbour) pairs closer than ``near_m`` (3 m by default), the
  fraction that had a matched track at that instant: how aware each drone was
  of the drones that could hit it (this is what active yaw is for).

Ground truth enters here and in :mod:`mpcde.flight.metrics` only; agents never see it.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from perception.types import NeighborPrediction

__all__ = ["TrackingScore"]


class TrackingScore:
    """Accumulates track errors over a flight.

    Args:
        match_gate_m: a prediction farther than this [m] from every unmatched true drone is a false track.
        near_m: neighbours closer than this [m] count in the awareness fraction.
    """

    def __init__(self, match_gate_m: float = 1.0, near_m: float = 3.0) -> None:
        self.match_gate_m, self.near_m = float(match_gate_m), float(near_m)
        self.sq_pos = self.sq_vel = 0.0
        self.matched = self.false = 0
        self.near_pairs = self.near_tracked = 0
        self.used = False

    def update(
        self, observer: int, predictions: Sequence[NeighborPrediction], time_s: float,
        pos_world: np.ndarray, vel_world: np.ndarray, alive: np.ndarray,
    ) -> None:
        """Score one observer's predictions at ``time_s`` [s].

        Args:
            observer: the observing drone's index.
            predictions: its track predictions.
            pos_world, vel_world: (N, 3) true states of all drones at ``time_s``.
            alive: (N,) bool, drones still flying (failed drones are not neighbours).
        """
        self.used = True
        others = np.flatnonzero(alive & (np.arange(len(alive)) != observer))
        dist_true = np.linalg.norm(pos_world[others] - pos_world[observer], axis=1)
        near = dist_true < self.near_m
        self.near_pairs += int(np.count_nonzero(near))
        if not predictions:
            return
        p = np.array([nb.position(time_s) for nb in predictions])
        v = np.array([nb.vel_world[-1] for nb in predictions])
        if others.size == 0:
            self.false += len(predictions)
            return
        cost = np.linalg.norm(p[:, None, :] - pos_world[others][None, :, :], axis=2)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] <= self.match_gate_m
        rows, cols = rows[ok], cols[ok]
        self.matched += rows.size
        self.false += len(predictions) - rows.size
        self.sq_pos += float(np.sum((p[rows] - pos_world[others[cols]]) ** 2))
        self.sq_vel += float(np.sum((v[rows] - vel_world[others[cols]]) ** 2))
        self.near_tracked += int(np.count_nonzero(near[cols]))

    def result(self) -> dict:
        """The metrics above (empty if no agent perceived)."""
        if not self.used:
            return {}
        n = self.matched
        return {
            "tracking_pos_rmse_m": float(np.sqrt(self.sq_pos / n)) if n else None,
            "tracking_vel_rmse_mps": float(np.sqrt(self.sq_vel / n)) if n else None,
            "track_samples": int(n),
            "false_track_samples": int(self.false),
            "neighbours_tracked_within_m": self.near_m,
            "neighbours_tracked_fraction": float(self.near_tracked / self.near_pairs) if self.near_pairs else None,
        }
