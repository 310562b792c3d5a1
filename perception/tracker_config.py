"""Configuration of the neighbour tracker (MP-CDE Sec. IV-B, Table I).

One frozen dataclass, :class:`TrackerConfig`. Every field has a default taken
from MP-CDE (Table I or the text of Sec. IV-B) where the paper gives one, and
otherwise the value chosen here with the reason in its docstring. Validation
raises ``ValueError`` with the one-line message ``"<field>=<value!r>: <allowed>"``
(perception/ may not import mpcde; mpcde turns these into ``ConfigError``).
Measurements behind the chosen defaults: docs/results/tracker.md#trackerconfig.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from sim.checks import ConfigError, require_positive

__all__ = ["FILTERS", "TrackerConfig"]

FILTERS = ("akf", "kf")
"""Allowed values of :attr:`TrackerConfig.filter`."""


@dataclass(frozen=True)
class TrackerConfig:
    """Settings of :class:`perception.tracker.MultiTargetTracker`.

    Class constants (:data:`typing.ClassVar`, not fields: no scenario, sweep or
    preset sets them, so a scenario file that names one is refused as an
    unknown key; docs/design.md section 7): ``adapt_scale``,
    ``adapt_after_hits``, ``init_vel_std_mps``, ``birth_gate_chi2``,
    ``coast_pos_inflation_m2ps``, ``coast_vel_inflation_m2ps3``,
    ``confirm_hits``, ``tentative_drop_s``, ``meas_std_floor_m`` and ``meas_std_per_range``. A
    test that needs another value overrides one in a subclass.

    Attributes:
        filter: ``"akf"`` (MP-CDE's adaptive Kalman filter: process noise by
            covariance matching on the innovation, Eq. 11) or ``"kf"`` (the
            baseline: the same constant-velocity filter with the fixed process
            noise ``sigma_acc_mps2``).
        alpha_ema: exponential smoothing factor of the adaptive process noise,
            ``Q_k = alpha Q_hat_k + (1 - alpha) Q_{k-1}`` [-] (MP-CDE Table I,
            alpha_EMA = 0.3). Used by ``"akf"`` only.
        sigma_acc_mps2: standard deviation of the white-noise acceleration of
            the fixed process noise, per axis [m/s^2]. It is the whole process
            noise of ``"kf"`` and the floor under the adaptive part of
            ``"akf"``. MP-CDE Table I gives no process noise (nor a KF
            baseline setting), so both filters share this one value and differ
            only by the adaptation. 0.5 m/s^2 suits a slowly manoeuvring or
            hovering neighbour (docs/results/tracker.md#trackerconfig).
        adapt_scale: factor ``c`` on the covariance-matching estimate of the
            adaptive acceleration covariance, ``A_hat = c K_v D+ K_v^T / dt^2``
            [-] (see :mod:`perception.kalman_cv`).
        adapt_after_hits: the adaptation starts once a track has this many
            associated measurements (birth included) [-]; before that the gain
            is dominated by the unknown initial velocity and covariance
            matching would read the velocity's convergence as acceleration.
        sigma_acc_max_mps2: cap on the adaptive acceleration, as the square
            root of the trace of one covariance-matching estimate [m/s^2].
            A neighbour's acceleration is bounded (our planners cap it at
            4 m/s^2: ``planners.trajectory_cost`` and the DMPC config); 6 m/s^2
            leaves room for a foreign drone. The cap matters when an
            association goes wrong: a swapped measurement reads as a huge
            manoeuvre, which without it widens the gates until tracks swap
            targets (docs/results/tracker.md#trackerconfig).
        init_vel_std_mps: velocity standard deviation per axis of a new track
            [m/s]. A track is born from one position with zero velocity and
            this (large) uncertainty, so its second and third measurements set
            the velocity as a two-point estimate would, weighted by their
            noise; 2 m/s covers the neighbours' top speed per axis.
        gate_chi2: chi-square gate on the squared Mahalanobis distance of the
            innovation [-]. Default 25.0, about the 99.998 % quantile of
            chi-square with 3 degrees of freedom. MP-CDE prints 7.38, which is
            the 97.5 % quantile with 2 degrees of freedom (an image-plane
            gate); on 3-D positions it keeps only about 94 % of true
            measurements, and with a CV filter that lags in turns it breaks
            tracks often (docs/results/tracker.md#trackerconfig). Set 7.38 to
            follow the paper.
        birth_gate_chi2: an unmatched measurement starts a new track only if
            its squared Mahalanobis distance to every live track exceeds this
            [-] (40, about 6 standard deviations). Without it a true
            measurement that falls just outside ``gate_chi2`` spawns a
            duplicate track that then steals measurements from the original
            (docs/results/tracker.md#trackerconfig).
        t_hold_s: a confirmed track without a matched measurement for longer
            than this keeps predicting (Eq. 9) and becomes ``coasting`` with
            linearly inflated covariance [s] (MP-CDE Table I, 0.6 s).
        t_drop_s: a track without a matched measurement for longer than this
            is pruned [s] (MP-CDE Table I, 1.0 s).
        coast_pos_inflation_m2ps: growth rate of the position variance per
            axis of a coasting track [m^2/s] (linear inflation, Sec. IV-B; the
            paper gives no rate: 0.1 m^2/s adds about 0.2 m of standard
            deviation over the 0.4 s between t_hold and t_drop).
        coast_vel_inflation_m2ps3: growth rate of the velocity variance per
            axis of a coasting track [(m/s)^2/s].
        confirm_hits: a tentative track becomes ``confirmed`` once this many
            measurements (its birth included) were associated to it [-]
            (a 3-hit rule; the paper does not state one).
        tentative_drop_s: a tentative track without a matched measurement for
            longer than this is deleted [s] (false positives die quickly).
        meas_std_floor_m: measurement noise model, standard deviation per axis
            at zero range [m]; see :func:`perception.tracker.range_noise_cov`.
        meas_std_per_range: measurement noise model, growth of the standard
            deviation per metre of range [m/m] (back-projection error grows
            with depth: std = floor + per_range * range).
    """

    filter: str = "akf"
    alpha_ema: float = 0.3
    sigma_acc_mps2: float = 0.5
    adapt_scale: ClassVar[float] = 1.0
    adapt_after_hits: ClassVar[int] = 3
    sigma_acc_max_mps2: float = 6.0
    init_vel_std_mps: ClassVar[float] = 2.0
    gate_chi2: float = 25.0
    birth_gate_chi2: ClassVar[float] = 40.0
    t_hold_s: float = 0.6
    t_drop_s: float = 1.0
    coast_pos_inflation_m2ps: ClassVar[float] = 0.1
    coast_vel_inflation_m2ps3: ClassVar[float] = 1.0
    confirm_hits: ClassVar[int] = 3
    tentative_drop_s: ClassVar[float] = 0.2
    meas_std_floor_m: ClassVar[float] = 0.02
    meas_std_per_range: ClassVar[float] = 0.01

    def __post_init__(self) -> None:
        if self.filter not in FILTERS:
            raise ConfigError("filter", self.filter, f"one of {', '.join(repr(f) for f in FILTERS)}")
        if not (isinstance(self.alpha_ema, (int, float)) and 0.0 < self.alpha_ema <= 1.0):
            raise ConfigError("alpha_ema", self.alpha_ema, "a number in (0, 1]")
        for name in (
            "sigma_acc_mps2",
            "adapt_scale",
            "sigma_acc_max_mps2",
            "init_vel_std_mps",
            "gate_chi2",
            "birth_gate_chi2",
            "t_hold_s",
            "t_drop_s",
            "tentative_drop_s",
        ):
            require_positive(name, getattr(self, name))
        if self.sigma_acc_max_mps2 < self.sigma_acc_mps2:
            raise ConfigError("sigma_acc_max_mps2", self.sigma_acc_max_mps2, f">= sigma_acc_mps2 ({self.sigma_acc_mps2!r})")
        if self.birth_gate_chi2 < self.gate_chi2:
            raise ConfigError("gate_chi2", self.gate_chi2, f"<= birth_gate_chi2 ({self.birth_gate_chi2!r})")
        if self.t_drop_s < self.t_hold_s:
            raise ConfigError("t_drop_s", self.t_drop_s, f">= t_hold_s ({self.t_hold_s!r})")
        for name in ("coast_pos_inflation_m2ps", "coast_vel_inflation_m2ps3", "meas_std_floor_m", "meas_std_per_range"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigError(name, value, "a finite number >= 0")
        if self.meas_std_floor_m == 0 and self.meas_std_per_range == 0:
            raise ConfigError("meas_std_floor_m", self.meas_std_floor_m, "> 0 when meas_std_per_range is 0 (measurement noise must be > 0)")
        for name in ("confirm_hits", "adapt_after_hits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(name, value, "an integer >= 1")

    @property
    def adaptive(self) -> bool:
        """True for the adaptive filter (``filter == "akf"``)."""
        return self.filter == "akf"
