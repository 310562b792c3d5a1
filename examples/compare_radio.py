"""The same scenario and seed flown by the communicating, the denied and the switching swarm.

Run: ``.venv/bin/python examples/compare_radio.py``. Each stack is picked by
``mode``; the scenario is loaded once and its seed fixed before any flight.
"""

from __future__ import annotations

from dataclasses import replace

import mpcde


def main(duration_s: float = 3.0) -> dict[str, dict]:
    """Fly ``radio_outage`` for ``duration_s`` in comm, denied and auto; return each mode's metrics."""
    rows = {}
    for mode in ("comm", "denied", "auto"):
        cfg = mpcde.load_scenario("radio_outage", mode=mode, seed=0, duration_s=duration_s)
        cfg = replace(cfg, name=f"radio_outage-{mode}")
        m = mpcde.fly(cfg).metrics
        rows[mode] = m
        print(f"{mode:>6}: collisions {m['collisions']}, min inter-drone {m['min_inter_drone_distance_m']} m, "
              f"real-time factor {m['real_time_factor']:.2f}")
    return rows


if __name__ == "__main__":
    main()
