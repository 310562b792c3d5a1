"""The most any yaw could have seen along a Table III flight's path: S_obs of a camera that sees all round (360 deg)
at the same true positions, beside the flight's own S_obs (issue 28, Table III's margin).

Usage:
    .venv/bin/python scripts/table3_ceiling.py [SWEEP.yaml] --flights CELL:SEED ...

Flies each named flight of the sweep (default ``data/sweeps/table3_active_perception.yaml``) in this process,
one after the other. Next to the flight's :class:`mpcde.flight.observed_area.ObservedArea` it keeps a second one
fed the same true camera poses with a 360 deg field of view (same depth range, same trees, same raster), and
prints both areas. The all-round area bounds S_obs for *that path* from above, whatever the heading did: a yaw
planner can add at most ``ceiling / S_obs - 1`` there. (Another yaw flies another path, so it is a bound for
the path flown, not for the method.)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mpcde.flight import observed_area as oa
from mpcde.sweep.runner import prepare_flight
from mpcde.sweep.spec import load_sweep

SHADOWS: list[oa.ObservedArea] = []


class _WithAllRound(oa.ObservedArea):
    """The flight's observed area, with an all-round twin fed every frame (module docstring)."""

    def __init__(self, obstacles, arena_size_m, n_drones, hfov_deg, depth_max_m) -> None:  # noqa: ANN001
        super().__init__(obstacles, arena_size_m, n_drones, hfov_deg, depth_max_m)
        self.all_round = oa.ObservedArea(obstacles, arena_size_m, n_drones, 360.0 - oa.RAY_STEP_DEG, depth_max_m)
        SHADOWS.append(self.all_round)

    def add_frame(self, drone: int, transform_camera_to_world) -> None:  # noqa: ANN001
        super().add_frame(drone, transform_camera_to_world)
        self.all_round.add_frame(drone, transform_camera_to_world)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep", type=Path, nargs="?", default=Path("data/sweeps/table3_active_perception.yaml"))
    ap.add_argument("--flights", nargs="+", required=True, help="CELL:SEED pairs")
    args = ap.parse_args()
    import mpcde.flight.session as session

    session.ObservedArea = _WithAllRound  # the session builds its metric from this name
    from mpcde.flight.loop import run_scenario

    spec = load_sweep(args.sweep)
    cells = {c.index: c for c in spec.cells()}
    print("cell  seed  label  S_obs m^2  all-round m^2  headroom")
    for item in args.flights:
        c, s = (int(x) for x in item.split(":"))
        result = run_scenario(prepare_flight(spec, cells[c], s, None))
        own = result.metrics["observed_area_swarm_m2"]
        ceiling = SHADOWS[-1].areas_m2()[1]
        print(f"{c}  {s}  {cells[c].label}  {own:.1f}  {ceiling:.1f}  {100 * (ceiling / own - 1):+.1f} %", flush=True)


if __name__ == "__main__":
    main()
