"""The learned detector: shipped weights find rendered drones, NMS and peaks, batching, bad weights, API."""

import inspect

import numpy as np
import pytest
import torch

from perception.detector import DEFAULT_WEIGHTS, DroneDetector, box_iou_xyxy, decode_outputs, nms_xyxy
from perception.detector.decode import decode_outputs_reference
from perception.detector.model import DetectorNet, ModelConfig, fold_batchnorm
from sim.bullet.scene import RenderStyle, SceneSpec
from sim.checks import ConfigError
from sim.camera import CameraConfig, apply_depth_sensor_model, intrinsics
from sim.rendering.camera_rig import CameraRig
from sim.rendering.tiny import PARKED_POS, SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.types import GroundTruthSegmentation, ObstacleSpec, RgbdFrame


@pytest.fixture(scope="module")
def detector() -> DroneDetector:
    return DroneDetector.load()


@pytest.fixture(scope="module")
def rendered():
    """Two cameras looking at drones at 1-5 m among obstacles; frames, mask boxes and visible fractions.

    A drone's visible fraction is its pixel count in the scene over its pixel
    count when rendered with the other drones parked (obstacles stay), so a
    drone hidden behind a nearer one shows a small fraction.
    """
    obstacles = (
        ObstacleSpec(kind="tree", center_xy=(5.5, 1.5), height_m=4.0, radius_m=0.25, rgba=(0.3, 0.45, 0.25, 1.0)),
        ObstacleSpec(kind="box", center_xy=(8.0, -2.0), height_m=2.5, half_extents_xy=(0.5, 0.4), yaw=0.4, rgba=(0.55, 0.45, 0.4, 1.0)),
        ObstacleSpec(kind="tree", center_xy=(-4.0, -1.0), height_m=4.5, radius_m=0.2, rgba=(0.45, 0.32, 0.2, 1.0)),
    )
    pos = np.array([[0.0, 0.0, 1.5], [1.2, 0.3, 1.6], [2.5, -0.7, 1.3], [3.8, 0.9, 1.8], [4.6, -1.4, 1.2], [-3.0, 0.5, 1.4], [-2.0, -0.4, 1.7]])
    quat = np.stack([quat_xyzw_from_yaw(y) for y in (0.0, 0.5, -1.0, 2.0, 0.8, 3.1, -2.5)])
    renderer = SceneRenderer(SceneSpec(obstacles=obstacles, n_drones=len(pos)), CameraConfig())
    rig = CameraRig(CameraConfig(), seed=0)
    frames, boxes, visible = [], [], []
    try:
        renderer.set_drone_poses(pos, quat)
        for cam, yaw in ((0, 0.0), (0, np.pi)):
            R = rotation_from_quat_xyzw(quat_xyzw_from_yaw(yaw))
            T = rig.transform_camera_to_world(pos[cam], R)
            raw = renderer.render(T, own_drone=cam, style=RenderStyle())
            depth = apply_depth_sensor_model(raw.depth_true_m, np.random.default_rng(len(frames)), CameraConfig())
            frames.append(RgbdFrame(drone_id=len(frames), time_s=0.0, rgb=raw.rgb, depth_m=depth, K=intrinsics(CameraConfig()), transform_camera_to_world=T))
            fb, fv = [], []
            for i in range(len(pos)):
                vs, us = np.nonzero(raw.drone_index_mask == i)
                if us.size:
                    fb.append([us.min() - 0.5, vs.min() - 0.5, us.max() + 0.5, vs.max() + 0.5])
                    alone = pos.copy()
                    alone[np.arange(len(pos)) != i] = PARKED_POS
                    renderer.set_drone_poses(alone, quat)
                    fv.append(us.size / np.count_nonzero(renderer.render(T, own_drone=None).drone_index_mask == i))
                    renderer.set_drone_poses(pos, quat)
            boxes.append(np.array(fb).reshape(-1, 4))
            visible.append(np.array(fv))
    finally:
        renderer.close()
    return frames, boxes, visible


def test_shipped_weights_find_every_mostly_visible_drone_at_1_to_5_m(detector, rendered):
    """Every drone at least half visible is found at IoU >= 0.5; at most one spurious detection per frame.

    Not required: a drone whose image centre lies within two heatmap cells
    (8 px) of a larger drone's centre. CenterNet's 3 x 3 peak pooling at
    stride 4 keeps one peak there (Zhou et al. 2019, Sec. 4: "centre point
    collisions"); in this scene a drone at 4.6 m, 7 x 3 px, sits just above
    the 17 x 7 px one at 2.5 m and the single detection covers the near one.
    """
    frames, boxes, visible = rendered
    detections = detector.detect(frames)
    required = 0
    for dets, truth, frac in zip(detections, boxes, visible):
        centre = 0.5 * (truth[:, :2] + truth[:, 2:])
        area = (truth[:, 2] - truth[:, 0]) * (truth[:, 3] - truth[:, 1])
        gap = np.linalg.norm(centre[:, None] - centre[None], axis=2)
        collides = np.any((gap < 8.0) & (area[None, :] > area[:, None]), axis=1)
        keep = (frac >= 0.5) & ~collides
        required += int(keep.sum())
        pred = np.array([d.box_xyxy for d in dets]).reshape(-1, 4)
        iou = box_iou_xyxy(truth[keep], pred)
        assert iou.shape[1] > 0 and np.all(iou.max(axis=1) >= 0.5), f"best IoU per true box {iou.max(axis=1) if iou.size else iou}"
        assert len(dets) <= len(truth) + 1
    assert required >= 4


def test_batch_equals_one_by_one(detector, rendered):
    frames, _, _ = rendered
    batch = detector.detect(frames + frames[:1], score_threshold=0.2)
    for f, dets in zip(frames + frames[:1], batch):
        single = detector.detect([f], score_threshold=0.2)[0]
        assert len(single) == len(dets)
        for a, b in zip(single, dets):
            assert a.box_xyxy == pytest.approx(b.box_xyxy, abs=1e-3) and a.score == pytest.approx(b.score, abs=1e-4)


def test_nms_keeps_the_best_of_overlapping_boxes():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [20, 20, 30, 30], [0, 0, 10, 4.0], [21, 20, 31, 30]], float)
    scores = np.array([0.6, 0.9, 0.5, 0.8, 0.7])
    # IoU(box0, box1) = 81 / 119 = 0.68; IoU(box0, box3) = 0.4; IoU(box2, box4) = 90 / 110 = 0.82
    assert list(nms_xyxy(boxes, scores, 0.5)) == [1, 3, 4]
    assert list(nms_xyxy(boxes, scores, 0.7)) == [1, 3, 4, 0]
    assert list(nms_xyxy(boxes, scores, 0.3)) == [1, 3, 4]  # IoU(box1, box3) = 27 / 113 = 0.24
    assert list(nms_xyxy(boxes, scores, 0.2)) == [1, 4]
    assert nms_xyxy(np.zeros((0, 4)), np.zeros(0), 0.5).size == 0
    assert box_iou_xyxy(boxes[:1], boxes[1:2])[0, 0] == pytest.approx(81 / 119)


@pytest.mark.parametrize("decode", [decode_outputs, decode_outputs_reference], ids=["compiled", "reference"])
def test_decode_finds_local_peaks_and_places_boxes(decode):
    out = torch.full((1, 5, 8, 10), 0.0)
    out[0, 0] = -8.0
    out[0, 0, 2, 3] = 3.0  # a peak ...
    out[0, 0, 2, 4] = 1.0  # ... and its weaker neighbour (not a peak)
    out[0, 0, 6, 8] = 0.5
    out[0, 1, 2, 3], out[0, 2, 2, 3] = np.log(2.0), np.log(1.5)  # 8 x 6 px box
    out[0, 3, 2, 3], out[0, 4, 2, 3] = 0.25, 0.75
    boxes, scores = decode(out, 0.3)[0]
    assert scores == pytest.approx([torch.sigmoid(torch.tensor(3.0)).item(), torch.sigmoid(torch.tensor(0.5)).item()])
    cu, cv = 4 * (3 + 0.25) - 0.5, 4 * (2 + 0.75) - 0.5
    assert boxes[0] == pytest.approx([cu - 4, cv - 3, cu + 4, cv + 3])
    assert len(decode(out, 0.7)[0][0]) == 1


@pytest.mark.parametrize("threshold", [0.02, 0.4])
def test_compiled_decode_equals_the_reference_on_the_network_outputs(detector, rendered, threshold):
    """Peaks, order, boxes (to 1e-9 px), scores (exactly) and NMS of the compiled decode equal the torch/numpy oracle's."""
    from perception.detector.encode_kernel import encode_channels_last

    frames, _, _ = rendered
    with torch.inference_mode():
        x = encode_channels_last([f.rgb for f in frames], [f.depth_m for f in frames], 4).to(next(detector.net.parameters()).dtype)
        out = detector.net(x).float()
    # large boxes overlapping a little: NMS has work to do at a low threshold
    for (ba, sa), (bb, sb) in zip(decode_outputs(out, threshold, 20, 0.3, (240, 320)), decode_outputs_reference(out, threshold, 20, 0.3, (240, 320))):
        assert ba.shape == bb.shape and len(sa) > 0
        np.testing.assert_allclose(ba, bb, atol=1e-9, rtol=0)
        np.testing.assert_array_equal(sa, sb)


@pytest.mark.parametrize("stem", ["conv", "patch"])
def test_folded_batchnorm_gives_the_same_outputs(stem):
    torch.manual_seed(0)
    net = DetectorNet(ModelConfig(stem=stem))
    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.2, 0.2)
            m.running_var.uniform_(0.5, 2.0)
            m.weight.data.uniform_(0.5, 1.5)
    net.eval()
    x = torch.randn(2, 4, 64, 96)
    with torch.no_grad():
        ref = net(x)
        got = fold_batchnorm(net)(x)
    assert torch.allclose(ref, got, atol=1e-4)


def test_patch_stem_sees_each_input_pixel_once_per_cell():
    """The patch stem's output cell (i, j) depends on input pixels [4i, 4i + 4) x [4j, 4j + 4) only."""
    torch.manual_seed(0)
    net = DetectorNet(ModelConfig(stem="patch")).eval()
    x = torch.randn(1, 4, 32, 48)
    with torch.no_grad():
        base = net.stem(x)
        x2 = x.clone()
        x2[0, :, 9, 13] += 5.0  # inside cell (2, 3)
        diff = (net.stem(x2) - base).abs().sum(dim=1)[0]
    assert base.shape == (1, 16, 8, 12)
    changed = torch.nonzero(diff > 0).tolist()
    assert changed == [[2, 3]]


def test_unknown_stem_is_a_config_error():
    with pytest.raises(ConfigError, match="stem"):
        ModelConfig(stem="resnet")


def test_bad_weights_raise_one_line_value_error(tmp_path):
    with pytest.raises(ValueError) as exc:
        DroneDetector.load(tmp_path / "nothing.pt")
    assert str(exc.value) == f"detector weights={tmp_path / 'nothing.pt'}: missing"
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint at all")
    wrong = tmp_path / "wrong.pt"
    torch.save({"format": "something-else", "state_dict": {}}, wrong)
    broken = tmp_path / "broken.pt"
    ckpt = torch.load(DEFAULT_WEIGHTS, weights_only=True)
    ckpt["state_dict"] = {k: v for k, v in list(ckpt["state_dict"].items())[:-2]}
    torch.save(ckpt, broken)
    for path in (garbage, wrong, broken):
        with pytest.raises(ValueError) as exc:
            DroneDetector.load(path)
        msg = str(exc.value)
        assert "\n" not in msg and msg.startswith(f"detector weights={path}: not a valid mpcde detector checkpoint (")


def test_detector_takes_rgbd_frames_only(detector, rendered):
    params = inspect.signature(DroneDetector.detect).parameters
    assert list(params) == ["self", "frames", "score_threshold"]
    seg = GroundTruthSegmentation(drone_id=0, time_s=0.0, drone_index_mask=np.zeros((240, 320), np.int16), transform_camera_to_world_true=np.eye(4))
    with pytest.raises(TypeError):
        detector.detect([seg])
    assert detector.detect([]) == []
    frames, _, _ = rendered
    with pytest.raises(ValueError, match="score_threshold"):
        detector.detect(frames[:1], score_threshold=1.5)


def test_allocator_thresholds_are_applied_once_on_glibc():
    import platform

    from perception.detector.allocator import keep_large_allocations

    first = keep_large_allocations()
    assert keep_large_allocations() is first
    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        assert first is True


def test_compiled_encoding_equals_the_torch_encoding_and_leaves_the_input_alone():
    """encode_channels_last (one compiled pass) == encode_frames (the oracle), special depths included."""
    from perception.detector.encode_kernel import encode_channels_last
    from perception.detector.model import encode_frames

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (3, 16, 32, 3), dtype=np.uint8)
    depth = rng.uniform(-1.0, 12.0, (3, 16, 32)).astype(np.float32)
    depth[0, 0, :5] = [np.nan, np.inf, -np.inf, 10.0, 0.0]
    before = depth.copy()
    fast = encode_channels_last(list(rgb), list(depth), 4)
    assert fast.is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(fast, encode_frames(rgb, depth, 4))
    assert torch.equal(encode_channels_last(list(rgb), None, 3), encode_frames(rgb, None, 3))
    np.testing.assert_array_equal(depth, before)  # neither encoder writes into the caller's depth


def test_bfloat16_detector_finds_the_same_drones_as_float32(rendered):
    """Same boxes to 1 px and scores to 0.02 at the shipped threshold (bfloat16 keeps 8 mantissa bits)."""
    frames, _, _ = rendered
    f32 = DroneDetector.load(precision="float32").detect(frames)
    b16 = DroneDetector.load(precision="bfloat16").detect(frames)
    for a, b in zip(f32, b16):
        assert len(a) == len(b)
        for da, db in zip(a, b):
            assert np.allclose(da.box_xyxy, db.box_xyxy, atol=1.0) and abs(da.score - db.score) < 0.02


def test_precision_auto_follows_the_cpu_flags():
    from perception.detector.detector import native_bfloat16, resolve_precision

    bf16_cpu = "processor\t: 0\nflags\t\t: fpu sse2 avx2 avx512f avx512_bf16\n"
    assert native_bfloat16(bf16_cpu, max_isa="") == torch.backends.mkldnn.is_available()
    assert native_bfloat16(bf16_cpu, max_isa="avx512_core_bf16") == torch.backends.mkldnn.is_available()
    assert not native_bfloat16(bf16_cpu, max_isa="AVX2")  # the portable profile's cap (mpcde/numerics.py)
    assert not native_bfloat16("flags\t\t: fpu sse2 avx2 avx512f\n", max_isa="")
    assert resolve_precision("auto") in ("float32", "bfloat16")
    assert resolve_precision("float32") == "float32"
    with pytest.raises(ValueError, match="precision='half'"):
        resolve_precision("half")
