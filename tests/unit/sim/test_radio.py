"""The radio: loss statistics, jamming, range, line of sight, determinism."""

import numpy as np
import pytest

from sim.radio import Radio, RadioConfig

POS = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [0.0, 4.0, 1.0], [40.0, 0.0, 1.0]])


def run_rounds(cfg: RadioConfig, rounds: int, seed: int = 7, pos=POS, los=None) -> tuple[Radio, list[list]]:
    radio = Radio(cfg, pos.shape[0], seed, line_of_sight=los)
    received = [[] for _ in range(pos.shape[0])]
    for k in range(rounds):
        t = k / cfg.rate_hz
        for s in range(pos.shape[0]):
            radio.broadcast(s, t, ("hello", s, k), pos)
        for r in range(pos.shape[0]):
            received[r].extend(radio.receive(r, t + cfg.delay_s))
    return radio, received


def test_bernoulli_loss_rate_matches_its_probability():
    radio, _ = run_rounds(RadioConfig(loss_model="bernoulli", loss_probability=0.2), 2000, pos=POS[:3])
    n = radio.sent
    rate = radio.lost["loss"] / n
    assert abs(rate - 0.2) < 3 * np.sqrt(0.2 * 0.8 / n)


def test_gilbert_elliott_loss_is_bursty_with_its_stationary_rate():
    cfg = RadioConfig(loss_model="gilbert_elliott", ge_p_good_to_bad=0.05, ge_p_bad_to_good=0.25, ge_loss_good=0.0, ge_loss_bad=1.0)
    radio = Radio(cfg, 2, seed=3)
    lost = []
    for k in range(20000):
        before = radio.lost["loss"]
        radio.broadcast(0, k * 0.2, k, POS[:2])
        lost.append(radio.lost["loss"] > before)
    lost = np.array(lost)
    assert lost.mean() == pytest.approx(cfg.stationary_loss_rate(), abs=0.02)
    # bursty: P(lost | previous lost) = 1 - p_bad_to_good, far above the marginal rate
    p_cond = lost[1:][lost[:-1]].mean()
    assert p_cond == pytest.approx(1 - cfg.ge_p_bad_to_good, abs=0.03)


def test_jamming_window_delivers_nothing_and_the_rest_everything():
    cfg = RadioConfig(rate_hz=10.0, jamming_windows_s=((2.0, 4.0),))
    radio, received = run_rounds(cfg, 60, pos=POS[:3])
    times = [m.receive_time_s for inbox in received for m in inbox]
    assert times and not any(2.0 <= t < 4.0 for t in times)
    assert radio.lost["jamming"] == 20 * 3 * 2  # 20 rounds x 3 senders x 2 receivers
    assert radio.delivered == (60 - 20) * 6


def test_blackout_range_and_line_of_sight():
    _, received = run_rounds(RadioConfig(blackout=True), 5)
    assert all(not inbox for inbox in received)
    radio, received = run_rounds(RadioConfig(range_m=10.0), 5)
    assert all(m.sender_id != 3 for m in received[0]) and not received[3]
    blocked = lambda a, b: not (a[1] == 4.0 or b[1] == 4.0)  # noqa: E731  drone 2 is behind a wall
    radio, received = run_rounds(RadioConfig(line_of_sight_only=True), 5, los=blocked)
    assert not received[2] and radio.lost["line_of_sight"] > 0


def test_a_view_gated_radio_delivers_only_what_the_receiver_sees():
    """view_gated: j's message reaches i only while in_view(i, j); drone 0 sees 1 only, the others see nobody."""
    sees = {(0, 1)}
    radio = Radio(RadioConfig(view_gated=True), 3, seed=1, in_view=lambda r, s: (r, s) in sees)
    for s in range(3):
        radio.broadcast(s, 0.0, s, POS[:3])
    got = [[m.sender_id for m in radio.receive(r, 0.0)] for r in range(3)]
    assert got == [[1], [], []]
    assert radio.lost["view"] == 5
    with pytest.raises(ValueError, match="in_view"):
        Radio(RadioConfig(view_gated=True), 3, seed=1)


@pytest.mark.slow
def test_a_view_gated_flight_loses_the_messages_of_unseen_drones():
    """In flight, the session's in_view (camera field of view, depth range, line of sight): antipodal drones face the
    centre, so the plans of those in front get through and the rest are lost to "view"."""
    import mpcde

    cfg = mpcde.load_scenario("antipodal", mode="comm", duration_s=3.0)
    from dataclasses import replace

    cfg = replace(cfg, radio=replace(cfg.radio, view_gated=True))
    m = mpcde.fly(cfg).metrics
    lost = m["radio"]["lost"]
    assert lost.get("view", 0) > 0 and m["radio"]["delivered"] > 0


def test_delay_shifts_delivery_and_same_seed_gives_same_deliveries():
    cfg = RadioConfig(delay_s=0.15, loss_model="bernoulli", loss_probability=0.3)
    _, a = run_rounds(cfg, 50, seed=11)
    _, b = run_rounds(cfg, 50, seed=11)
    _, c = run_rounds(cfg, 50, seed=12)
    key = lambda inboxes: [[(m.sender_id, m.send_time_s) for m in inbox] for inbox in inboxes]  # noqa: E731
    assert key(a) == key(b) and key(a) != key(c)
    assert all(m.receive_time_s - m.send_time_s == pytest.approx(0.15) for m in a[0])


@pytest.mark.parametrize("field,value", [("loss_probability", 1.5), ("loss_model", "magic"), ("delay_s", -1.0), ("jamming_windows_s", ((3.0, 2.0),))])
def test_invalid_radio_settings_are_rejected_with_the_field_named(field, value):
    with pytest.raises(ValueError, match=field):
        RadioConfig(**{field: value})
