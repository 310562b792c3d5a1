"""Closed-loop runs: outputs, reproducibility, the onboard interfaces."""

import inspect
import json
from dataclasses import fields, replace

import numpy as np
import pytest

from mpcde.cli import main
from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario
from mpcde.onboard import base as agent_module
from mpcde.onboard import placeholder as placeholder_module
from sim.types import PoseEstimate, RadioMessage, RgbdFrame

VOLATILE = {"wall_time_s", "real_time_factor", "compute_time"}


def short(name: str, seconds: float, **run) -> "object":
    cfg = load_scenario(name, {"duration_s": seconds})
    return replace(cfg, run=replace(cfg.run, **run))


@pytest.mark.slow
def test_same_seed_gives_identical_metrics_and_another_seed_differs():
    """The default stack (auto: DMPC, the detector, the tracks, the map) flies a seed again metric for metric."""
    from agent_metrics import without_wall_clock  # tests/integration/agent_metrics.py

    cfg = short("forest_swarm", 3.0, render_workers=0)
    a = run_scenario(prepare_run(cfg)).metrics
    b = run_scenario(prepare_run(cfg)).metrics
    c = run_scenario(prepare_run(replace(cfg, seed=1))).metrics
    assert without_wall_clock(a) == without_wall_clock(b)
    assert without_wall_clock(a) != without_wall_clock(c)


@pytest.mark.slow
def test_rendering_in_worker_processes_gives_the_same_frames_as_in_process():
    from sim.bullet.scene import SceneSpec
    from sim.camera import CameraConfig
    from sim.rendering.pool import RenderPool
    from sim.rotations import quat_xyzw_from_yaw

    prepared = prepare_run(load_scenario("forest_swarm"))
    spec = SceneSpec(obstacles=prepared.obstacles, n_drones=6)
    pos = prepared.starts + np.array([2.0, 0.0, 0.0])
    quat = np.stack([quat_xyzw_from_yaw(0.1 * i) for i in range(6)])
    cams = []
    for i in range(6):
        T = np.eye(4)
        T[:3, :3] = np.array([[0, 0, 1.0], [-1, 0, 0], [0, -1, 0]])  # looking along +x
        T[:3, 3] = pos[i] - [0.3, 0, 0]
        cams.append((i, T))
    with RenderPool(spec, CameraConfig(), 0) as local, RenderPool(spec, CameraConfig(), 2) as pool:
        a = local.render(pos, quat, cams, sensor=(3, 17))
        b = pool.render(pos, quat, cams, sensor=(3, 17))
    for x, y in zip(a, b):
        assert np.array_equal(x.depth_sensor_m, y.depth_sensor_m, equal_nan=True)
        assert np.isnan(x.depth_sensor_m).any() and not np.array_equal(x.depth_sensor_m, x.depth_true_m, equal_nan=True)
        assert np.array_equal(x.rgb, y.rgb)
        assert np.array_equal(x.drone_index_mask, y.drone_index_mask)
        assert np.array_equal(x.depth_true_m, y.depth_true_m)


@pytest.mark.slow
def test_workers_run_the_detector_on_the_frames_asked_for_as_the_main_process_would():
    """The pool's frame processor (the detector in the render workers) gives each asked-for frame the detections
    the main process's detector finds in the same frame (to float rounding of the batch), None for the others."""
    from mpcde.config.perception import DetectorRequest
    from mpcde.onboard.detection import BatchedDetector, frame_detector
    from sim.bullet.scene import SceneSpec
    from sim.camera import CameraConfig
    from sim.rendering.camera_rig import CameraRig
    from sim.rendering.pool import RenderPool
    from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw

    prepared = prepare_run(load_scenario("forest_swarm"))
    spec = SceneSpec(obstacles=prepared.obstacles, n_drones=6)
    pos = prepared.starts.copy()
    pos[1::2] = pos[0::2] + [1.5, 0.4, 0.1]  # every other drone ahead of the one before it, in its view
    quat = np.stack([quat_xyzw_from_yaw(0.0) for _ in range(6)])
    rig = CameraRig(CameraConfig(), 0)
    cams = [(i, rig.transform_camera_to_world(pos[i], rotation_from_quat_xyzw(quat[i]))) for i in range(6)]
    request = DetectorRequest(precision="float32")
    asked = [0, 2, 3, 4]
    with RenderPool(spec, CameraConfig(), 2, (frame_detector, request)) as pool, RenderPool(spec, CameraConfig(), 0, (frame_detector, request)) as local:
        raws = pool.render(pos, quat, cams, sensor=(0, 5), process=asked)
        in_workers = pool.processed
        local.render(pos, quat, cams, sensor=(0, 5), process=asked)
        in_process = local.processed
        assert pool.processed_frames == 4 and pool.process_s > 0.0
    main = BatchedDetector(request).detector.detect_images([r.rgb for r in raws], [r.depth_sensor_m for r in raws], 0.4)
    found = 0
    for i in range(6):
        if i not in asked:
            assert in_workers[i] is None and in_process[i] is None
            continue
        for got in (in_workers[i], in_process[i]):
            assert len(got) == len(main[i])
            for a, b in zip(got, main[i]):
                assert np.allclose(a.box_xyxy, b.box_xyxy, atol=1e-3) and abs(a.score - b.score) < 1e-4
        found += len(main[i])
    assert found >= 2  # the drones ahead are seen


def test_a_render_does_not_depend_on_what_the_client_rendered_before():
    """A pose where PyBullet's TinyRenderer gave one pixel 1 off on odd getCameraImage calls.

    Found in ``radio_outage`` (seed 0 layout; drones near their starts): camera 2 rendered
    right after camera 0 differed from camera 2 rendered first (sim/rendering/tiny.py docstring).
    """
    from sim.bullet.scene import SceneSpec
    from sim.rendering.camera_rig import CameraRig
    from sim.rendering.tiny import SceneRenderer
    from sim.rotations import rotation_from_quat_xyzw

    cfg = load_scenario("radio_outage")
    prepared = prepare_run(cfg)
    pos = np.array(
        [
            [-6.297904816371964, -2.6578973448463445, 1.522282873526646],
            [-6.197937560549335, -1.7202237589690403, 1.507501163703177],
            [-6.248767087462863, -0.49964738058758285, 1.4118236608050734],
            [-6.324094247246924, 0.6089741316015447, 1.5822892634924985],
            [-6.334447237922741, 1.6397886191243165, 1.4282252394578723],
            [-6.308068419874316, 2.762657917000822, 1.5850838540339418],
        ]
    )
    sin_half = [0.9975144561422545, -0.358522156384527, 0.8994577777311555, 0.2827946040166374, 0.011529860614640343, 0.2692162196911634]
    cos_half = [0.07046211597179174, 0.9335212174243223, 0.43700767279183006, 0.9591804897614803, 0.9999335289479031, 0.9630797615230003]
    quat = np.array([[0.0, 0.0, s, c] for s, c in zip(sin_half, cos_half)])
    rig = CameraRig(cfg.camera, seed=0)
    T = [rig.transform_camera_to_world(pos[i], rotation_from_quat_xyzw(quat[i])) for i in range(6)]
    renders = []
    for history in ([], [0], [0, 1], [0, 1, 3], [2]):
        renderer = SceneRenderer(SceneSpec(obstacles=prepared.obstacles, n_drones=6), cfg.camera)
        try:
            renderer.set_drone_poses(pos, quat)
            for j in history:
                renderer.render(T[j], own_drone=j)
            renders.append(renderer.render(T[2], own_drone=2))
        finally:
            renderer.close()
    for r in renders[1:]:
        assert np.array_equal(r.rgb, renders[0].rgb)
        assert np.array_equal(r.depth_true_m, renders[0].depth_true_m)
        assert np.array_equal(r.drone_index_mask, renders[0].drone_index_mask)


@pytest.mark.slow
def test_fly_writes_metrics_plots_log_and_an_h264_video(tmp_path):
    out = tmp_path / "run"
    code = main(["fly", "crossing", "--out", str(out), "--duration", "2.0", "--video", "--quiet"])
    assert code == 0
    names = {p.name for p in out.iterdir()}
    assert {"config.yaml", "metrics.json", "states.npz", "top_down.png", "min_distance.png", "yaw.png", "video.mp4"} <= names
    m = json.loads((out / "metrics.json").read_text())
    for key in ("success", "collisions", "min_inter_drone_distance_m", "min_obstacle_distance_m", "mission_time_s", "real_time_factor"):
        assert key in m
    assert m["frames_received"] > 0 and m["radio"]["sent"] > 0
    assert set(m["numerics"]) == {"profile", "effective", "machine", "numpy_v4", "openblas_core", "pins"}
    assert m["numerics"]["profile"] in ("portable", "native")
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(out / "video.mp4"))
    meta = next(reader)
    assert meta["codec"] == "h264"
    log = np.load(out / "states.npz")
    assert log["pos_world"].shape[1:] == (2, 3)


@pytest.mark.slow
def test_the_placeholder_crossing_collides_and_the_metrics_say_so():
    """Two blind straight lines through one point must collide: metrics are not optimistic."""
    cfg = short("crossing", 14.0, cameras=False)
    r = run_scenario(prepare_run(replace(cfg, planner=replace(cfg.planner, kind="min_jerk_line"))))
    assert r.metrics["drone_drone_collisions"] >= 1 and r.metrics["success"] is False
    assert r.metrics["min_inter_drone_distance_m"] < 0.2


class SpyAgent(placeholder_module.Agent):
    """Records the type of everything the loop hands to the onboard agent."""

    seen: list = []

    def on_pose_estimate(self, estimate):
        SpyAgent.seen.append(("pose", type(estimate), estimate))
        super().on_pose_estimate(estimate)

    def on_frame(self, frame, detections=None):
        SpyAgent.seen.append(("frame", type(frame), frame))
        super().on_frame(frame, detections)

    def on_radio(self, messages):
        SpyAgent.seen.append(("radio", type(messages), messages))
        super().on_radio(messages)


def test_onboard_agent_sees_only_its_frames_its_estimate_and_its_inbox(monkeypatch):
    import mpcde.flight.loop as loop

    monkeypatch.setattr(loop, "make_agent", lambda cfg, i, goals, obstacles, budget=None: SpyAgent(i, goals[i], cfg.planner.line_speed_mps, cfg.planner.start_delay_s))
    SpyAgent.seen = []
    run_scenario(prepare_run(short("crossing", 0.5, render_workers=0)))
    kinds = {k for k, _, _ in SpyAgent.seen}
    assert kinds == {"pose", "frame", "radio"}
    for kind, tp, value in SpyAgent.seen:
        if kind == "pose":
            assert tp is PoseEstimate
        elif kind == "frame":
            assert tp is RgbdFrame
        else:
            assert all(type(m) is RadioMessage for m in value)
    # a frame carries no segmentation, only image, depth, intrinsics and the own pose estimate
    assert {f.name for f in fields(RgbdFrame)} == {"drone_id", "time_s", "rgb", "depth_m", "K", "transform_camera_to_world"}
    # the only entry points of an onboard agent: its three inputs, the round's planning verb, its two outputs, its metrics
    protocol = {n for n, _ in inspect.getmembers(agent_module.OnboardAgent, inspect.isfunction) if not n.startswith("_")}
    assert protocol == {"on_pose_estimate", "on_frame", "on_radio", "plan_round", "outgoing", "reference", "extra_metrics"}
    public = {n for n, _ in inspect.getmembers(placeholder_module.Agent, inspect.isfunction) if not n.startswith("_")}
    assert public == protocol


def test_closing_a_pool_with_an_uncollected_batch_and_idle_workers_returns():
    """A run that fails mid-render must not hang in close() (one camera, two workers)."""
    from sim.bullet.scene import SceneSpec
    from sim.camera import CameraConfig
    from sim.rendering.pool import RenderPool

    pool = RenderPool(SceneSpec(obstacles=(), n_drones=1), CameraConfig(width_px=32, height_px=24), 2)
    T = np.eye(4)
    T[:3, :3] = np.array([[0, 0, 1.0], [-1, 0, 0], [0, -1, 0]])
    T[2, 3] = 1.5
    pool.submit(np.array([[5.0, 0.0, 1.5]]), np.array([[0, 0, 0, 1.0]]), [(0, T)])
    pool.close()
    assert not pool.busy


def test_open_session_flies_the_given_agents_and_the_scenarios_own_for_the_rest():
    from mpcde.flight.loop import open_session
    from mpcde.stacks.build import make_agent

    prepared = prepare_run(short("crossing", 0.5, cameras=False))
    mine = SpyAgent(1, prepared.goals[1], 1.0, 0.0)
    session = open_session(prepared, agents={1: mine})
    try:
        assert session.agents[1] is mine
        own = make_agent(prepared.config, 0, prepared.goals, prepared.obstacles)
        assert type(session.agents[0]) is type(own) and session.agents[0].drone_id == 0
        SpyAgent.seen = []
        while not session.done:
            session.step()
        assert any(k == "pose" for k, _, _ in SpyAgent.seen)  # the given agent was flown
    finally:
        session.close()
    with pytest.raises(ValueError, match=r"agents: drone ids must be in 0\.\.1, got \[2\]"):
        open_session(prepared, agents={2: mine})
