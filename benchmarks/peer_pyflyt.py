"""Peer row for bench_sim: PyFlyt's real-time factor with six camera drones on our forest_swarm scene.

What is measured: PyFlyt 0.29.0's ``Aviary`` (a PyBullet ``BulletClient``, headless in DIRECT mode) flying
len(starts) ``quadx`` drones (Crazyflie 2.x model) among the scene's obstacles, each drone with its camera on
(320 x 240, rendered at ``camera_hz``). Real-time factor = simulated seconds / wall seconds of the ``step()``
loop only: building the aviary, loading obstacles and one warm-up step (numba compiles PyFlyt's PID jitclass
there) are not timed.

Why it is a fair peer: the same engine (PyBullet) and the same renderer. PyFlyt calls ``getCameraImage`` with no
``renderer=`` argument; in DIRECT mode there is no OpenGL context, so PyBullet draws with ER_TINY_RENDERER,
the CPU rasteriser our sim/rendering/tiny.py names explicitly. Same drones count, obstacles, starts, goals and image
size; vertical FOV 58 deg and a level camera like our D435i model (PyFlyt's defaults are 90 deg, tilted up 20 deg).

What PyFlyt does per ``step()`` (one control period, 120 Hz; defaults kept): two 240 Hz physics ticks, each
with per-drone motor and drag forces, ``stepSimulation``, a state read-back and a full ``getContactPoints``
scan; the cascaded PID set-point controller (mode 7: x, y, yaw, z) runs at 120 Hz. A camera renders RGBA,
depth and segmentation on physics ticks divisible by 240 / camera_fps (so ``camera_fps`` must divide 240: 24 Hz
does, 25 Hz does not); without ``camera_fps`` it would render on every 240 Hz tick. It also renders once when
the aviary is built (not counted here).

What it does not do: no detector, no tracker, no map, no planner, no radio model; each drone flies straight
at its goal with PyFlyt's own PID position mode (at most 2 m/s horizontally), so drones may hit trees or each
other (the forest_swarm goals cross); contacts are simulated, the run goes on. Obstacles enter as
(x, y, radius, height) cylinders: a box is replaced by its bounding cylinder (``ObstacleSpec.footprint_radius_m``).

Installing: PyFlyt 0.29.0 (the newest release) declares numpy<2.0.0 and our lock pins numpy 2.4.6, so pip refuses
it under -c requirements-lock.txt, so there is no pip extra; `make bench-peer` installs it --no-deps. PyFlyt.core runs on numpy 2.4.6: the
figures were taken with PyFlyt==0.29.0, gymnasium==1.4.0 and farama-notifications==0.0.6 installed --no-deps
into a separate --target folder put on PYTHONPATH (PyFlyt.core imports gymnasium; pettingzoo is not needed).

Run on its own:  PYTHONPATH=<that folder> python benchmarks/peer_pyflyt.py --duration 5
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import time

import numpy as np

INSTALL_HINT = "make bench-peer installs it: PyFlyt 0.29.0 declares numpy<2, the lock pins 2.4.6, so it goes in without its declared dependencies"


def pyflyt_available() -> str | None:
    """None when PyFlyt imports, else a one-line note saying why the row is skipped."""
    try:
        import PyFlyt.core  # noqa: F401
    except ModuleNotFoundError as e:
        if e.name == "PyFlyt":
            return f"PyFlyt not installed ({INSTALL_HINT})"
        return f"PyFlyt does not import: missing {e.name}"
    except Exception as e:  # e.g. a numpy/numba incompatibility at import
        return f"PyFlyt does not import ({type(e).__name__}: {e})"
    return None


def pyflyt_peer_rtf(obstacles: list[tuple[float, float, float, float]], starts: np.ndarray, goals: np.ndarray,
                    duration_s: float, camera_hz: float = 24.0, width_px: int = 320, height_px: int = 240) -> dict:
    """Fly PyFlyt's Aviary headless with len(starts) QuadX camera drones among ``obstacles`` for ``duration_s``.

    ``obstacles`` are (x, y, radius, height) cylinders standing on the ground, loaded as static bodies.
    Returns {'real_time_factor', 'wall_s', 'sim_s', 'frames'}; frames counts the camera renders
    (``getCameraImage`` calls) made inside the timed loop, all drones together.
    """
    from PyFlyt.core import Aviary

    starts, goals = np.asarray(starts, float), np.asarray(goals, float)
    n = starts.shape[0]
    yaw = np.arctan2(goals[:, 1] - starts[:, 1], goals[:, 0] - starts[:, 0])
    start_orn = np.stack([np.zeros(n), np.zeros(n), yaw], axis=1)
    if abs(240.0 / camera_hz - round(240.0 / camera_hz)) > 1e-9:
        raise ValueError(f"camera_hz={camera_hz}: PyFlyt renders on physics ticks, so it must divide 240 Hz")
    opts = dict(use_camera=True, camera_resolution=(height_px, width_px),  # PyFlyt's order: (height, width)
                camera_fps=int(round(camera_hz)), camera_FOV_degrees=58, camera_angle_degrees=0)
    with contextlib.redirect_stdout(io.StringIO()):  # Aviary prints a cursor-up escape sequence
        env = Aviary(start_pos=starts, start_orn=start_orn, drone_type="quadx", render=False,
                     drone_options=[dict(opts) for _ in range(n)])
    try:
        for x, y, r, h in obstacles:
            col = env.createCollisionShape(env.GEOM_CYLINDER, radius=r, height=h)
            vis = env.createVisualShape(env.GEOM_CYLINDER, radius=r, length=h, rgbaColor=[0.45, 0.32, 0.2, 1.0])
            env.createMultiBody(0.0, col, vis, basePosition=[x, y, h / 2.0])
        env.register_all_new_bodies()  # resize PyFlyt's contact table to the new body ids
        env.set_mode(7)  # position set-points: [x, y, yaw, z]
        env.set_all_setpoints(np.column_stack([goals[:, 0], goals[:, 1], yaw, goals[:, 2]]))

        frames = [0]
        for d in env.drones:
            def counted(cap=d.camera.capture_image):
                frames[0] += 1
                return cap()
            d.camera.capture_image = counted
        env.step()  # warm-up: numba compiles the PID jitclass methods here
        frames[0], t0_steps = 0, env.physics_steps
        n_steps = max(1, math.ceil(duration_s / env.step_period - 1e-9))
        t0 = time.perf_counter()
        for _ in range(n_steps):
            env.step()
        wall = time.perf_counter() - t0
        sim = (env.physics_steps - t0_steps) / env.physics_hz
    finally:
        env.disconnect()
    return {"real_time_factor": sim / wall, "wall_s": wall, "sim_s": sim, "frames": frames[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds (default 20)")
    args = ap.parse_args()
    note = pyflyt_available()
    if note is not None:
        print(f"PyFlyt peer row skipped: {note}")
        return
    from mpcde.config.scenario import load_scenario
    from mpcde.flight.loop import prepare_run

    prepared = prepare_run(load_scenario("forest_swarm", {"seed": 0}))
    obstacles = [(*o.center_xy, o.footprint_radius_m, o.height_m) for o in prepared.obstacles]
    n = len(prepared.starts)
    r = pyflyt_peer_rtf(obstacles, prepared.starts, prepared.goals, args.duration)
    print(f"PyFlyt 0.29.0 peer: {n} QuadX drones each rendering a 320 x 240 camera at 24 Hz among "
          f"{len(obstacles)} obstacles: real-time factor {r['real_time_factor']:.2f} "
          f"({r['sim_s']:.1f} sim s in {r['wall_s']:.1f} wall s, {r['frames']} frames)")


if __name__ == "__main__":
    main()
