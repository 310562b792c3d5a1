"""Configuration of the active yaw planner (MP-CDE Sec. IV-A, Alg. 1): :class:`YawPlannerConfig`.

Defaults come from MP-CDE (Table I and the text of Sec. IV-A: t_y = 0.1 s,
n = 12, yaw_rate_max = 2.0 rad/s, eps = 1.2, 0.1 s hysteresis, alpha = 0.6,
beta = 0.4, 72 rays, t_hold = 0.6 s) and from the camera (RealSense D435i,
85 deg x 58 deg, DESIGN.md section 4). Values the paper does not give are
marked "chosen" and say why. Validation raises :class:`sim.checks.ConfigError` with the one-line
message ``"<field>=<value!r>: <allowed>"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from sim.checks import ConfigError, require_boolean, require_integer_at_least, require_non_negative, require_one_of, require_positive

__all__ = ["YawPlannerConfig"]


@dataclass(frozen=True)
class YawPlannerConfig:
    """Settings of :class:`planners.yaw.YawPlanner`.

    Class constants (:data:`typing.ClassVar`, not fields: no scenario, sweep or
    preset sets them, so a scenario file that names one is refused as an
    unknown key; docs/design.md section 7): ``n_steps``, ``n_candidates``,
    ``epsilon``, ``hysteresis_s``, ``turn_penalty``, ``n_rays``,
    ``ray_step_m``, ``detection_range_m``, ``window_s``, ``safety_sample_s``,
    ``free_slab_half_height_m``, ``distance_eps_m``, ``visibility_sigma_ref_m``,
    ``visibility_weight_max`` and ``still_speed_mps``. A test or benchmark that
    needs another value overrides one in a subclass.

    Attributes:
        period_s: t_y, spacing of the yaw lattice's layers and the planner's
            call period [s] (MP-CDE Table I: 0.1 s).
        n_steps: n, number of lattice layers after the current yaw [-]
            (MP-CDE: 12, i.e. a 1.2 s horizon).
        n_candidates: m, candidate yaws per layer [-], spaced uniformly over
            the full circle and anchored at the current yaw (candidate 0 *is*
            the current yaw, so the lattice is reachable from it and holding
            the yaw is always a candidate). Must satisfy
            ``2 pi / m <= yaw_rate_max_radps * period_s`` so that adjacent
            candidates are connected. Chosen: 64 (spacing 0.098 rad, so an
            edge may hop 0, +-1 or +-2 candidates: yaw rates 0, +-0.98 and
            +-1.96 rad/s within the 2.0 rad/s limit).
        yaw_rate_max_radps: yaw rate limit [rad/s] (MP-CDE Table I: 2.0); the
            lattice's edges and every output sequence honour it.
        epsilon: eps of the switching threshold tau_thr = eps pi / yaw_rate_max
            [-] (MP-CDE Eq. 2: 1.2).
        hysteresis_s: the exploring/observing regime is entered when
            S(0) > tau_thr + hysteresis_s and left when S(0) < tau_thr [s]
            (MP-CDE Alg. 1 and Sec. IV-A: 0.1 s; the text once writes 0.15 s
            for the observing mode, Alg. 1 uses 0.1 s for both).
        alpha: weight of the exploration metric E in the edge cost, Eq. 5 [-]
            (MP-CDE: 0.6).
        beta: weight of the visibility metric V in the edge cost, Eq. 5 [-]
            (MP-CDE: 0.4).
        turn_penalty: cost [-] added to an edge in proportion to its yaw change,
            ``turn_penalty * |dpsi| / (yaw_rate_max * t_y)``. Not in the paper
            (chosen: 0.01): a tie-breaker so that, when nothing is to be gained
            anywhere, the planner holds its yaw instead of wandering; it keeps
            every edge cost non-negative.
        n_rays: rays per field-of-view sector of the coverage estimator, Eq. 3
            [-] (MP-CDE: 72).
        fov_h_deg: horizontal field of view of the camera [deg] (D435i: 85).
        fov_v_deg: vertical field of view of the camera [deg] (D435i: 58); used
            by the visibility metric (a neighbour must lie within +-fov_v/2 of
            the horizontal, the camera is taken as level).
        sensing_range_m: length of the coverage rays [m] (chosen: 5 m, half the
            default 10 m map window, so rays from its centre stay inside it).
        ray_step_m: spacing of the samples along a coverage ray [m] (chosen:
            0.15 m, the default voxel edge).
        detection_range_m: a neighbour farther than this counts as not visible
            in the visibility metric, Eq. 4 [m] (chosen: 8 m, inside the
            camera's 10 m depth range).
        v_max_mps: speed limit of the trajectory optimiser [m/s], the v_max of
            Eq. 1 (chosen: 1.0, the denied agent's default).
        t_hold_s: a neighbour last seen at most this long ago is "recently
            observed", the set V of Alg. 1 line 2 [s] (MP-CDE: 0.6).
        window_s: memory of the coverage window W: sectors of the yaws
            executed (i.e. current at a call of ``plan``) within this long
            before now [s] count as already covered (chosen: 1.0 s, ten
            planner periods: about the time the map needs to integrate what
            the camera saw).
        safety_sample_s: spacing of the trajectory samples of the safety
            metric, Eq. 1 [s] (chosen: 0.05 s, 5 cm at 1 m/s).
        safety_horizon_s: the safety metric samples ``[t, t + safety_horizon_s]``
            (beyond the trajectory's end the drone holds its end position), so
            tau_s is at most this [s]. It must exceed tau_thr + hysteresis_s,
            else the exploring regime could never be entered; beyond that it
            does not change the mode (chosen: 4.0 s).
        free_max_age_s: the safe point P_s of Eq. 1 ends at the first trajectory
            sample whose voxel is not verified free OR was last seen by the
            camera longer than this before the map's latest frame [s]: MP-CDE's
            "the segment ahead has been temporally validated by the perception
            pipeline". Default 1.0 s (chosen: the other drones are the only
            things that move in the simulated world, and in 1 s a neighbour at
            the swarm's 0.5-2 m/s crosses 0.5-2 m of space the camera saw
            free); ``inf``: verified free space never ages.
            It ages only tau_s, not d_free (the braking distance to unobserved
            space): d_free measured on fresh space alone would be about zero at
            the drone (only the camera's wedge is fresh) and forbid every mode
            but tracking. A drone that observes a neighbour while it flies
            sideways into space it saw seconds ago therefore loses the
            exploring/observing regime and looks where it goes (MP-CDE Fig. 3,
            for neighbours that now fly where the camera saw free space): the
            observing mode cannot stare at known neighbours while an unseen
            one closes in along the path (docs/results/yaw_planner.md#free_max_age_s-10-s).
        free_distance: how Eq. 1's d_free is measured: ``"horizontal"`` (in the
            plane of the drone's altitude slab, to the nearest cell not verified
            free; default), ``"voxel"`` (the map's 3-D verified-free distance)
            or ``"occupied"`` (in the same slab, to the nearest occupied cell:
            the paper's literal "ESDF value of the map", unknown space counting
            as free while tau_s still ends where verified-free space does); see
            :mod:`planners.yaw.safety`. ``"occupied"`` is not the default: it
            lets the camera leave the path while unobserved space is near
            (docs/results/mp-cde.md#the-swarm-without-tracking-mode-and-with-d_free-read-literally).
        free_slab_half_height_m: half height [m] of the altitude slab of
            ``"horizontal"`` (chosen: 0.3 m, two voxels either side: the
            drone's height plus its altitude tracking error).
        distance_eps_m: eps of 1 / (d + eps) in Eq. 4 and Eq. 6 [m] (chosen:
            0.2 m, about a drone's radius: closer than that, distance no
            longer adds urgency).
        visibility_sigma_ref_m: a neighbour's weight in Eq. 4 is
            ``min(1 + sigma / visibility_sigma_ref_m, visibility_weight_max)``
            with sigma = sqrt(trace P_pos(t)) its predicted position standard
            deviation [m], so a stale track (inflated covariance) matters more
            (chosen: 0.5 m).
        visibility_weight_max: cap on that weight [-] (chosen: 3).
        tracking_sweep_deg: in tracking mode the camera swings about the
            direction of travel by up to this much [deg], a triangle wave of
            period ``tracking_sweep_period_s`` in absolute time (0: straight
            along travel, the paper's tracking mode; set it to 0 to fly
            MP-CDE exactly). Not in MP-CDE. Why: a neighbour on a converging
            course at the same speed keeps a constant bearing of 90 deg minus
            half the crossing angle from the direction of travel, outside a
            forward camera's +-fov_h/2 for crossings shallower than
            180 - fov_h = 95 deg, so in tracking mode it is never seen; the
            swing widens the watched arc to +-(fov_h/2 + sweep). Chosen from
            that geometry: 60 deg. Drones that start side by side converge at
            bearings up to 90 deg, and 90 - fov_h / 2 = 47.5 deg puts such a
            neighbour only on the frame's edge; 12.5 deg more puts it inside
            the frame for 0.2 s of each period, five frames at 25 Hz, enough
            for the tracker's three confirming hits. The direction of travel
            then leaves the view for the 29 % of each period where the swing
            passes fov_h / 2 (the map keeps what was seen ahead). Allowed
            below 90 deg (the camera never looks behind the drone), and the
            swing's rate 4 sweep / period may not exceed
            ``yaw_rate_max_radps``. A swing small enough to keep travel always
            in view leaves a neighbour at 85-90 deg outside the frame at the
            swing's extreme (docs/results/yaw_planner.md#tracking_sweep_deg-60-deg-every-21-s).
        tracking_sweep_period_s: period of that swing [s] (chosen 2.1 s: the
            shortest period at which a 60 deg swing turns within the 2 rad/s
            limit, 4 x 60 deg / 2.1 s = 1.99 rad/s, so the camera revisits
            each side every 2.1 s).
        still_speed_mps: in tracking mode, below this horizontal speed the
            direction of travel is undefined and the yaw is held [m/s]
            (chosen: 0.1 m/s).
        exploring_mode: MP-CDE's exploring mode is on (default). False is the
            paper's "ours w/o exploring mode" (Table III): where it would
            explore, the heading follows travel instead (as tracking does;
            observing is unchanged).
        tracking_mode: MP-CDE's tracking mode is on (default). False is the
            paper's "ours w/o tracking mode": the planner never turns the
            camera to the direction of travel for safety; whatever S(0) says,
            it observes or explores (the regime is still computed and reported).
        method: ``"mpcde"`` (default, :class:`planners.yaw.planner.YawPlanner`)
            or ``"zhou"`` (:class:`planners.yaw.zhou.ZhouYawPlanner`), MP-CDE's
            comparison [26] in Table III: Zhou et al.'s perception-aware yaw
            planning, the lattice whose only reward is the unknown area in
            view, in every situation.
    """

    period_s: float = 0.1
    n_steps: ClassVar[int] = 12
    n_candidates: ClassVar[int] = 64
    yaw_rate_max_radps: float = 2.0
    epsilon: ClassVar[float] = 1.2
    hysteresis_s: ClassVar[float] = 0.1
    alpha: float = 0.6
    beta: float = 0.4
    turn_penalty: ClassVar[float] = 0.01
    n_rays: ClassVar[int] = 72
    fov_h_deg: float = 85.0
    fov_v_deg: float = 58.0
    sensing_range_m: float = 5.0
    ray_step_m: ClassVar[float] = 0.15
    detection_range_m: ClassVar[float] = 8.0
    v_max_mps: float = 1.0
    t_hold_s: float = 0.6
    window_s: ClassVar[float] = 1.0
    safety_sample_s: ClassVar[float] = 0.05
    safety_horizon_s: float = 4.0
    free_max_age_s: float = 1.0
    free_distance: str = "horizontal"
    free_slab_half_height_m: ClassVar[float] = 0.3
    distance_eps_m: ClassVar[float] = 0.2
    visibility_sigma_ref_m: ClassVar[float] = 0.5
    visibility_weight_max: ClassVar[float] = 3.0
    still_speed_mps: ClassVar[float] = 0.1
    tracking_sweep_deg: float = 60.0
    tracking_sweep_period_s: float = 2.1
    exploring_mode: bool = True
    tracking_mode: bool = True
    method: str = "mpcde"

    def __post_init__(self) -> None:
        for name in (
            "period_s",
            "yaw_rate_max_radps",
            "epsilon",
            "sensing_range_m",
            "ray_step_m",
            "detection_range_m",
            "v_max_mps",
            "safety_sample_s",
            "safety_horizon_s",
            "free_slab_half_height_m",
            "distance_eps_m",
            "visibility_sigma_ref_m",
        ):
            require_positive(name, getattr(self, name))
        for name in ("hysteresis_s", "alpha", "beta", "turn_penalty", "t_hold_s", "window_s", "still_speed_mps"):
            require_non_negative(name, getattr(self, name))
        if self.alpha + self.beta <= 0.0:
            raise ConfigError("beta", self.beta, f"allowed alpha + beta > 0 (alpha={self.alpha!r})")
        require_positive("free_max_age_s", self.free_max_age_s, inf_means="free space never ages")
        require_one_of("method", self.method, ("mpcde", "zhou"))
        require_one_of("free_distance", self.free_distance, ("horizontal", "voxel", "occupied"))
        require_integer_at_least("n_steps", self.n_steps, 1)
        require_integer_at_least("n_rays", self.n_rays, 2)
        require_integer_at_least("n_candidates", self.n_candidates, 3)
        if self.n_candidates * self.max_step_rad < 2.0 * math.pi * (1.0 - 1e-9):  # adjacent candidates must be connected
            slowest = 2.0 * math.pi / (self.n_candidates * self.period_s)
            allowed = f"allowed >= 2 pi / (n_candidates t_y) = {slowest:.3f} rad/s (adjacent yaw candidates must be one step apart)"
            raise ConfigError("yaw_rate_max_radps", self.yaw_rate_max_radps, allowed)
        for name, upper in (("fov_h_deg", 360.0), ("fov_v_deg", 180.0)):
            value = getattr(self, name)
            require_positive(name, value)
            if not value < upper:
                raise ConfigError(name, value, f"allowed 0 < {name} < {upper:g}")
        if self.ray_step_m > self.sensing_range_m:
            raise ConfigError("sensing_range_m", self.sensing_range_m, f"allowed >= ray_step_m = {self.ray_step_m!r} m")
        if not self.fov_h_deg + math.degrees(self.max_step_rad) < 360.0:
            allowed = f"allowed < 360 - yaw_rate_max * t_y = {360.0 - math.degrees(self.max_step_rad):.1f} deg (a turn must not wrap the sector onto itself)"
            raise ConfigError("fov_h_deg", self.fov_h_deg, allowed)
        require_positive("tracking_sweep_period_s", self.tracking_sweep_period_s)
        require_boolean("exploring_mode", self.exploring_mode)
        require_boolean("tracking_mode", self.tracking_mode)
        require_non_negative("tracking_sweep_deg", self.tracking_sweep_deg)
        if not self.tracking_sweep_deg < 90.0:
            raise ConfigError("tracking_sweep_deg", self.tracking_sweep_deg, "allowed 0 <= sweep < 90 (the camera never looks behind the drone)")
        sweep_rate = 4.0 * math.radians(self.tracking_sweep_deg) / self.tracking_sweep_period_s
        if sweep_rate > self.yaw_rate_max_radps * (1.0 + 1e-9):
            shortest = 4.0 * math.radians(self.tracking_sweep_deg) / self.yaw_rate_max_radps
            raise ConfigError(
                "tracking_sweep_deg", self.tracking_sweep_deg,
                f"allowed 4 * sweep / tracking_sweep_period_s <= yaw_rate_max_radps={self.yaw_rate_max_radps!r} rad/s "
                f"(this swing turns at {sweep_rate:.2f} rad/s; a smaller sweep, or a period >= {shortest:.2f} s)",
            )
        require_positive("visibility_weight_max", self.visibility_weight_max)
        if self.visibility_weight_max < 1.0:
            raise ConfigError("visibility_weight_max", self.visibility_weight_max, "allowed >= 1")
        needed = self.tau_thr_s + self.hysteresis_s
        if not self.safety_horizon_s > needed:
            raise ConfigError("safety_horizon_s", self.safety_horizon_s, f"allowed > tau_thr + hysteresis_s = {needed:.3f} s")

    @property
    def tau_thr_s(self) -> float:
        """Switching threshold tau_thr = eps pi / yaw_rate_max [s] (MP-CDE Eq. 2; 1.885 s by default)."""
        return self.epsilon * math.pi / self.yaw_rate_max_radps

    @property
    def max_step_rad(self) -> float:
        """Largest yaw change per lattice step, yaw_rate_max * t_y [rad] (0.2 rad by default)."""
        return self.yaw_rate_max_radps * self.period_s

    @property
    def candidate_spacing_rad(self) -> float:
        """Spacing of the candidate yaws, 2 pi / m [rad]."""
        return 2.0 * math.pi / self.n_candidates

    @property
    def max_hop(self) -> int:
        """q: an edge joins candidate k to candidates k - q .. k + q of the next layer (wrapping) [-].

        At most ``(m - 1) // 2``, so that no two hops of one node reach the same candidate.
        """
        q = int(math.floor(self.max_step_rad / self.candidate_spacing_rad + 1e-9))
        return min(q, (self.n_candidates - 1) // 2)

    @property
    def fov_h_rad(self) -> float:
        """Horizontal field of view [rad]."""
        return math.radians(self.fov_h_deg)

    @property
    def fov_v_rad(self) -> float:
        """Vertical field of view [rad]."""
        return math.radians(self.fov_v_deg)
