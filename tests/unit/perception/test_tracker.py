"""Tests of the multi-target tracker: association, gate, life cycle, predictions (MP-CDE Sec. IV-B)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from perception.kalman_cv import transition_matrix
from perception.tracker import (
    COASTING,
    CONFIRMED,
    TENTATIVE,
    Measurement,
    MultiTargetTracker,
    range_noise_cov,
)
from perception.tracker_config import TrackerConfig

DT = 0.04
STD = 0.03
R = STD**2 * np.eye(3)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(42)


def _meas(pos, t) -> Measurement:
    return Measurement(np.asarray(pos, float), R.copy(), float(t))


def _confirmed_tracker(rng, config=None, frames=30, vel=(1.0, 0.0, 0.0)):
    """A tracker that has followed one target moving at ``vel`` from the origin for ``frames`` frames."""
    tr = MultiTargetTracker(config or TrackerConfig())
    vel = np.asarray(vel)
    for k in range(frames):
        t = k * DT
        tr.update(t, [_meas(vel * t + rng.normal(0, STD, 3), t)])
    return tr, (frames - 1) * DT


def test_a_track_is_tentative_until_its_third_hit_then_confirmed(rng):
    tr = MultiTargetTracker()
    statuses = []
    for k in range(4):
        tr.update(k * DT, [_meas(rng.normal(0, STD, 3), k * DT)])
        statuses.append([t.status for t in tr.tracks()])
    assert statuses == [[TENTATIVE], [TENTATIVE], [CONFIRMED], [CONFIRMED]]
    assert tr.predictions(3 * DT)[0].neighbor_id == tr.tracks()[0].track_id


def test_a_lone_false_positive_dies_tentative_and_is_never_predicted(rng):
    tr = MultiTargetTracker()
    tr.update(0.0, [_meas([5.0, 5.0, 1.0], 0.0)])
    assert [t.status for t in tr.tracks()] == [TENTATIVE]
    assert tr.predictions(0.0) == []
    for k in range(1, 8):
        tr.update(k * DT, [])
    assert tr.tracks() == []


def test_two_crossing_targets_keep_their_identities(rng):
    """Two drones cross in an X at 1.5 m/s (same height); each keeps its track id throughout."""
    tr = MultiTargetTracker()
    a0, va = np.array([-3.0, -3.0, 1.5]), np.array([1.5, 1.5, 0.0])
    b0, vb = np.array([-3.0, 3.0, 1.5]), np.array([1.5, -1.5, 0.0])
    owner: dict[str, set[int]] = {"a": set(), "b": set()}
    for k in range(100):  # they meet at t = 2 s
        t = k * DT
        pa, pb = a0 + va * t, b0 + vb * t
        ms = [_meas(pa + rng.normal(0, STD, 3), t), _meas(pb + rng.normal(0, STD, 3), t)]
        tr.update(t, ms[:: 1 if k % 2 else -1])  # measurement order carries no identity
        if np.linalg.norm(pa - pb) < 0.3:
            continue  # too close to say which truth a track is nearest to
        for track in tr.tracks():
            if track.status == CONFIRMED:
                name = "a" if np.linalg.norm(track.pos_world - pa) < np.linalg.norm(track.pos_world - pb) else "b"
                owner[name].add(track.track_id)
    assert len(owner["a"]) == 1 and len(owner["b"]) == 1
    assert owner["a"] != owner["b"]
    assert len(tr.tracks()) == 2


def test_the_gate_rejects_an_outlier_and_the_track_only_predicts(rng):
    tr, t = _confirmed_tracker(rng)
    before = tr.tracks()[0]
    t1 = t + DT
    outlier = before.pos_world + before.vel_world * DT + np.array([0.0, 1.0, 0.0])  # 1 m off, 33 sigma
    tr.update(t1, [_meas(outlier, t1)])
    assert tr.last_assignment == {}
    track = next(x for x in tr.tracks() if x.track_id == before.track_id)
    np.testing.assert_allclose(track.state_world, transition_matrix(DT) @ before.state_world, atol=1e-12)
    assert track.last_seen_s == pytest.approx(t)
    born = [x for x in tr.tracks() if x.track_id != before.track_id]
    assert len(born) == 1 and born[0].status == TENTATIVE  # far outside the birth gate: a new candidate


def test_a_measurement_inside_the_birth_gate_starts_no_duplicate(rng):
    wide_birth_gate = type("WideBirthGate", (TrackerConfig,), {"birth_gate_chi2": 1e4})  # a class constant
    cfg = wide_birth_gate(gate_chi2=7.38)
    tr, t = _confirmed_tracker(rng, cfg)
    before = tr.tracks()[0]
    t1 = t + DT
    near = before.pos_world + before.vel_world * DT + np.array([0.0, 0.2, 0.0])  # outside 7.38, inside 1e4
    tr.update(t1, [_meas(near, t1)])
    assert tr.last_assignment == {}
    assert [x.track_id for x in tr.tracks()] == [before.track_id]


def test_coasting_starts_after_t_hold_with_linear_inflation_and_pruning_after_t_drop(rng):
    # the inflation rates are class constants: subclasses set them
    cfg = type("Inflating", (TrackerConfig,), {"coast_pos_inflation_m2ps": 0.5, "coast_vel_inflation_m2ps3": 2.0})()
    no_inflation = type("NotInflating", (TrackerConfig,), {"coast_pos_inflation_m2ps": 0.0, "coast_vel_inflation_m2ps3": 0.0})()
    a, t_seen = _confirmed_tracker(np.random.default_rng(3), cfg)
    b, _ = _confirmed_tracker(np.random.default_rng(3), no_inflation)
    times = t_seen + DT * np.arange(1, 30)
    status, pos_var_gap = {}, {}
    for t in times:
        a.update(t, [])
        b.update(t, [])
        ta, tb = a.tracks(), b.tracks()
        status[round(t - t_seen, 2)] = ta[0].status if ta else None
        if ta:
            pos_var_gap[round(t - t_seen, 2)] = ta[0].cov_world[0, 0] - tb[0].cov_world[0, 0]
    assert status[0.56] == CONFIRMED and status[0.6] == CONFIRMED  # unseen for exactly t_hold: not yet
    assert status[0.64] == COASTING and status[1.0] == COASTING
    assert status[1.04] is None  # pruned once unseen for more than t_drop
    assert pos_var_gap[0.6] == 0.0
    assert pos_var_gap[0.64] == pytest.approx(0.5 * 0.04, rel=1e-9)  # c_p (t - t_seen - t_hold), one step
    assert pos_var_gap[0.72] > pos_var_gap[0.68] > pos_var_gap[0.64]  # and it keeps growing


def test_a_redetected_coasting_track_is_confirmed_again(rng):
    tr, t_seen = _confirmed_tracker(rng)
    track = tr.tracks()[0]
    t = t_seen
    for _ in range(18):  # 0.72 s unseen
        t += DT
        tr.update(t, [])
    assert tr.tracks()[0].status == COASTING
    t += DT
    tr.update(t, [_meas(track.pos_world + track.vel_world * (t - t_seen), t)])
    assert tr.tracks()[0].status == CONFIRMED
    assert tr.tracks()[0].track_id == track.track_id


def test_predictions_follow_eq12_with_last_seen_as_stamp(rng):
    tr, t_seen = _confirmed_tracker(rng, vel=(0.5, -1.0, 0.2))
    t_now = t_seen + 3 * DT
    for k in (1, 2, 3):
        tr.update(t_seen + k * DT, [])
    track = tr.tracks()[0]
    (pred,) = tr.predictions(t_now)
    assert pred.source == "perception" and pred.neighbor_id == track.track_id
    assert pred.stamp_s == pytest.approx(t_seen)
    assert pred.age_s(t_now) == pytest.approx(3 * DT)
    for tau in (0.0, 0.3, 1.2):
        np.testing.assert_allclose(pred.position(t_now + tau), track.pos_world + track.vel_world * tau, atol=1e-12)
        F = transition_matrix(tau)
        np.testing.assert_allclose(pred.position_cov(t_now + tau)[0], (F @ track.cov_world @ F.T)[:3, :3], atol=1e-12)
    # asked for a later time, the prediction is the track propagated by Eq. 9 (with process noise)
    (later,) = tr.predictions(t_now + 0.5)
    np.testing.assert_allclose(later.pos_world[0], track.pos_world + 0.5 * track.vel_world, atol=1e-12)
    assert np.trace(later.cov_world) > np.trace(pred.position_cov(t_now + 0.5)[0])


def test_numba_and_filterpy_backends_agree_on_a_cluttered_scene():
    """Births, misses, false positives, pruning and the AKF adaptation: identical tracks to 1e-9."""
    rng = np.random.default_rng(5)
    cfg = TrackerConfig(filter="akf")
    fast, ref = MultiTargetTracker(cfg, "numba"), MultiTargetTracker(cfg, "filterpy")
    starts = rng.uniform(-4, 4, (3, 3))
    vels = rng.normal(0, 1.0, (3, 3))
    for k in range(120):
        t = k * DT
        ms = [
            Measurement(p + v * t + 0.3 * np.sin(t) + rng.normal(0, 0.05, 3), range_noise_cov(4.0), t)
            for p, v in zip(starts, vels)
            if rng.random() > 0.2 and not (40 <= k < 70 and p is starts[0])
        ]
        if rng.random() < 0.1:
            ms.append(Measurement(rng.uniform(-6, 6, 3), range_noise_cov(6.0), t))
        fast.update(t, ms)
        ref.update(t, ms)
        a, b = fast.tracks(), ref.tracks()
        assert [(x.track_id, x.status, x.hits) for x in a] == [(x.track_id, x.status, x.hits) for x in b]
        for x, y in zip(a, b):
            np.testing.assert_allclose(x.state_world, y.state_world, atol=1e-9)
            np.testing.assert_allclose(x.cov_world, y.cov_world, atol=1e-9)
            np.testing.assert_allclose(x.acc_cov, y.acc_cov, atol=1e-9)
    assert any(np.trace(x.acc_cov) > 0 for x in fast.tracks())


def test_bad_input_is_refused_with_a_clear_message(rng):
    tr = MultiTargetTracker()
    tr.update(1.0, [])
    with pytest.raises(ValueError, match="time_s"):
        tr.update(0.5, [])
    with pytest.raises(ValueError, match="Measurement.time_s"):
        tr.update(1.1, [_meas([0, 0, 0], 1.0)])
    with pytest.raises(ValueError, match="pos_world"):
        Measurement(np.zeros(2), R, 0.0)
    with pytest.raises(ValueError, match="backend"):
        MultiTargetTracker(backend="cuda")


@pytest.mark.parametrize(
    "field, value",
    [
        ("filter", "ukf"),
        ("alpha_ema", 0.0),
        ("alpha_ema", 1.5),
        ("sigma_acc_mps2", -1.0),
        ("gate_chi2", float("nan")),
        ("gate_chi2", 50.0),  # past the birth gate (40)
        ("t_drop_s", 0.5),
        ("confirm_hits", 0),
        ("confirm_hits", True),
        ("coast_pos_inflation_m2ps", -0.1),
        ("sigma_acc_max_mps2", 0.1),
    ],
)
def test_config_validation_names_the_field(field, value):
    with pytest.raises(ValueError, match=f"^{field}="):
        if field in {f.name for f in dataclasses.fields(TrackerConfig)}:
            TrackerConfig(**{field: value})
        else:  # a class constant: a subclass overrides it
            type("Overridden", (TrackerConfig,), {field: value})()


def test_config_defaults_follow_mp_cde_table_i():
    cfg = TrackerConfig()
    assert (cfg.alpha_ema, cfg.t_hold_s, cfg.t_drop_s, cfg.filter) == (0.3, 0.6, 1.0, "akf")
    assert cfg.adaptive and not TrackerConfig(filter="kf").adaptive


@pytest.mark.parametrize("backend", ["numba", "filterpy"])
def test_conflicting_gates_are_resolved_by_the_minimum_cost_assignment(backend):
    """Two tracks 0.1 m apart, both measurements inside both gates: the pairing of least total d2 wins."""
    cfg = TrackerConfig(filter="kf")
    tr = MultiTargetTracker(cfg, backend)
    a, b = np.array([0.0, 0.0, 1.0]), np.array([0.1, 0.0, 1.0])
    for k in range(5):
        tr.update(k * DT, [_meas(a, k * DT), _meas(b, k * DT)])
    (ta, tb) = sorted(tr.tracks(), key=lambda x: x.pos_world[0])
    t = 5 * DT
    za, zb = a + [0.03, 0.0, 0.0], b + [0.03, 0.0, 0.0]  # za is 0.07 m from track b, inside its gate too
    tr.update(t, [_meas(zb, t), _meas(za, t)])
    x = {ta.track_id: ta.state_world, tb.track_id: tb.state_world}

    def d2(track, z):  # without the process noise: a lower bound on S, so an upper bound on d2
        S = (transition_matrix(DT) @ tr_cov[track] @ transition_matrix(DT).T)[:3, :3] + R
        nu = z - (transition_matrix(DT) @ x[track])[:3]
        return nu @ np.linalg.solve(S, nu)

    tr_cov = {ta.track_id: ta.cov_world, tb.track_id: tb.cov_world}
    assert d2(ta.track_id, zb) < cfg.gate_chi2 and d2(tb.track_id, za) < cfg.gate_chi2  # a real conflict
    assert tr.last_assignment == {ta.track_id: 1, tb.track_id: 0}
