"""Detector dataset: labels are the segmentation's visible boxes, splits are disjoint, frames are deterministic."""

import json
from pathlib import Path

import numpy as np
import pytest

from mpcde.errors import ConfigError
from mpcde.training.dataset import (
    MIN_BOX_HEIGHT_PX,
    MIN_BOX_WIDTH_PX,
    MIN_VISIBLE_PX,
    SPLIT_SEED_BASE,
    DatasetConfig,
    boxes_from_mask,
    render_scene,
    split_seeds,
)
from mpcde.training.dataset_files import load_dataset
from sim.camera import CameraConfig

FIXTURE = Path(__file__).resolve().parents[4] / "data" / "detector" / "fixture" / "test"


@pytest.fixture(scope="module")
def fixture_data() -> dict:
    return load_dataset(FIXTURE)


def test_boxes_from_mask_use_pixel_edges():
    mask = np.full((10, 12), -1, np.int16)
    mask[2:5, 3:9] = 1  # rows 2-4, columns 3-8
    mask[7, 0] = 0
    ids, boxes, counts = boxes_from_mask(mask, 3)
    assert list(ids) == [0, 1] and list(counts) == [1, 18]
    assert boxes[1] == pytest.approx([2.5, 1.5, 8.5, 4.5])  # width 6 columns, height 3 rows
    assert boxes[0] == pytest.approx([-0.5, 6.5, 0.5, 7.5])


def test_fixture_labels_match_the_segmentation_mask(fixture_data):
    d = fixture_data
    assert d["rgb"].shape[0] >= 3 and d["box_xyxy"].shape[0] >= 3
    for f in range(d["rgb"].shape[0]):
        rows = np.nonzero(d["box_frame"] == f)[0]
        mask = d["drone_index_mask"][f]
        n = int(mask.max()) + 1
        ids, boxes, counts = boxes_from_mask(mask, max(n, 1))
        assert sorted(d["box_drone_index"][rows]) == sorted(ids)
        for r in rows:
            k = int(np.nonzero(ids == d["box_drone_index"][r])[0][0])
            assert d["box_xyxy"][r] == pytest.approx(boxes[k])
            w, h = boxes[k][2] - boxes[k][0], boxes[k][3] - boxes[k][1]
            small = w < MIN_BOX_WIDTH_PX or h < MIN_BOX_HEIGHT_PX or counts[k] < MIN_VISIBLE_PX
            assert bool(d["box_ignore"][r]) == small
        # true distance is camera centre to drone centre, within the configured range
        T = d["transform_camera_to_world"][f]
        dist = np.linalg.norm(d["box_pos_world"][rows] - T[:3, 3], axis=1)
        assert d["box_distance_m"][rows] == pytest.approx(dist, rel=1e-5)
        assert np.all((dist >= 0.3 - 1e-6) & (dist <= 10.0 + 1e-6))


def test_split_seed_ranges_are_disjoint():
    sets = {s: set(split_seeds(s, 5000)) for s in SPLIT_SEED_BASE}
    assert not (sets["train"] & sets["val"]) and not (sets["train"] & sets["test"]) and not (sets["val"] & sets["test"])
    big = {s: split_seeds(s, 1_000_000) for s in SPLIT_SEED_BASE}
    assert big["train"][-1] < big["val"][0] and big["val"][-1] < big["test"][0]
    with pytest.raises(ConfigError):
        split_seeds("train", 1_000_001)
    with pytest.raises(ConfigError):
        split_seeds("holdout", 3)


def test_frames_are_deterministic_per_seed_and_reproduce_the_fixture(fixture_data):
    manifest = json.loads((FIXTURE / "manifest.json").read_text())
    cfg = DatasetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in manifest["config"].items()})
    seed = int(fixture_data["scene_seed"][0])
    a = render_scene(seed, cfg)
    b = render_scene(seed, cfg)
    for fa, fb in zip(a, b):
        assert np.array_equal(fa.rgb, fb.rgb) and np.array_equal(fa.depth_m, fb.depth_m, equal_nan=True)
        assert np.array_equal(fa.box_xyxy, fb.box_xyxy)
    other = render_scene(seed + 1, DatasetConfig(frames_per_scene=1))[0]
    assert not np.array_equal(other.rgb, a[0].rgb)
    # the committed fixture was rendered by TinyRenderer (camera.renderer: tiny), the shipped detector's training renderer
    f0 = render_scene(seed, cfg, CameraConfig(renderer="tiny"))[0]
    assert np.array_equal(f0.rgb, fixture_data["rgb"][0])
    assert np.array_equal(f0.depth_m.astype(np.float16), fixture_data["depth_m"][0], equal_nan=True)


def test_bad_dataset_config_names_the_field():
    with pytest.raises(ConfigError, match="distance_range_m"):
        DatasetConfig(distance_range_m=(5.0, 1.0))
    with pytest.raises(ConfigError, match="frames_per_scene"):
        DatasetConfig(frames_per_scene=0)


def test_truncation_rule_ignores_drones_whose_centre_leaves_the_image():
    from mpcde.training.dataset import centre_out_of_view
    from sim.camera import CameraConfig, intrinsics

    cam = CameraConfig()
    K = intrinsics(cam)
    T = np.eye(4)  # camera at the origin looking along world z (optical frame = world)
    W, H = cam.width_px, cam.height_px
    def at(u, v, z):
        return np.array([(u - K[0, 2]) * z / K[0, 0], (v - K[1, 2]) * z / K[1, 1], z])
    pts = np.stack([at(160, 120, 3.0), at(W - 0.6, 5, 2.0), at(W - 0.4, 5, 2.0), at(-0.6, 100, 1.0), at(100, H - 0.6, 4.0), at(160, 120, -3.0)])
    np.testing.assert_array_equal(centre_out_of_view(pts, K, T, (H, W)), [False, False, True, True, False, True])
