"""Benchmark of the simulator's hot paths; prints medians and in-run baselines.

1. Render [ms/frame] at 160x120, 320x240, 640x480 with 6 drones and 20
   obstacles in view range, against a baseline measured in the same run: the
   same scene with the ground rasterised as a mesh by TinyRenderer (what a
   plain PyBullet scene does) instead of drawn analytically; and the
   analytic ray-casting renderer (``camera.renderer: raycast``) against ours.
2. Physics + controller step [ms/tick] for 6 drones, against PyBullet's bare
   ``stepSimulation`` of the same bodies (the floor).
3. Real-time factor of the 6-drone forest flight (forest_swarm, 20 s, cameras
   at 25 Hz, 320x240) for every stack side by side (placeholder, comm,
   denied, auto), each with its per-component compute budget
   (``metrics.json`` ``compute_time``), against a peer measured in the same
   run: PyFlyt flying and rendering six camera drones on the same scene
   (``benchmarks/peer_pyflyt.py``; skipped with a note when PyFlyt is absent).

Usage: python benchmarks/bench_sim.py [--quick] [--stacks ...] [--no-peer] [--only-rtf] [--detector-weights PATH]
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

import numpy as np
from peer_pyflyt import pyflyt_available, pyflyt_peer_rtf
from timing import median_ms

from mpcde.stacks import get_stack
from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario
from mpcde.onboard.budget import COMPONENTS
from sim.bullet import pb
from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig
from sim.rendering.camera_rig import CameraRig
from sim.rendering.raycast import RaycastRenderer
from sim.rendering.tiny import SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.types import FlatOutputReference
from sim.world import World


def render_bench(repeats: int) -> None:
    prepared = prepare_run(load_scenario("forest_swarm", {"seed": 0}))
    obstacles = tuple(sorted(prepared.obstacles, key=lambda o: np.hypot(*o.center_xy))[:20])
    spec = SceneSpec(obstacles=obstacles, n_drones=6)
    pos = np.array([[-3.0, -1.0, 1.5], [-1.0, 0.5, 1.4], [0.5, -0.8, 1.7], [2.0, 1.2, 1.5], [3.5, 0.0, 1.6], [5.0, -1.5, 1.3]])
    quat = np.stack([quat_xyzw_from_yaw(0.2 * i) for i in range(6)])
    print("render, 6 drones, 20 obstacles (ms/frame, median of", repeats, "x 6 cameras)")
    print(f"{'resolution':>12} {'ours':>8} {'ground mesh':>12} {'speed-up':>9} {'raycast':>9} {'vs ours':>8}")
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
        ray = RaycastRenderer(spec, cam)
        ray.set_drone_poses(pos, quat)
        analytic = median_ms(lambda: [ray.render(poses[i], i) for i in range(6)], repeats) / 6
        print(f"{W:>5}x{H:<6} {ours:8.2f} {base:12.2f} {base / ours:8.2f}x {analytic:9.2f} {ours / analytic:7.2f}x")


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


STACKS = ("placeholder", "comm", "denied", "auto")  # registry names (mpcde.stacks); the stacks that fly forest_swarm
BUDGET_ROWS = (*COMPONENTS, "other")


def rtf_bench(duration_s: float, stacks: tuple[str, ...] = STACKS, peer: bool = True, renderer: str = "raycast",
              detector_weights: str | None = None) -> None:
    """Real-time factor of forest_swarm (6 drones, cameras 25 Hz at 320 x 240) per stack, with each stack's budget.

    Every stack flies the same seed for ``duration_s`` simulated seconds (no
    early stop at arrival), render workers one per core, as ``mpcde fly``
    does. The peer row is PyFlyt on the same scene (benchmarks/peer_pyflyt.py),
    skipped with a note when PyFlyt does not import; the ratios are against it.
    ``detector_weights`` flies another checkpoint (``perception.detector_weights``),
    e.g. an earlier detector as the baseline of a detector change.
    """
    base = load_scenario("forest_swarm", {"duration_s": duration_s})
    rows = {}
    for stack in stacks:
        over = {"duration_s": duration_s, "planner": {"kind": get_stack(stack).kind}, "camera": {"renderer": renderer}}
        if detector_weights is not None:
            over["perception"] = {"detector_weights": detector_weights}
        cfg = load_scenario("forest_swarm", over)
        cfg = replace(cfg, run=replace(cfg.run, stop_when_arrived=False))
        rows[stack] = run_scenario(prepare_run(cfg)).metrics
    peer_rtf, note = None, pyflyt_available() if peer else "not asked (--no-peer)"
    if note is None:
        prepared = prepare_run(base)
        obstacles = [(*o.center_xy, o.footprint_radius_m, o.height_m) for o in prepared.obstacles]
        peer_rtf = pyflyt_peer_rtf(obstacles, prepared.starts, prepared.goals, duration_s)["real_time_factor"]
    weights = f", detector {detector_weights}" if detector_weights else ""
    print(f"forest_swarm, 6 drones, {duration_s:.0f} s simulated, cameras 25 Hz at 320x240 ({renderer} renderer{weights}), {os.cpu_count()} cores:")
    print(f"{'stack':>12} {'real-time factor':>17} {'vs PyFlyt':>10}   collisions  frames  workers  detector")
    for stack, m in rows.items():
        ratio = f"{m['real_time_factor'] / peer_rtf:9.2f}x" if peer_rtf else f"{'-':>10}"
        det = m.get("detector_precision") or "-"
        print(f"{stack:>12} {m['real_time_factor']:17.3f} {ratio}   {m['collisions']:10d}  {m['frames_rendered']:6d}  {m['render_workers']:7d}  {det}")
    if peer_rtf:
        print(f"{'PyFlyt peer':>12} {peer_rtf:17.3f} {'1.00x':>10}   (6 QuadX, 320x240 camera each at 24 Hz, renders and flies only)")
    else:
        print(f"{'PyFlyt peer':>12} skipped: {note}")
    print("compute per simulated second [ms] (ms per call, detect per frame); render and detect in the workers, the rest in the main process:")
    print(f"{'component':>12} " + " ".join(f"{s:>20}" for s in rows))
    for comp in BUDGET_ROWS:
        cells = []
        for m in rows.values():
            c = m["compute_time"].get(comp)
            cells.append(f"{c['ms_per_sim_s']:8.0f} ({c['ms_per_call']:7.2f})" if c else f"{'-':>20}")
        if any(c.strip() != "-" for c in cells):
            print(f"{comp:>12} " + " ".join(f"{c:>20}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer repeats, 5 s flights")
    ap.add_argument("--stacks", nargs="+", choices=STACKS, default=list(STACKS), help="stacks of the real-time rows")
    ap.add_argument("--no-peer", action="store_true", help="skip the PyFlyt row")
    ap.add_argument("--only-rtf", action="store_true", help="only the real-time rows (no render / physics micro-benchmarks)")
    ap.add_argument("--renderer", choices=["tiny", "raycast"], default="raycast", help="camera.renderer of the real-time rows")
    ap.add_argument("--detector-weights", default=None, help="detector checkpoint of the real-time rows (default: the shipped one)")
    args = ap.parse_args()
    if not args.only_rtf:
        render_bench(3 if args.quick else 10)
        physics_bench(5 if args.quick else 20)
    rtf_bench(5.0 if args.quick else 20.0, tuple(args.stacks), peer=not args.no_peer, renderer=args.renderer,
              detector_weights=args.detector_weights)


if __name__ == "__main__":
    main()
