"""Benchmark of the simulator's hot paths; prints medians and in-run baselines.

1. Render [ms/frame] at 160x120, 320x240, 640x480 with 6 drones and 20
   obstacles in view range, against a baseline measured in the same run: the
   same scene with the ground rasterised as a mesh by TinyRenderer (what a
   plain PyBullet scene does) instead of drawn analytically.
2. Physics + controller step [ms/tick] for 6 drones, against PyBullet's bare
   ``stepSimulation`` of the same bodies (the floor).
3. Real-time factor of the 6-drone forest flight (forest_swarm, 20 s, cameras
   at 25 Hz, 320x240) with render workers (one per core) against rendering in
   the main process.

Usage: python benchmarks/bench_sim.py [--quick]
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

import numpy as np
import pybullet as pb

from mpcde.loop import prepare_run, run_scenario
from mpcde.scenario import load_scenario
from sim.camera import CameraConfig
from sim.camera_rig import CameraRig
from sim.renderer import SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.scene import SceneSpec
from sim.types import FlatOutputReference
from sim.world import World
from timing import median_ms


def render_bench(repeats: int) -> None:
    prepared = prepare_run(load_scenario("forest_swarm", {"seed": 0}))
    obstacles = tuple(sorted(prepared.obstacles, key=lambda o: np.hypot(*o.center_xy))[:20])
    spec = SceneSpec(obstacles=obstacles, n_drones=6)
    pos = np.array([[-3.0, -1.0, 1.5], [-1.0, 0.5, 1.4], [0.5, -0.8, 1.7], [2.0, 1.2, 1.5], [3.5, 0.0, 1.6], [5.0, -1.5, 1.3]])
    quat = np.stack([quat_xyzw_from_yaw(0.2 * i) for i in range(6)])
    print("render, 6 drones, 20 obstacles (ms/frame, median of", repeats, "x 6 cameras)")
    print(f"{'resolution':>12} {'ours':>8} {'ground mesh':>12} {'speed-up':>9}")
    for W, H in ((160, 120), (320, 240), (640, 480)):
        cam = CameraConfig(width_px=W, height_px=H)
        rig = CameraRig(cam, 0)
        R = rotation_from_quat_xyzw(quat)
        poses = [rig.transform_camera_to_world(pos[i], R[i]) for i in range(6)]
        r = SceneRenderer(spec, cam)
        r.set_drone_poses(pos, quat)
        ours = median_ms(lambda: [r.render(poses[i], i) for i in range(6)], repeats) / 6
        # baseline: a ground box rasterised by TinyRenderer, plain getCameraImage
        col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[30, 30, 0.05], physicsClientId=r.client)
        vis = pb.createVisualShape(pb.GEOM_BOX, halfExtents=[30, 30, 0.05], rgbaColor=[0.4, 0.5, 0.35, 1], physicsClientId=r.client)
        pb.createMultiBody(0, col, vis, basePosition=[0, 0, -0.05], physicsClientId=r.client)

        def plain(i: int) -> None:
            from sim.camera import opengl_view_from_camera_to_world

            pb.getCameraImage(W, H, opengl_view_from_camera_to_world(poses[i]), r.projection, renderer=pb.ER_TINY_RENDERER, physicsClientId=r.client)

        base = median_ms(lambda: [plain(i) for i in range(6)], repeats) / 6
        r.close()
        print(f"{W:>5}x{H:<6} {ours:8.2f} {base:12.2f} {base / ours:8.2f}x")


def physics_bench(repeats: int) -> None:
    n = 6
    starts = np.array([[i * 1.0, 0.0, 1.5] for i in range(n)])
    w = World(SceneSpec(obstacles=(), n_drones=n), starts, np.zeros(n))
    refs = [FlatOutputReference.hover(starts[i]) for i in range(n)]
    step = median_ms(lambda: [w.step(refs) for _ in range(24)], repeats) / 24
    bare = median_ms(lambda: [pb.stepSimulation(physicsClientId=w.client) for _ in range(24)], repeats) / 24
    w.close()
    print(f"physics + SE(3) control + motors, 6 drones: {step:.3f} ms/tick (bare stepSimulation {bare:.3f} ms; overhead x{step / bare:.1f}); "
          f"240 Hz needs {step * 240:.0f} ms per simulated s")


def rtf_bench(duration_s: float) -> None:
    cfg = load_scenario("forest_swarm", {"duration_s": duration_s})
    cfg = replace(cfg, run=replace(cfg.run, stop_when_arrived=False))
    rows = []
    for workers in (os.cpu_count() or 1, 0):
        c = replace(cfg, run=replace(cfg.run, render_workers=workers))
        m = run_scenario(prepare_run(c)).metrics
        rows.append((workers, m["real_time_factor"], m["frames_rendered"]))
    print(f"forest_swarm, 6 drones, {duration_s:.0f} s, cameras 25 Hz at 320x240:")
    for workers, rtf, frames in rows:
        print(f"  render workers {workers}: real-time factor {rtf:.2f} ({frames} frames)")
    print(f"  speed-up of workers over in-process: x{rows[0][1] / rows[1][1]:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer repeats, 5 s flight")
    args = ap.parse_args()
    render_bench(3 if args.quick else 10)
    physics_bench(5 if args.quick else 20)
    rtf_bench(5.0 if args.quick else 20.0)


if __name__ == "__main__":
    main()
