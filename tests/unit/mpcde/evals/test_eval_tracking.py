"""Tests of the tracking evaluation (synthetic measurement source, results schema, AKF vs KF)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mpcde.evals.tracking import (
    SyntheticMeasurements,
    camera_pose,
    format_table,
    in_camera_view,
    make_scenario,
    run_eval_tracking,
)
from sim.pose_estimate import PoseEstimateConfig

ROW_KEYS = {"speed_mps", "filter", "measurements", "pos_rmse_m", "vel_rmse_mps", "id_switches", "nees"}


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("eval_tracking")
    results = run_eval_tracking(out, speeds_mps=(0.5, 2.0), seeds=(2,), duration_s=8.0, progress=False)
    return out, results


def test_results_json_has_exactly_the_schema(tiny_run):
    out, results = tiny_run
    on_disk = json.loads((out / "results.json").read_text())
    assert on_disk == results
    assert set(on_disk) == {"rows", "run"}
    from mpcde.numerics import describe
    from mpcde.sweep.engine import git_revision

    run = {"seeds": [2], "duration_s": 8.0, "version": on_disk["run"]["version"], "git_rev": git_revision(), "numerics": describe()}
    assert on_disk["run"] == run
    assert len(on_disk["rows"]) == 4
    for row in on_disk["rows"]:
        assert set(row) == ROW_KEYS
        assert row["filter"] in ("akf", "kf") and row["measurements"] == "synthetic"
        assert isinstance(row["id_switches"], int)
        assert np.isfinite([row["pos_rmse_m"], row["vel_rmse_mps"], row["nees"]]).all()
    assert {(r["speed_mps"], r["filter"]) for r in on_disk["rows"]} == {(0.5, "akf"), (0.5, "kf"), (2.0, "akf"), (2.0, "kf")}


def test_akf_beats_kf_at_high_speed(tiny_run):
    _, results = tiny_run
    rows = {(r["speed_mps"], r["filter"]): r for r in results["rows"]}
    assert rows[(2.0, "akf")]["pos_rmse_m"] < rows[(2.0, "kf")]["pos_rmse_m"]
    assert rows[(2.0, "akf")]["vel_rmse_mps"] < rows[(2.0, "kf")]["vel_rmse_mps"]
    assert rows[(2.0, "akf")]["nees"] < rows[(2.0, "kf")]["nees"]


def test_table_and_plots_are_written(tiny_run):
    out, results = tiny_run
    text = (out / "results.txt").read_text()
    assert text.startswith(format_table(results))
    assert "akf" in text and "kf" in text and "MP-CDE" in text
    assert (out / "tracking_0.5mps.png").stat().st_size > 1000
    assert (out / "tracking_2mps.png").stat().st_size > 1000


def test_an_unknown_source_or_bad_weights_are_refused_before_anything_is_written(tmp_path):
    out = tmp_path / "never"
    with pytest.raises(ValueError) as err:
        run_eval_tracking(out, measurements=("lidar",), progress=False)
    assert str(err.value) == "measurements='lidar': allowed: 'synthetic', 'pipeline'"
    with pytest.raises(ValueError, match="weights"):
        run_eval_tracking(out, measurements=("pipeline",), progress=False, detector_weights=str(tmp_path / "none.pt"))
    assert not out.exists()


@pytest.mark.slow
def test_pipeline_rows_track_rendered_drones(tmp_path):
    """Render -> detect -> back-project -> track, 6 s at 1 m/s, 2 targets: both filters track to a few cm."""
    res = run_eval_tracking(tmp_path / "p", speeds_mps=(1.0,), measurements=("pipeline",), seeds=(1,), duration_s=6.0, progress=False)
    rows = {r["filter"]: r for r in res["rows"]}
    assert set(rows) == {"akf", "kf"} and all(r["measurements"] == "pipeline" for r in rows.values())
    assert rows["akf"]["pos_rmse_m"] < 0.15 and rows["akf"]["vel_rmse_mps"] < 0.6
    assert rows["akf"]["id_switches"] == 0


def test_synthetic_noise_follows_the_ray_model_and_drops_detections():
    """With a perfect pose estimate the errors are the along / across-ray model; each measurement carries it."""
    scenario = make_scenario(1.0, 1, 40.0, seed=3)
    source = SyntheticMeasurements(p_occlusion=0.0, false_positive_rate=0.0, p_miss=0.2, pose_estimate=PoseEstimateConfig(0, 0, 0, 0, 0))
    frames = source.measure(scenario, seed=3)
    assert len(frames) == scenario.times_s.size
    detected = [k for k, f in enumerate(frames) if f]
    assert abs(len(detected) / len(frames) - 0.8) < 0.03
    z = np.array([frames[k][0].pos_world for k in detected])
    truth = scenario.target_pos_world[detected, 0]
    cam_pos, _ = camera_pose(scenario, source.camera)
    offset = truth - cam_pos
    rng_m = np.linalg.norm(offset, axis=1)
    e = offset / rng_m[:, None]
    err = z - truth
    along = np.sum(err * e, axis=1)
    across = err - along[:, None] * e
    std_along, std_across = source.noise_std_m(rng_m)
    assert abs((along / std_along).std() - 1.0) < 0.05 and abs((along / std_along).mean()) < 0.05
    # two independent across-ray components: the squared norm over std^2 averages 2
    assert abs(np.mean(np.sum(across**2, axis=1) / std_across**2) - 2.0) < 0.25  # 3.5 sigma of the mean of 800 samples
    # each measurement carries the model's covariance at its measured range and ray
    m = frames[detected[0]][0]
    o = m.pos_world - cam_pos
    a, c = source.noise_std_m(np.linalg.norm(o))
    u = o / np.linalg.norm(o)
    np.testing.assert_allclose(m.cov_world, c**2 * (np.eye(3) - np.outer(u, u)) + a**2 * np.outer(u, u), atol=1e-12)


def test_synthetic_measurements_carry_the_observer_pose_error():
    """Pose white noise of 5 cm (and near-zero sensor noise) shows in the errors and in the covariance."""
    scenario = make_scenario(0.5, 1, 20.0, seed=4)
    pose = PoseEstimateConfig(pos_noise_m=0.05, vel_noise_mps=0.0, yaw_noise_rad=0.0, pos_drift_m_per_sqrt_s=0.0, yaw_drift_rad_per_sqrt_s=0.0)
    tiny = dict(along_std_base_m=1e-4, along_std_quadratic_per_m=0.0, across_std_base_m=1e-4, across_std_per_range=0.0)
    source = SyntheticMeasurements(p_occlusion=0.0, false_positive_rate=0.0, p_miss=0.0, pose_estimate=pose, **tiny)
    frames = source.measure(scenario, seed=4)
    err = np.array([f[0].pos_world - scenario.target_pos_world[k, 0] for k, f in enumerate(frames) if f])
    assert len(err) > 400
    np.testing.assert_allclose(err.std(axis=0), 0.05, rtol=0.1)
    cov = frames[0][0].cov_world
    np.testing.assert_allclose(np.diag(cov), 0.05**2 + 1e-8, rtol=1e-6)


def test_synthetic_noise_parameters_are_checked():
    with pytest.raises(ValueError, match="along_std_base_m=-0.1"):
        SyntheticMeasurements(along_std_base_m=-0.1)
    with pytest.raises(ValueError, match="across_std_base_m=0"):
        SyntheticMeasurements(across_std_base_m=0.0, across_std_per_range=0.0)


def test_scenarios_are_seeded_and_manoeuvre():
    a = make_scenario(2.0, 2, 10.0, seed=1)
    b = make_scenario(2.0, 2, 10.0, seed=1)
    np.testing.assert_array_equal(a.target_pos_world, b.target_pos_world)
    acc = np.diff(a.target_vel_world, axis=0) * 25.0
    assert np.linalg.norm(acc, axis=2).max() > 1.0  # it turns
    speed = np.linalg.norm(a.target_vel_world[..., :2], axis=2)
    assert 1.0 < speed.min() and speed.max() < 2.7


@pytest.mark.parametrize("speed", [0.5, 2.0])
def test_targets_fly_in_front_of_the_observer_camera(speed):
    """Targets stay in range 2-7 m, |azimuth| <= 30 deg, height +-0.8 m nearly all the time (brief overshoots)."""
    inside, seen = [], []
    source = SyntheticMeasurements()
    for seed in (0, 1):
        sc = make_scenario(speed, 3, 30.0, seed)
        assert sc.observer_yaw_rad == 0.0
        rel = sc.target_pos_world - sc.observer_pos_world
        r_xy = np.hypot(rel[..., 0], rel[..., 1])
        az_deg = np.degrees(np.arctan2(rel[..., 1], rel[..., 0]))
        inside.append((r_xy >= 2.0) & (r_xy <= 7.0) & (np.abs(az_deg) <= 30.0))
        assert np.abs(rel[..., 2]).max() <= 0.8
        cam_pos, rot = camera_pose(sc, source.camera)
        seen.append(in_camera_view(sc.target_pos_world.reshape(-1, 3), cam_pos, rot, source.camera, 0.15))
    assert np.mean(inside) > 0.9
    assert np.mean(np.concatenate(seen)) > 0.97


def test_the_camera_view_check_follows_the_frustum():
    sc = make_scenario(1.0, 1, 1.0, seed=0)
    cam = SyntheticMeasurements().camera
    cam_pos, rot = camera_pose(sc, cam)
    np.testing.assert_allclose(cam_pos, [0.07, 0.0, 1.51])
    np.testing.assert_allclose(rot @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-12)  # optical axis = world +x
    half_h = np.radians(cam.hfov_deg / 2)
    d = 4.0
    edge_y = d * np.tan(half_h)  # on the horizontal side plane at depth d
    pts = cam_pos + np.array(
        [
            [d, 0.0, 0.0],  # straight ahead
            [-d, 0.0, 0.0],  # behind
            [10.5, 0.0, 0.0],  # beyond the depth range
            [d, edge_y - 0.1 / np.cos(half_h), 0.0],  # 0.1 m inside the left plane: less than the margin
            [d, edge_y - 0.2 / np.cos(half_h), 0.0],  # 0.2 m inside it
            [d, 0.0, d * np.tan(np.radians(cam.vfov_deg / 2)) + 0.05],  # above the top plane
        ]
    )
    np.testing.assert_array_equal(in_camera_view(pts, cam_pos, rot, cam, 0.15), [True, False, False, False, True, False])


def test_targets_out_of_view_are_not_measured_and_false_positives_are_in_view():
    sc = make_scenario(1.0, 2, 4.0, seed=0)
    behind = sc.target_pos_world.copy()
    behind[:, 1] = sc.observer_pos_world + (sc.observer_pos_world - behind[:, 1]) * [1, 1, 0]  # mirrored behind
    sc = dataclasses.replace(sc, target_pos_world=behind)
    source = SyntheticMeasurements(p_miss=0.0, p_occlusion=0.0, false_positive_rate=0.5)
    frames = source.measure(sc, seed=0)
    cam_pos, rot = camera_pose(sc, source.camera)
    all_z = np.array([m.pos_world for f in frames for m in f])
    assert len(all_z) > 0.9 * len(frames)  # target 0 every frame, a few false positives
    assert np.all(np.linalg.norm(all_z[:, :2] - behind[0, 1, :2], axis=1) > 1.0)  # never the target behind
    assert np.all(in_camera_view(all_z, cam_pos, rot, source.camera, -0.5))  # false positives lie in the image
