"""Fly the communication-denied swarm (MP-CDE) for a few seconds and print what it measured.

Run: ``.venv/bin/python examples/fly_denied.py`` (about a minute on 2 cores).
No ``if __name__ == "__main__":`` is needed to call :func:`mpcde.fly` from a
script; ``main()`` is here so the examples test can run it.
"""

from __future__ import annotations

import mpcde


def main(duration_s: float = 4.0, out: str | None = None) -> dict:
    """Fly ``forest_swarm`` in ``denied`` mode; return its metrics."""
    result = mpcde.fly("forest_swarm", mode="denied", seed=0, duration_s=duration_s, out=out, overwrite=True)
    m = result.metrics
    print(f"denied, {duration_s:g} s: collisions {m['collisions']}, min inter-drone {m['min_inter_drone_distance_m']} m, "
          f"tracking RMSE {m.get('tracking_pos_rmse_m')} m, real-time factor {m['real_time_factor']:.2f}")
    return m


if __name__ == "__main__":
    main()
