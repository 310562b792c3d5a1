"""The simulated radio: broadcast with delay, loss, range, line of sight, jamming.

Every broadcast is decided per receiver, in a fixed order, from one seeded
generator, so a run is reproducible. A message is lost when any of these holds
(the first that applies is counted as the cause):

1. ``blackout``: nothing is ever delivered;
2. ``range``: sender-receiver distance above ``range_m`` at send time;
3. ``line_of_sight``: an obstacle blocks the straight line (when enabled);
4. ``view``: with ``view_gated``, the sender is not in the receiver's camera
   view at send time (outside its field of view or depth range, or hidden by
   an obstacle): MP-CDE's rule for making the communicating baselines
   comparable (Sec. V-B 3: "communication is permitted only when other
   quadrotors are within the FoV");
5. ``jamming``: the delivery time falls in a jamming window (receivers deaf
   from t1 to t2, closed-open);
6. ``loss``: the link's loss model drops it: Bernoulli with probability p, or
   Gilbert-Elliott, a two-state Markov chain per directed link advanced once
   per message (good -> bad with ``ge_p_good_to_bad``, bad -> good with
   ``ge_p_bad_to_good``; loss probability ``ge_loss_good`` / ``ge_loss_bad``
   in each state). Its stationary loss rate is
   ``(pi_g l_g + pi_b l_b)`` with ``pi_b = p_gb / (p_gb + p_bg)``.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from sim.checks import ConfigError
from sim.types import RadioMessage

__all__ = ["Radio", "RadioConfig"]

LossCause = str


@dataclass(frozen=True)
class RadioConfig:
    """Radio channel settings.

    Attributes:
        rate_hz: broadcast rounds per second [Hz] (DMPC round T = 0.2 s -> 5 Hz).
        delay_s: delivery delay [s] after sending.
        loss_model: ``"none"``, ``"bernoulli"`` or ``"gilbert_elliott"``.
        loss_probability: Bernoulli drop probability in [0, 1].
        ge_p_good_to_bad: Gilbert-Elliott transition good -> bad per message.
        ge_p_bad_to_good: Gilbert-Elliott transition bad -> good per message.
        ge_loss_good: drop probability in the good state.
        ge_loss_bad: drop probability in the bad state.
        range_m: maximum link distance [m] (``inf`` for no limit).
        line_of_sight_only: drop messages whose straight path an obstacle blocks.
        view_gated: deliver a message only if its sender was in the receiver's
            camera view at send time (module docstring, cause 4).
        jamming_windows_s: ((t1, t2), ...) windows [s] when receivers are deaf.
        blackout: deliver nothing at all.
    """

    rate_hz: float = 5.0
    delay_s: float = 0.0
    loss_model: str = "none"
    loss_probability: float = 0.0
    ge_p_good_to_bad: float = 0.05
    ge_p_bad_to_good: float = 0.3
    ge_loss_good: float = 0.0
    ge_loss_bad: float = 1.0
    range_m: float = float("inf")
    line_of_sight_only: bool = False
    view_gated: bool = False
    jamming_windows_s: tuple[tuple[float, float], ...] = field(default=())
    blackout: bool = False

    def __post_init__(self) -> None:
        if not self.rate_hz > 0:
            raise ConfigError("rate_hz", self.rate_hz, "must be > 0")
        if not self.delay_s >= 0:
            raise ConfigError("delay_s", self.delay_s, "must be >= 0")
        if self.loss_model not in ("none", "bernoulli", "gilbert_elliott"):
            raise ConfigError("loss_model", self.loss_model, "allowed 'none', 'bernoulli', 'gilbert_elliott'")
        for name in ("loss_probability", "ge_p_good_to_bad", "ge_p_bad_to_good", "ge_loss_good", "ge_loss_bad"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ConfigError(name, v, "a probability in [0, 1]")
        if not self.range_m > 0:
            raise ConfigError("range_m", self.range_m, "must be > 0 (inf for no limit)")
        for w in self.jamming_windows_s:
            if len(w) != 2 or not w[0] < w[1]:
                raise ConfigError("jamming_windows_s", self.jamming_windows_s, "pairs (t1, t2) with t1 < t2")

    def stationary_loss_rate(self) -> float:
        """Long-run drop probability of the loss model alone."""
        if self.loss_model == "bernoulli":
            return self.loss_probability
        if self.loss_model == "gilbert_elliott":
            pi_b = self.ge_p_good_to_bad / (self.ge_p_good_to_bad + self.ge_p_bad_to_good)
            return (1 - pi_b) * self.ge_loss_good + pi_b * self.ge_loss_bad
        return 0.0

    def jammed(self, time_s: float) -> bool:
        """Whether receivers are deaf at ``time_s`` [s]."""
        return any(t1 <= time_s < t2 for t1, t2 in self.jamming_windows_s)


class Radio:
    """Broadcast channel among N drones.

    Args:
        config: channel settings.
        n_drones: number of drones.
        seed: seed of the channel's random decisions.
        line_of_sight: ``f(p_a (3,), p_b (3,)) -> bool``, needed when
            ``config.line_of_sight_only`` (the world's ray test).
        in_view: ``f(receiver, sender) -> bool``, whether the sender is in the
            receiver's camera view now; needed when ``config.view_gated``.
    """

    def __init__(
        self, config: RadioConfig, n_drones: int, seed: int, line_of_sight: Callable[[np.ndarray, np.ndarray], bool] | None = None,
        in_view: Callable[[int, int], bool] | None = None,
    ) -> None:  # fmt: skip
        if config.line_of_sight_only and line_of_sight is None:
            raise ValueError("line_of_sight_only=True needs a line_of_sight function")
        if config.view_gated and in_view is None:
            raise ValueError("view_gated=True needs an in_view function")
        self.in_view = in_view
        self.config = config
        self.n = n_drones
        self.rng = np.random.default_rng([seed, 0x4AD10])
        self.line_of_sight = line_of_sight
        self.link_bad = np.zeros((n_drones, n_drones), bool)  # Gilbert-Elliott state per directed link
        self.pending: list[RadioMessage] = []
        self.inboxes: list[list[RadioMessage]] = [[] for _ in range(n_drones)]
        self.sent = 0
        self.delivered = 0
        self.latency_sum_s = 0.0  # sum of send-to-delivery times of the delivered messages [s]
        self.lost: Counter[LossCause] = Counter()

    def _drop_by_loss_model(self, sender: int, receiver: int) -> bool:
        c = self.config
        u = self.rng.uniform()
        if c.loss_model == "bernoulli":
            return u < c.loss_probability
        if c.loss_model == "gilbert_elliott":
            bad = self.link_bad[sender, receiver]
            flip = self.rng.uniform() < (c.ge_p_bad_to_good if bad else c.ge_p_good_to_bad)
            bad = bad ^ flip
            self.link_bad[sender, receiver] = bad
            return u < (c.ge_loss_bad if bad else c.ge_loss_good)
        return False

    def broadcast(self, sender: int, time_s: float, payload: Any, pos_world: np.ndarray) -> None:
        """Send ``payload`` from ``sender`` at ``time_s`` [s] to every other drone.

        Args:
            pos_world: (N, 3) true positions at send time (the channel's physics).
        """
        c = self.config
        receive_time = time_s + c.delay_s
        for r in range(self.n):
            if r == sender:
                continue
            self.sent += 1
            cause = None
            # the loss model advances for every message so the chain's statistics do not depend on the other causes
            dropped = self._drop_by_loss_model(sender, r)
            if c.blackout:
                cause = "blackout"
            elif np.linalg.norm(pos_world[r] - pos_world[sender]) > c.range_m:
                cause = "range"
            elif c.line_of_sight_only and not self.line_of_sight(pos_world[sender], pos_world[r]):
                cause = "line_of_sight"
            elif c.view_gated and not self.in_view(r, sender):
                cause = "view"
            elif c.jammed(receive_time):
                cause = "jamming"
            elif dropped:
                cause = "loss"
            if cause is not None:
                self.lost[cause] += 1
                continue
            self.pending.append(RadioMessage(sender_id=sender, send_time_s=time_s, receive_time_s=receive_time, payload=(r, payload)))

    def deliver(self, time_s: float) -> None:
        """Move every message due by ``time_s`` [s] into its receiver's inbox."""
        keep = []
        for m in self.pending:
            if m.receive_time_s <= time_s + 1e-12:
                r, payload = m.payload
                self.inboxes[r].append(RadioMessage(m.sender_id, m.send_time_s, m.receive_time_s, payload))
                self.delivered += 1
                self.latency_sum_s += m.receive_time_s - m.send_time_s
            else:
                keep.append(m)
        self.pending = keep

    def receive(self, receiver: int, time_s: float) -> list[RadioMessage]:
        """Empty and return ``receiver``'s inbox of messages delivered by ``time_s``."""
        self.deliver(time_s)
        out, self.inboxes[receiver] = self.inboxes[receiver], []
        return out

    def stats(self) -> dict[str, Any]:
        """Counts of messages sent (per receiver), delivered and lost by cause; the loss model and delay that applied.

        ``lost["loss"]`` counts the random losses of ``loss_model`` (named
        beside it, so a Bernoulli and a Gilbert-Elliott channel are told apart);
        ``mean_latency_s`` is the mean send-to-delivery time of the delivered
        messages (``delay_s`` on this channel; None before any).
        """
        return {
            "sent": self.sent, "delivered": self.delivered, "lost": dict(sorted(self.lost.items())),
            "loss_model": self.config.loss_model, "delay_s": self.config.delay_s,
            "mean_latency_s": self.latency_sum_s / self.delivered if self.delivered else None,
        }  # fmt: skip
