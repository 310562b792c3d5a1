"""The one step that derives the settings that follow from others, at load time.

A scenario sets each quantity once; the copies other components need are
derived here, so the resolved config (what ``config.yaml`` in the run folder
holds) is exactly what flies, and flying that file again gives the same
flight. Derived fields (target <- source):

* ``perception.backprojection.pose_pos_std_m`` <- ``pose_estimate.pos_noise_m``
  and ``pose_yaw_std_rad`` <- ``pose_estimate.yaw_noise_rad``: a drone's
  back-projection uncertainty includes its own localisation noise, what its
  VIO reports (MP-CDE Eq. 8);
* each stack's ``speed_fields`` (``denied.limits.v_max_mps`` with ``mpcde``,
  ``auto`` or ``minco_comm``, ``dmpc.qp.limits.v_max_mps`` with ``dmpc`` or ``auto``;
  :mod:`mpcde.stacks.builtin`) <- ``planner.cruise_speed_mps`` when it is
  set: the scenario's speed is each stack's speed limit;
* ``denied.yaw.v_max_mps`` <- ``denied.limits.v_max_mps``, ``denied.yaw.yaw_rate_max_radps``
  <- ``denied.yaw_rate_max_radps``, ``denied.yaw.t_hold_s`` <-
  ``perception.tracker.t_hold_s``, ``denied.yaw.fov_h_deg`` / ``fov_v_deg`` <-
  ``camera.hfov_deg`` / ``vfov_deg``: the yaw planner predicts with the
  optimiser's speed limit, turns at the heading limit, calls a track recent
  as the tracker does, and covers the camera's field of view (Alg. 1);
* a stack's own ``derived`` fields: ``radio.rate_hz`` <- 2 x the ADMM iterations per step (``admm.l_max``, times ``admm.sqp_iterations`` with dSQP) / ``admm.step_s``
  with ``planner.kind: admm`` and ``admm.radio_rate_from_step``: one radio sub-round per ADMM exchange;
  ``dmpc.obstacle_range_m`` <- max(3, sqrt(2) ``dmpc.qp.limits.v_max_mps`` K h + the inflation) with ``dmpc`` or
  ``auto`` and ``dmpc.commit_when_unheard``: every obstacle a plan flown to its halt can reach gets its plane.

Before the derivations, a stack's ``preset`` (:class:`mpcde.stacks.registry.Stack`) sets the
fields the scenario leaves unset: ``planner.kind: mpcde_paper`` flies the denied agent with
MP-CDE as published whatever the section's defaults become. A preset field the file sets is
kept (a preset is a default, not a derivation).

A target that the file (or the code building the config) sets to another
value than its derivation is refused with one line naming both, never
silently replaced. Without the file's mapping, "set" means "differs from the
field's default".
"""

from __future__ import annotations

import dataclasses
from typing import Any

from mpcde.config.bounds import check_ranges
from mpcde.config.scenario import SCENARIO_RANGES, ScenarioConfig
from mpcde.errors import ConfigError
from mpcde.stacks.registry import Derivation, stack_of

__all__ = ["COMMON", "derivations", "resolve"]

_MISSING = object()

# every scenario's: (target path, source named in errors, derivation, applies to this scenario)
COMMON: tuple[Derivation, ...] = (
    Derivation("perception.backprojection.pose_pos_std_m", "pose_estimate.pos_noise_m", lambda c: c.pose_estimate.pos_noise_m),
    Derivation("perception.backprojection.pose_yaw_std_rad", "pose_estimate.yaw_noise_rad", lambda c: c.pose_estimate.yaw_noise_rad),
    Derivation("denied.yaw.v_max_mps", "denied.limits.v_max_mps", lambda c: c.denied.limits.v_max_mps),
    Derivation("denied.yaw.yaw_rate_max_radps", "denied.yaw_rate_max_radps", lambda c: c.denied.yaw_rate_max_radps),
    Derivation("denied.yaw.t_hold_s", "perception.tracker.t_hold_s", lambda c: c.perception.tracker.t_hold_s),
    Derivation("denied.yaw.fov_h_deg", "camera.hfov_deg", lambda c: c.camera.hfov_deg),
    Derivation("denied.yaw.fov_v_deg", "camera.vfov_deg", lambda c: c.camera.vfov_deg),
)  # fmt: skip


def derivations(cfg: ScenarioConfig) -> tuple[Derivation, ...]:
    """The fields derived for ``cfg``, in order: its stack's speed limits from ``planner.cruise_speed_mps`` (its
    ``speed_fields``), the common ones, then its stack's own (``derived``): a derived field may be the source of a later one."""
    stack = stack_of(cfg)
    speed = tuple(
        Derivation(target, "planner.cruise_speed_mps", lambda c: c.planner.cruise_speed_mps, lambda c: c.planner.cruise_speed_mps is not None)
        for target in stack.speed_fields
    )  # fmt: skip
    return speed + COMMON + stack.derived


def _get(obj: Any, path: str) -> Any:
    for name in path.split("."):
        obj = getattr(obj, name)
    return obj


def _set(obj: Any, path: str, value: Any) -> Any:
    head, _, rest = path.partition(".")
    if not rest:
        return dataclasses.replace(obj, **{head: value})
    return dataclasses.replace(obj, **{head: _set(getattr(obj, head), rest, value)})


def _written(data: Any, path: str) -> Any:
    """The value the file's mapping gives for ``path``, or _MISSING."""
    for name in path.split("."):
        if not isinstance(data, dict) or name not in data:
            return _MISSING
        data = data[name]
    return data


def _default(path: str) -> Any:
    return _get(ScenarioConfig(), path)


def _same(a: Any, b: Any) -> bool:
    try:
        return a == b or abs(float(a) - float(b)) <= 1e-9 * max(1.0, abs(float(b)))
    except (TypeError, ValueError):
        return False


def resolve(cfg: ScenarioConfig, written: dict | None = None) -> ScenarioConfig:
    """``cfg`` with every derived field set from its source (idempotent).

    Args:
        cfg: a checked scenario.
        written: the mapping the scenario was read from (YAML plus
            overrides), to tell a field the user set from a default; None:
            a field is "set" when it differs from its default.

    Raises:
        ConfigError: a number outside its range (:data:`mpcde.config.scenario.SCENARIO_RANGES`;
            a config built in code meets them here), or a derived field set to
            another value than its derivation.
    """
    check_ranges(cfg, SCENARIO_RANGES)
    out = cfg
    for target, value in stack_of(cfg).preset.items():  # the stack's defaults for what the file leaves unset
        current = _get(cfg, target)
        given = _written(written, target) if written is not None else (current if not _same(current, _default(target)) else _MISSING)
        if given is _MISSING and not _same(current, value):
            out = _set(out, target, value)
    for d in derivations(cfg):  # in order: a derived field may be the source of a later one
        target, source = d.target, d.source
        if not d.applies(out):
            continue
        value = d.derive(out)
        current = _get(cfg, target)
        given = _written(written, target) if written is not None else (current if not _same(current, _default(target)) else _MISSING)
        if given is not _MISSING and not _same(given, value):
            raise ConfigError(target, given, f"derived from {source} = {value!r}; set that instead, or leave {target} out")
        if not _same(current, value) or type(current) is not type(value):
            try:
                out = _set(out, target, value)
            except ConfigError as e:  # the derived value breaks a rule of its section: name the section's path
                raise e.under(target.rpartition(".")[0]) from None
    return out
