"""Why a perceiving flight collided: re-fly it with a recorder and name each collision's cause (issue 29, part 5).

A flight is deterministic for its seed, so a collision found in a sweep can
be flown again with the same configuration and watched. :func:`explain_flight`
steps a :class:`mpcde.flight.session.FlightSession` and records, at every
camera delivery and for every ordered pair of drones (i, j): whether j was in
i's frame (pixels of j in the true segmentation), whether i's detector found
it (a box holding j's mask centroid), whether i tracked it (a track
prediction within :data:`TRACK_GATE_M` of j's true position) and i's current
plan (the denied stack's MINCO trajectory). Truth is used here only to judge;
the flight is the flight ``mpcde fly`` flies.

Each collision event of the metrics gets one cause, the first that holds in
this order (each drone-drone check is made both ways, i about j and j about
i, and the event takes the first cause either direction shows):

* ``fallback``: a drone of the event was braking (its optimiser had failed;
  ``DeniedAgent.braking``) at the event and already :data:`BEFORE_S` before
  it (a brake that began later is the drone's reaction to what it has just
  seen, and the checks below name what it saw too late);
* ``control overshoot``: the references were clear by
  :data:`CONTROL_MARGIN_M` (drone-drone: the two reference positions at least
  2 r + margin apart; obstacle: the reference's exact obstacle distance at
  least r + margin) but the true positions were not: the controller did not
  follow;
* ``never in view``: the other drone had no pixel in the drone's frames in
  the :data:`LOOKBACK_S` before the event (the yaw planner never looked);
* ``late detection``: it was in view, but first detected less than
  :data:`LATE_S` before the event (or never);
* ``track loss``: it was detected before, but :data:`BEFORE_S` before the
  event no track was within :data:`TRACK_GATE_M` of it;
* ``optimiser local minimum``: it was tracked, and the plan the drone flew
  :data:`BEFORE_S` before the event passes within 2 r of that track's
  prediction over the next second (the optimiser accepted a conflicting plan);
* ``prediction error``: tracked, the plan cleared the prediction, but the
  neighbour went elsewhere;
* obstacle events: ``map miss`` when the drone's map had no occupied voxel
  within one voxel of the obstacle point it hit, else ``optimiser local
  minimum`` when its plan entered the obstacle, else ``prediction error`` is
  not possible and the cause is ``unexplained``;
* ``comm mode``: an ``auto`` drone flying DMPC at the event (its neighbours
  came from radio plans; see docs/results/comm_safety.md).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mpcde.config.scenario import ScenarioConfig
from sim.camera import VIEW as WHERE
from sim.obstacles import ObstacleField
from sim.rotations import rotation_from_quat_xyzw, yaw_from_rotation

__all__ = ["BEFORE_S", "CAUSES", "CONTROL_MARGIN_M", "LATE_S", "LOOKBACK_S", "TRACK_GATE_M", "WHERE", "CollisionCause", "explain_flight"]

LOOKBACK_S = 2.0
"""How far back [s] the record reaches for "in view" and "detected"."""
LATE_S = 0.5
"""A first detection nearer than this [s] to the event is late."""
BEFORE_S = 0.3
"""Time [s] before the event at which tracks and plans are judged (what the drone acted on)."""
TRACK_GATE_M = 1.0
"""A track prediction within this [m] of the neighbour's true position tracks it."""
CONTROL_MARGIN_M = 0.1
"""References at least this [m] clear of contact (2 r apart, or r from an obstacle, plus this) make a collision the controller's."""
CAUSES = (
    "fallback", "control overshoot", "never in view", "late detection", "track loss",
    "optimiser local minimum", "prediction error", "map miss", "comm mode", "unexplained",
)  # fmt: skip


@dataclass
class CollisionCause:
    """One collision event and its cause.

    Attributes:
        time_s: event time [s].
        kind: ``"drone"`` or ``"obstacle"``.
        drones: the drones of the event.
        cause: one of :data:`CAUSES`.
        detail: what the checks saw (per direction for drone events).
    """

    time_s: float
    kind: str
    drones: list[int]
    cause: str
    detail: dict[str, Any] = field(default_factory=dict)


@dataclass
class _Tick:
    """What one camera delivery showed, for every ordered pair."""

    time_s: float
    in_view: np.ndarray  # (n, n) pixels of j in i's frame
    detected: np.ndarray  # (n, n) bool
    track_err: np.ndarray  # (n, n) distance [m] of i's nearest track to j's truth (inf: none)
    predictions: list  # per drone: its NeighborPrediction list
    plans: list  # per drone: its MINCO trajectory (or None)
    braking: np.ndarray  # (n,) bool
    comm_mode: np.ndarray  # (n,) bool
    yaw_modes: list  # per drone: the mode of its last yaw plan ("exploring", "observing", "tracking"), or None
    off_axis_deg: np.ndarray  # (n, n) true horizontal bearing of j from i's camera axis [deg], in (-180, 180]
    where: np.ndarray  # (n, n) int: index into WHERE (sim.camera.VIEW, FlightSession.view_of), where j's centre truly was for i's camera
    z_m: np.ndarray  # (n,) true altitudes [m]
    travel_off_deg: np.ndarray  # (n, n) true horizontal bearing of j from i's horizontal velocity [deg] (nan: i still)


def _denied_part(agent: Any) -> Any:
    """The MP-CDE half of an agent (the agent itself, or an auto agent's ``denied``), or None."""
    if hasattr(agent, "trajectory") and hasattr(agent, "map"):
        return agent
    return getattr(agent, "denied", None)


class _Recorder:
    """Hooks the agents' frames and keeps the last :data:`LOOKBACK_S` of deliveries."""

    def __init__(self, session: Any) -> None:
        self.session = session
        n = session.n
        self.n = n
        self.ticks: deque[_Tick] = deque()
        self.boxes: list[list] = [[] for _ in range(n)]
        # the whole flight's history, one entry per delivery: time, and per ordered pair whether j was in i's
        # frame, detected by i, tracked by i (for "when did i last know of j", beyond the look-back)
        self.history_t: list[float] = []
        self.history: list[np.ndarray] = []  # (3, n, n) bool: in view, detected, tracked
        for a in session.agents:
            original = a.on_frame

            def on_frame(frame, detections=None, _i=a.drone_id, _orig=original):  # noqa: ANN001, ANN202
                self.boxes[_i] = [] if detections is None else [np.asarray(d.box_xyxy, float) for d in detections]
                return _orig(frame, detections)

            a.on_frame = on_frame

    def record(self, t: float) -> None:
        s, n = self.session, self.n
        truth = s.truth
        in_view = np.zeros((n, n), int)
        detected = np.zeros((n, n), bool)
        for i in range(n):
            seg = s.segmentations[i]
            if seg is None:
                continue
            mask = seg.drone_index_mask
            for j in range(n):
                if j == i:
                    continue
                vs, us = np.nonzero(mask == j)
                in_view[i, j] = us.size
                if us.size:
                    cu, cv = us.mean(), vs.mean()
                    detected[i, j] = any(b[0] - 2 <= cu <= b[2] + 2 and b[1] - 2 <= cv <= b[3] + 2 for b in self.boxes[i])
        track_err = np.full((n, n), np.inf)
        predictions, plans = [], []
        braking, comm_mode = np.zeros(n, bool), np.zeros(n, bool)
        yaw_modes: list = []
        for i, a in enumerate(s.agents):
            denied = _denied_part(a)
            preds = denied.neighbours(t, count=False) if denied is not None else (a.perception.predictions(t) if a.perception is not None else [])
            predictions.append(preds)
            plans.append(getattr(denied, "trajectory", None))
            braking[i] = bool(getattr(denied, "braking", False))
            comm_mode[i] = getattr(a, "mode", None) == "comm"
            heading = getattr(denied, "heading", None)
            yaw_modes.append(None if heading is None or heading.plan is None else heading.plan.mode)
            if preds:
                p = np.array([pr.position(np.array([t]))[0] for pr in preds])
                for j in range(n):
                    if j != i:
                        track_err[i, j] = float(np.min(np.linalg.norm(p - truth.pos_world[j], axis=1)))
        yaws = np.array([yaw_from_rotation(rotation_from_quat_xyzw(q)) for q in truth.quat_xyzw])
        d = truth.pos_world[None, :, :2] - truth.pos_world[:, None, :2]  # (i, j, 2): j from i
        off = np.degrees(np.arctan2(d[..., 1], d[..., 0]) - yaws[:, None])
        off = (off + 180.0) % 360.0 - 180.0
        v = truth.vel_world[:, :2]
        moving = np.hypot(v[:, 0], v[:, 1]) >= 0.1
        trav = np.degrees(np.arctan2(d[..., 1], d[..., 0]) - np.arctan2(v[:, 1], v[:, 0])[:, None])
        trav = np.where(moving[:, None], (trav + 180.0) % 360.0 - 180.0, np.nan)
        where = np.array([[s.view_of(i, j) if i != j else 0 for j in range(n)] for i in range(n)])
        self.history_t.append(t)
        self.history.append(np.stack([in_view > 0, detected, track_err <= TRACK_GATE_M]))
        self.ticks.append(_Tick(t, in_view, detected, track_err, predictions, plans, braking, comm_mode, yaw_modes, off, where, truth.pos_world[:, 2].copy(), trav))
        while self.ticks and self.ticks[0].time_s < t - LOOKBACK_S - 1e-9:
            self.ticks.popleft()

    def last_known(self, i: int, j: int, t: float) -> dict[str, float | None]:
        """How long before ``t`` [s] drone i last had j in its frame, detected it and tracked it (None: never)."""
        times = np.asarray(self.history_t)
        keep = times <= t + 1e-9
        times = times[keep]
        flags = np.stack(self.history)[keep][:, :, i, j] if keep.any() else np.zeros((0, 3), bool)  # (k, 3)
        out: dict[str, float | None] = {}
        for c, name in enumerate(("in_view", "detected", "tracked")):
            hit = np.nonzero(flags[:, c])[0]
            out[name] = None if hit.size == 0 else round(float(t - times[hit[-1]]), 2)
        return out

    def at(self, t: float) -> _Tick | None:
        """The newest record at or before ``t``."""
        best = None
        for tick in self.ticks:
            if tick.time_s <= t + 1e-9:
                best = tick
        return best


def _direction(rec: _Recorder, i: int, j: int, t_event: float, true_future: np.ndarray, times: np.ndarray, two_r: float) -> tuple[str, dict]:
    """The cause as seen from drone i about drone j (module docstring order, perception and plan checks)."""
    ticks = [k for k in rec.ticks if k.time_s <= t_event + 1e-9]
    seen = [k.time_s for k in ticks if k.in_view[i, j] > 0]
    found = [k.time_s for k in ticks if k.detected[i, j]]
    detail = {"in_view_frames": len(seen), "detected_frames": len(found)}
    # over the whole flight: how long before the event i last had j in view, detected it, tracked it
    detail["last_known_s_before"] = rec.last_known(i, j, t_event)
    modes = [k.yaw_modes[i] for k in ticks if k.yaw_modes[i] is not None]
    if modes:  # what drone i's yaw planner was doing in the look-back: the fraction of deliveries in each mode
        detail["yaw_modes"] = {m: round(modes.count(m) / len(modes), 2) for m in sorted(set(modes))}
    if ticks:
        detail["tracks_before"] = len(ticks[-1].predictions[i])
        offs = np.array([abs(float(k.off_axis_deg[i, j])) for k in ticks])
        # how far off i's camera axis j truly was: nearest in the look-back, and at the last delivery
        detail["off_axis_deg"] = {"nearest": round(float(offs.min()), 1), "last": round(float(offs[-1]), 1)}
        # where j truly was for i's camera, as fractions of the look-back's deliveries, and j's height above i
        places = [WHERE[int(k.where[i, j])] for k in ticks]
        detail["where"] = {w: round(places.count(w) / len(places), 2) for w in WHERE if w in places}
        dz = np.array([float(k.z_m[j] - k.z_m[i]) for k in ticks])
        detail["dz_m"] = {"max_abs": round(float(np.abs(dz).max()), 2), "last": round(float(dz[-1]), 2)}
        # where j was relative to i's direction of travel (0: ahead, 180: behind), over the look-back's deliveries
        trav = np.array([abs(float(k.travel_off_deg[i, j])) for k in ticks])
        if np.isfinite(trav).any():
            detail["travel_off_deg"] = {
                "min": round(float(np.nanmin(trav)), 1), "max": round(float(np.nanmax(trav)), 1),
                "last": None if np.isnan(trav[-1]) else round(float(trav[-1]), 1),
            }  # fmt: skip
    if not seen:
        return "never in view", detail
    if not found or t_event - found[0] < LATE_S:
        detail["first_detection_before_event_s"] = round(t_event - found[0], 3) if found else None
        return "late detection", detail
    before = rec.at(t_event - BEFORE_S)
    if before is None or before.track_err[i, j] > TRACK_GATE_M:
        detail["track_err_m"] = None if before is None else round(float(before.track_err[i, j]), 3)
        return "track loss", detail
    detail["track_err_m"] = round(float(before.track_err[i, j]), 3)
    plan = before.plans[i]
    if plan is None:
        return "prediction error", detail
    own = plan.pos(np.clip(times - plan.t0_s, 0.0, plan.total_duration))
    preds = before.predictions[i]
    p_now = np.array([pr.position(np.array([before.time_s]))[0] for pr in preds])
    k = int(np.argmin(np.linalg.norm(p_now - true_future[0], axis=1)))  # the track that is j
    predicted = preds[k].position(times)
    detail["plan_to_prediction_m"] = round(float(np.min(np.linalg.norm(own - predicted, axis=1))), 3)
    if detail["plan_to_prediction_m"] < two_r:
        return "optimiser local minimum", detail
    return "prediction error", detail


def explain_flight(cfg: ScenarioConfig) -> tuple[dict[str, Any], list[CollisionCause]]:
    """Fly ``cfg`` (as ``mpcde fly`` would) and name the cause of each collision event.

    Returns:
        The flight's metrics and one :class:`CollisionCause` per event of ``collision_events``.
    """
    from mpcde.flight.loop import open_session, prepare_run

    prepared = prepare_run(cfg)
    session = open_session(prepared)
    rec = _Recorder(session)
    field_ = ObstacleField(prepared.obstacles)
    r = cfg.physics.quadrotor.robot_radius_m
    causes: list[CollisionCause] = []
    pending: list[tuple[dict, float]] = []  # events waiting for the second of truth after them (all flushed once done)
    future: deque[tuple[float, np.ndarray]] = deque()
    seen_events = 0
    last_delivery = None
    try:
        while not session.done:
            truth = session.step()
            future.append((truth.time_s, truth.pos_world.copy()))
            seg_time = session.segmentations[0].time_s if session.segmentations[0] is not None else None
            if seg_time is not None and seg_time != last_delivery:
                rec.record(truth.time_s)
                last_delivery = seg_time
            events = session.metrics.events
            while seen_events < len(events):
                pending.append((events[seen_events], _ref_at(session, events[seen_events]["time_s"])))
                seen_events += 1
            while pending and (session.done or truth.time_s >= pending[0][0]["time_s"] + 1.0):
                ev, ref = pending.pop(0)
                causes.append(_classify(ev, ref, rec, future, field_, r, session))
        return session.result().metrics, causes
    finally:
        session.close()


def _ref_at(session: Any, t: float) -> np.ndarray | None:
    """The logged reference positions (n, 3) nearest before ``t``."""
    rows = session.log.rows
    if not rows["time_s"]:
        return None
    k = int(np.searchsorted(np.asarray(rows["time_s"]), t + 1e-9)) - 1
    return np.asarray(rows["ref_pos_world"][max(k, 0)], float)


def _classify(ev: dict, ref: np.ndarray | None, rec: _Recorder, future: deque, field_: ObstacleField, r: float, session: Any) -> CollisionCause:
    t = float(ev["time_s"])
    drones = list(ev["drones"])
    tick = rec.at(t)
    out = CollisionCause(t, ev["kind"], drones, "unexplained")
    if tick is not None and any(tick.comm_mode[d] for d in drones):
        out.cause = "comm mode"
        return out
    before = rec.at(t - BEFORE_S)
    if tick is not None and before is not None and any(tick.braking[d] and before.braking[d] for d in drones):
        out.cause = "fallback"
        return out
    window = [(s, p) for s, p in future if t - BEFORE_S - 1e-9 <= s <= t + 1.0]  # truth from BEFORE_S before to 1 s after
    times = np.array([s for s, _ in window])
    truths = np.array([p for _, p in window])
    if ev["kind"] == "drone":
        i, j = drones
        out.detail["ref_distance_m"] = None if ref is None else round(float(np.linalg.norm(ref[i] - ref[j])), 3)
        if ref is not None and np.linalg.norm(ref[i] - ref[j]) >= 2 * r + CONTROL_MARGIN_M:
            out.cause = "control overshoot"
            return out
        labels = {}
        for a, b in ((i, j), (j, i)):
            labels[f"{a}->{b}"] = _direction(rec, a, b, t, truths[:, b], times, 2 * r)
        out.detail.update({k: {"cause": v[0], **v[1]} for k, v in labels.items()})
        order = {c: n for n, c in enumerate(CAUSES)}
        out.cause = min((v[0] for v in labels.values()), key=lambda c: order[c])
        return out
    (i,) = drones
    if ref is not None and float(field_.distance(ref[i][None])[0]) >= r + CONTROL_MARGIN_M:
        out.cause = "control overshoot"
        return out
    denied = _denied_part(session.agents[i])
    pos = truths[np.argmin(np.abs(times - t)), i] if times.size else None
    if denied is None or pos is None:
        return out
    snap = denied.map.snapshot()
    occupied = _near_occupied(snap, pos, r)
    out.detail["mapped"] = occupied
    if not occupied:
        out.cause = "map miss"
        return out
    before = rec.at(t - BEFORE_S)
    plan = before.plans[i] if before is not None else None
    if plan is not None:
        own = plan.pos(np.clip(times - plan.t0_s, 0.0, plan.total_duration))
        out.detail["plan_obstacle_distance_m"] = round(float(np.min(field_.distance(own))), 3)
        if out.detail["plan_obstacle_distance_m"] < r:
            out.cause = "optimiser local minimum"
    return out


def _near_occupied(snap: Any, pos: np.ndarray, r: float) -> bool:
    """Whether the map has an occupied voxel within r + one voxel of ``pos`` (3,) [m]."""
    v = snap.voxel_m
    reach = r + 2 * v
    idx = np.floor((pos - snap.origin_world) / v).astype(int)
    k = int(np.ceil(reach / v))
    lo = np.maximum(idx - k, 0)
    hi = np.minimum(idx + k + 1, np.asarray(snap.state.shape))
    if np.any(hi <= lo):
        return False
    block = snap.state[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]]
    return bool(np.any(block == 1))
