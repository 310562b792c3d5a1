"""The most any yaw could have seen along a Table III flight's path (``mpcde paper ceiling [SWEEP] --flights CELL:SEED ...``).

A flight of the sweep is flown again in this process, the flight ``mpcde sweep`` flies. Next to the session's
:class:`mpcde.flight.observed_area.ObservedArea` (S_obs, truth only) an :class:`AllRoundArea` keeps a second one,
fed the same true camera poses with a field of view all round (360 deg less one ray step, the same depth range,
trees and raster). The all-round area bounds S_obs for *that path* from above, whatever the heading did: a yaw
planner can add at most ``ceiling / S_obs - 1`` there. (Another yaw flies another path, so it is a bound for the
path flown, not for the method.)
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from mpcde.errors import ConfigError
from mpcde.flight import observed_area as oa
from mpcde.sweep.spec import SweepSpec
from sim.types import ObstacleSpec

__all__ = ["DEFAULT_SWEEP", "HEADER", "AllRoundArea", "Ceiling", "ceiling_lines", "fly_with_ceiling", "parse_flight"]

DEFAULT_SWEEP = "data/sweeps/table3_active_perception.yaml"
"""The sweep file whose flights are flown when none is named (Table III at the record's sensing range)."""
HEADER = "cell  seed  label  S_obs m^2  all-round m^2  headroom"
"""The first line of the report."""


class AllRoundArea(oa.ObservedArea):
    """A flight's observed area with an all-round twin (:attr:`all_round`) fed every frame it is fed."""

    def __init__(self, obstacles: Sequence[ObstacleSpec], arena_size_m: Sequence[float], n_drones: int, hfov_deg: float, depth_max_m: float) -> None:
        """As :class:`~mpcde.flight.observed_area.ObservedArea`: the arena's size (x, y) [m], the camera's horizontal
        field of view [deg] and depth range [m]; the twin sees 360 deg less one ray step."""
        super().__init__(obstacles, arena_size_m, n_drones, hfov_deg, depth_max_m)
        self.all_round = oa.ObservedArea(obstacles, arena_size_m, n_drones, 360.0 - oa.RAY_STEP_DEG, depth_max_m)

    def add_frame(self, drone: int, transform_camera_to_world: np.ndarray) -> None:
        """Add drone ``drone``'s frame, camera pose ``transform_camera_to_world`` (4, 4), to both areas."""
        super().add_frame(drone, transform_camera_to_world)
        self.all_round.add_frame(drone, transform_camera_to_world)


@dataclass(frozen=True)
class Ceiling:
    """One flight's S_obs beside the all-round bound along its path."""

    cell: int
    """The sweep's cell index."""
    seed: int
    """The flight's seed."""
    label: str
    """The cell's label (its axis values)."""
    s_obs_m2: float
    """The flight's swarm S_obs [m^2] (``observed_area_swarm_m2``)."""
    all_round_m2: float
    """The swarm's area seen all round along the same true poses [m^2]."""

    def line(self) -> str:
        """The report's line: cell, seed, label, both areas and the headroom ``all_round / S_obs - 1`` [%]."""
        return f"{self.cell}  {self.seed}  {self.label}  {self.s_obs_m2:.1f}  {self.all_round_m2:.1f}  {100 * (self.all_round_m2 / self.s_obs_m2 - 1):+.1f} %"


def parse_flight(text: str, spec: SweepSpec) -> tuple[int, int]:
    """(cell, seed) of ``CELL:SEED``; ConfigError (one line) unless both are integers, the cell one of ``spec``'s
    and the seed in [0, 2^32)."""
    cell_text, sep, seed_text = text.partition(":")
    try:
        cell, seed = int(cell_text), int(seed_text)
    except ValueError:
        raise ConfigError("--flights", text, "CELL:SEED, two integers") from None
    n_cells = len(spec.cells())
    if not sep or not 0 <= cell < n_cells:
        raise ConfigError("--flights", text, f"CELL:SEED with CELL a cell of the sweep, 0..{n_cells - 1}")
    if not 0 <= seed < 2**32:
        raise ConfigError("--flights", text, "CELL:SEED with SEED an integer in [0, 2^32)")
    return cell, seed


def fly_with_ceiling(spec: SweepSpec, cell: int, seed: int) -> Ceiling:
    """Fly ``spec``'s cell ``cell`` with ``seed`` (cameras on) and return its S_obs beside the all-round bound."""
    from mpcde.flight.loop import open_session
    from mpcde.sweep.runner import prepare_flight

    cells = {c.index: c for c in spec.cells()}
    prepared = prepare_flight(spec, cells[cell], seed, None)
    cfg = prepared.config
    if not cfg.run.cameras:
        raise ConfigError("run.cameras", False, "true: S_obs is the cameras' observed area")
    session = open_session(prepared)
    try:
        n = len(prepared.starts)
        session.observed = shadow = AllRoundArea(prepared.obstacles, cfg.world.arena_size_m, n, cfg.camera.hfov_deg, cfg.camera.depth_max_m)
        while not session.done:
            session.step()
        result = session.result()
    finally:
        session.close()  # render pool and shared memory
    return Ceiling(cell, seed, cells[cell].label, result.metrics["observed_area_swarm_m2"], shadow.all_round.areas_m2()[1])


def ceiling_lines(spec: SweepSpec, flights: Sequence[str]) -> Iterator[str]:
    """The report's lines: :data:`HEADER`, then one line per flight ``CELL:SEED`` of ``flights``, flown one after the
    other (every flight named is checked before the first flies)."""
    pairs = [parse_flight(text, spec) for text in flights]
    yield HEADER
    for cell, seed in pairs:
        yield fly_with_ceiling(spec, cell, seed).line()
