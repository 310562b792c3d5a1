"""Neighbour by neighbour: the radio's plan while it is fresh, the camera's track when it is not.

DESIGN.md's ``auto`` mode: "neighbour by neighbour it falls back to
perception tracks when that neighbour's plan is stale". A drone's tracks are
anonymous (a track id, not a drone index) and its radio plans are named (the
sender's index), so the two are associated by where they put the neighbour
now, at the round time t:

1. *fresh* plans (age <= ``stale_after_s``) are used as they are; each
   explains at most one track: the tracks and the fresh plans are matched
   one to one by the Hungarian method on the distance between the track's
   predicted position and the plan's position at t, within ``gate_m``
   (the same assignment as the tracker's own data association). An explained
   track is the same drone seen twice and is dropped: the plan says more
   (its intent over the horizon, not a constant-velocity guess).
2. *stale* plans (age > ``stale_after_s``): the remaining tracks are matched
   to them the same way, within ``gate_m + speed_bound_mps * age``: the
   neighbour has replanned since it sent the plan, and in ``age`` seconds it
   can be at most that much further from it. A matched stale plan is
   *substituted*: the drone plans against the track (a measurement of where
   that neighbour is now), relabelled with the plan's sender index so a
   formation offset to that neighbour still applies. An unmatched stale plan
   (the neighbour is out of view) is kept, shifted in time, as the DMPC agent
   already does.
3. tracks explained by no plan are drones the radio says nothing about (lost
   every message, or never had a radio); they are kept, with the
   ``neighbor_id`` ``-1 - track_id`` (negative: not a drone index, so no
   formation offset applies).

Gating and assignment cost are Euclidean in 3-D [m]. Nothing here sees ground truth.
A track enters the DMPC QP like a plan: a constant-velocity prediction
(MP-CDE Eq. 12) under the same r_min_m; the QP does not use its covariance.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from mpcde.config.auto import FusionConfig
from perception.types import NeighborPrediction

__all__ = ["FusedNeighbours", "FusionConfig", "fuse_neighbours", "unknown_neighbour_id"]


@dataclass(frozen=True)
class FusedNeighbours:
    """The neighbours one DMPC round plans against, and where each came from.

    Attributes:
        predictions: plans and tracks to plan against (order: plans by sender, then unknown tracks).
        fresh_plans: fresh radio plans used.
        stale_plans: stale radio plans used as they are (no track matched them).
        substituted: stale plans replaced by the matched track.
        unknown_tracks: tracks that no plan explains, used as extra neighbours.
        explained_tracks: tracks dropped because a fresh plan is the same drone.
    """

    predictions: list[NeighborPrediction]
    fresh_plans: int
    stale_plans: int
    substituted: int
    unknown_tracks: int
    explained_tracks: int


def unknown_neighbour_id(track_id: int) -> int:
    """The ``neighbor_id`` of a track no plan explains: ``-1 - track_id`` (< 0, never a drone index)."""
    return -1 - int(track_id)


def _match(a: np.ndarray, b: np.ndarray, gate_m: np.ndarray) -> list[tuple[int, int]]:
    """One-to-one pairs (i, j) of rows of ``a`` (n, 3) and ``b`` (m, 3) minimising the summed distance.

    A pair is allowed when ``|a_i - b_j| <= gate_m[j]`` (gate per column, (m,)).
    """
    if len(a) == 0 or len(b) == 0:
        return []
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)
    allowed = d <= gate_m[None, :]
    big = 1e6
    rows, cols = linear_sum_assignment(np.where(allowed, d, big))
    return [(int(i), int(j)) for i, j in zip(rows, cols) if allowed[i, j]]


def fuse_neighbours(
    plans: Sequence[NeighborPrediction],
    tracks: Sequence[NeighborPrediction],
    time_s: float,
    stale_after_s: float,
    gate_m: float,
    speed_bound_mps: float,
) -> FusedNeighbours:
    """Choose, neighbour by neighbour, between its radio plan and a camera track (module docstring).

    Args:
        plans: the neighbours' radio plans (``source="radio"``, ``stamp_s`` = send time,
            ``neighbor_id`` = sender index), already without the timed-out ones.
        tracks: this drone's confirmed and coasting tracks (``source="perception"``,
            ``neighbor_id`` = track id).
        time_s: the round time t [s].
        stale_after_s: a plan older than this [s] is stale.
        gate_m: a track within this [m] of a fresh plan at t is that plan's drone.
        speed_bound_mps: the neighbours' speed limit [m/s]; a stale plan's gate grows by it times the age.

    Returns:
        The fused neighbour set and its counts.
    """
    t = float(time_s)
    ages = np.array([p.age_s(t) for p in plans])
    fresh = [p for p, a in zip(plans, ages) if a <= stale_after_s]
    stale = [(p, a) for p, a in zip(plans, ages) if a > stale_after_s]
    track_pos = np.array([tr.position(t) for tr in tracks]).reshape(-1, 3)
    left = list(range(len(tracks)))

    fresh_pos = np.array([p.position(t) for p in fresh]).reshape(-1, 3)
    pairs = _match(track_pos, fresh_pos, np.full(len(fresh), gate_m))
    explained = {i for i, _ in pairs}
    left = [i for i in left if i not in explained]

    stale_pos = np.array([p.position(t) for p, _ in stale]).reshape(-1, 3)
    stale_gate = np.array([gate_m + speed_bound_mps * a for _, a in stale])
    pairs = _match(track_pos[left], stale_pos, stale_gate)
    by_stale = {j: left[i] for i, j in pairs}
    left = [i for i in left if i not in set(by_stale.values())]

    out = list(fresh)
    for j, (plan, _) in enumerate(stale):
        if j in by_stale:
            out.append(replace(tracks[by_stale[j]], neighbor_id=plan.neighbor_id))
        else:
            out.append(plan)
    out.sort(key=lambda p: p.neighbor_id)
    out.extend(replace(tracks[i], neighbor_id=unknown_neighbour_id(tracks[i].neighbor_id)) for i in left)
    return FusedNeighbours(
        predictions=out, fresh_plans=len(fresh), stale_plans=len(stale) - len(by_stale), substituted=len(by_stale),
        unknown_tracks=len(left), explained_tracks=len(explained),
    )  # fmt: skip
