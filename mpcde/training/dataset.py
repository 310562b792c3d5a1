"""Domain-randomised detector dataset rendered by sim/ (labels from the segmentation).

Each *scene seed* builds one world (obstacles with random colours, up to
``n_drones_max`` quadrotors) in the renderer ``camera.renderer`` names (:func:`sim.rendering.pool.make_renderer`) and
renders ``frames_per_scene`` frames from it. Per frame it draws:

* the camera: position in the arena (0.5-3 m high), any heading, roll and
  pitch perturbed uniformly within +-``camera_tilt_deg`` (the camera transform
  is perturbed directly, as a tilting airframe would);
* 0..``n_drones_max`` other drones at a true distance uniform in
  ``distance_range_m`` along a ray through a pixel drawn uniformly over the image
  widened by ``border_margin`` on each side (so some drones are cut by the image
  border), with random yaw and roll/pitch within +-``drone_tilt_deg``; drones
  behind or among the obstacles end up partly occluded; drones may not touch an
  obstacle, the ground or each other;
* the look (:class:`sim.bullet.scene.RenderStyle`): light direction, ambient, diffuse,
  specular, ground colour and checker contrast, sky colour;
* the depth sensor model (:func:`sim.camera.apply_depth_sensor_model`) with a
  random share of dropped pixels.

Labels come from the visible pixels of each drone in ``drone_index_mask``.
Box convention: ``[u_min - 0.5, v_min - 0.5, u_max + 0.5, v_max + 0.5]`` [px]
over the visible pixels (pixel centres sit at integer coordinates, as in K), so
a box's width is the number of columns it covers. A drone is *labelled* when its
box is at least ``MIN_BOX_WIDTH_PX`` wide, ``MIN_BOX_HEIGHT_PX`` high and it has
at least ``MIN_VISIBLE_PX`` visible pixels, and its centre projects inside the
image; any other drone with at least one visible pixel is kept as an *ignore*
box (training does not penalise a peak there; evaluation counts a detection on
it neither as a true nor as a false positive). The centre rule is KITTI's
"truncated" class: a drone cut by the image border past its centre shows a box
whose centre is not the drone's, so back-projection (MP-CDE Eq. 7-8) cannot
place it and no downstream consumer can use it (:func:`centre_out_of_view`;
it is applied when a split is loaded too, so shards written before it follow it).

Splits are disjoint ranges of scene seeds (``SPLIT_SEED_BASE``); a frame's
content depends only on (scene seed, frame index), never on the worker that
rendered it. Shards are ``shard_XXXXX.npz`` (compressed) in a folder with a
``manifest.json``.
"""

from __future__ import annotations

import multiprocessing as mp
from dataclasses import asdict, dataclass
from typing import Iterator, Sequence

import numpy as np

from mpcde.errors import ConfigError
from sim.bullet.scene import RenderStyle, SceneSpec
from sim.camera import CameraConfig, apply_depth_sensor_model, intrinsics, rotation_camera_to_body
from sim.obstacles import distance_to_obstacles, generate_obstacles
from sim.rendering.pool import make_renderer
from sim.rendering.tiny import PARKED_POS
from sim.rotations import quat_xyzw_from_rotation
from sim.spawn import main_module_hidden, sigint_ignored
from sim.types import ObstacleSpec

__all__ = [
    "LABEL_RULE",
    "MIN_BOX_HEIGHT_PX",
    "MIN_BOX_WIDTH_PX",
    "MIN_VISIBLE_PX",
    "centre_out_of_view",
    "SPLIT_SEED_BASE",
    "DatasetConfig",
    "LabelledFrame",
    "boxes_from_mask",
    "iter_scenes",
    "render_scene",
    "split_seeds",
]

MIN_BOX_WIDTH_PX = 3
"""Narrower visible boxes are ignore boxes [px]."""
MIN_BOX_HEIGHT_PX = 2
"""Lower visible boxes are ignore boxes [px]."""
MIN_VISIBLE_PX = 6
"""Drones with fewer visible pixels are ignore boxes."""

LABEL_RULE = (
    f"box width >= {MIN_BOX_WIDTH_PX} px, height >= {MIN_BOX_HEIGHT_PX} px, >= {MIN_VISIBLE_PX} visible px "
    "and centre inside the image; else ignore"
)
"""The labelling rule in words (manifests and model cards)."""

SPLIT_SEED_BASE = {"train": 0, "val": 1_000_000, "test": 2_000_000}
"""First scene seed of each split; each split owns [base, base + 1_000_000)."""
SPLIT_SIZE = 1_000_000


@dataclass(frozen=True)
class DatasetConfig:
    """How frames are drawn (see the module docstring).

    Attributes:
        frames_per_scene: frames rendered per scene seed.
        n_drones_max: most other drones in view per frame.
        empty_frame_prob: probability of a frame with no drone placed.
        distance_range_m: (2,) range of true camera-to-drone distance [m].
        border_margin: share of the image width/height by which drone centres
            may fall outside the image.
        camera_tilt_deg: camera roll and pitch perturbation bound [deg].
        drone_tilt_deg: other drones' roll and pitch bound [deg].
        obstacle_density_range: (2,) obstacles per 100 m^2.
        arena_half_m: half size of the square arena [m].
        max_invalid_pixel_fraction: upper bound of the random dropped-pixel share.
    """

    frames_per_scene: int = 8
    n_drones_max: int = 5
    empty_frame_prob: float = 0.08
    distance_range_m: tuple[float, float] = (0.3, 10.0)
    border_margin: float = 0.06
    camera_tilt_deg: float = 20.0
    drone_tilt_deg: float = 30.0
    obstacle_density_range: tuple[float, float] = (0.5, 7.0)
    arena_half_m: float = 14.0
    max_invalid_pixel_fraction: float = 0.03

    def __post_init__(self) -> None:
        if not (isinstance(self.frames_per_scene, int) and self.frames_per_scene >= 1):
            raise ConfigError("frames_per_scene", self.frames_per_scene, "an integer >= 1")
        if not (isinstance(self.n_drones_max, int) and 1 <= self.n_drones_max <= 16):
            raise ConfigError("n_drones_max", self.n_drones_max, "an integer in [1, 16]")
        if not 0.0 <= self.empty_frame_prob < 1.0:
            raise ConfigError("empty_frame_prob", self.empty_frame_prob, "in [0, 1)")
        lo, hi = self.distance_range_m
        if not 0.25 <= lo < hi <= 30.0:
            raise ConfigError("distance_range_m", self.distance_range_m, "0.25 <= min < max <= 30 m")
        if not 0.0 <= self.border_margin <= 0.3:
            raise ConfigError("border_margin", self.border_margin, "in [0, 0.3]")
        for name in ("camera_tilt_deg", "drone_tilt_deg"):
            if not 0.0 <= getattr(self, name) <= 60.0:
                raise ConfigError(name, getattr(self, name), "in [0, 60] deg")
        dlo, dhi = self.obstacle_density_range
        if not 0.0 <= dlo <= dhi <= 20.0:
            raise ConfigError("obstacle_density_range", self.obstacle_density_range, "0 <= min <= max <= 20 per 100 m^2")
        if not self.arena_half_m >= 5.0:
            raise ConfigError("arena_half_m", self.arena_half_m, ">= 5 m")
        if not 0.0 <= self.max_invalid_pixel_fraction < 0.5:
            raise ConfigError("max_invalid_pixel_fraction", self.max_invalid_pixel_fraction, "in [0, 0.5)")


@dataclass(frozen=True)
class LabelledFrame:
    """One rendered frame with its labels (ground truth: datasets and metrics only).

    Attributes:
        scene_seed: the scene seed; ``frame_index``: index within the scene.
        rgb: (H, W, 3) uint8.
        depth_m: (H, W) float32 sensor-model depth [m], NaN invalid.
        K: (3, 3) intrinsics.
        transform_camera_to_world: (4, 4) true camera pose.
        drone_index_mask: (H, W) int16 drone index or -1.
        box_xyxy: (n, 4) float32 visible boxes [px] (convention in the module docstring).
        ignore: (n,) bool, True for boxes below the size threshold.
        distance_m: (n,) true camera-centre-to-drone-centre distance [m].
        pos_world: (n, 3) true drone positions [m].
        drone_index: (n,) int drone index of each box.
    """

    scene_seed: int
    frame_index: int
    rgb: np.ndarray
    depth_m: np.ndarray
    K: np.ndarray
    transform_camera_to_world: np.ndarray
    drone_index_mask: np.ndarray
    box_xyxy: np.ndarray
    ignore: np.ndarray
    distance_m: np.ndarray
    pos_world: np.ndarray
    drone_index: np.ndarray


def split_seeds(split: str, n_scenes: int, offset: int = 0) -> list[int]:
    """Scene seeds ``[base + offset, base + offset + n_scenes)`` of ``split`` ('train', 'val', 'test')."""
    if split not in SPLIT_SEED_BASE:
        raise ConfigError("split", split, "'train', 'val' or 'test'")
    if offset < 0 or n_scenes < 1 or offset + n_scenes > SPLIT_SIZE:
        raise ConfigError("n_scenes", n_scenes, f"offset + n_scenes <= {SPLIT_SIZE}")
    base = SPLIT_SEED_BASE[split] + offset
    return list(range(base, base + n_scenes))


def centre_out_of_view(pos_world: np.ndarray, K: np.ndarray, transform_camera_to_world: np.ndarray, shape_px: tuple[int, int]) -> np.ndarray:
    """Whether each drone centre lies outside the image (or behind the camera): the truncation ignore rule.

    Args:
        pos_world: (n, 3) drone centres [m].
        K: (3, 3) intrinsics (pixel centres at integers), or (n, 3, 3), one per centre.
        transform_camera_to_world: (4, 4) camera pose, or (n, 4, 4), one per centre.
        shape_px: (H, W) image size.

    Returns:
        (n,) bool.
    """
    T = np.asarray(transform_camera_to_world, float)
    K = np.asarray(K, float)
    delta = np.asarray(pos_world, float).reshape(-1, 3) - T[..., :3, 3]
    p_c = np.einsum("...ji,...j->...i", T[..., :3, :3], delta)  # R^T (p - t)
    z = p_c[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K[..., 0, 0] * p_c[..., 0] / z + K[..., 0, 2]
        v = K[..., 1, 1] * p_c[..., 1] / z + K[..., 1, 2]
    H, W = shape_px
    inside = (z > 0) & (u >= -0.5) & (u <= W - 0.5) & (v >= -0.5) & (v <= H - 0.5)
    return ~inside


def boxes_from_mask(mask: np.ndarray, n_drones: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Visible boxes of drones ``0..n_drones-1`` in ``mask`` (H, W) int16.

    Returns:
        drone indices (m,) of the drones with at least one visible pixel, their
        boxes (m, 4) float32 ``[u_min - 0.5, v_min - 0.5, u_max + 0.5, v_max + 0.5]``,
        and their visible pixel counts (m,).
    """
    ids, boxes, counts = [], [], []
    for i in range(n_drones):
        vs, us = np.nonzero(mask == i)
        if us.size == 0:
            continue
        ids.append(i)
        boxes.append([us.min() - 0.5, vs.min() - 0.5, us.max() + 0.5, vs.max() + 0.5])
        counts.append(us.size)
    return np.asarray(ids, np.int64), np.asarray(boxes, np.float32).reshape(-1, 4), np.asarray(counts, np.int64)


def _rotation_xyz(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """(3, 3) R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return Rz @ Ry @ Rx


def _random_style(rng: np.random.Generator) -> RenderStyle:
    """A random look: light, shading coefficients, ground and sky colours."""
    az, el = rng.uniform(-np.pi, np.pi), rng.uniform(0.2, 1.5)
    sky = rng.uniform(0.5, 1.0, 3) if rng.uniform() < 0.7 else rng.uniform(0.1, 1.0, 3)
    return RenderStyle(
        light_direction=(float(np.cos(el) * np.cos(az)), float(np.cos(el) * np.sin(az)), float(np.sin(el))),
        ambient=float(rng.uniform(0.3, 0.8)),
        diffuse=float(rng.uniform(0.1, 0.6)),
        specular=float(rng.uniform(0.0, 0.2)),
        ground_rgb=tuple(float(c) for c in rng.uniform(0.1, 0.8, 3)),
        ground_checker_contrast=float(rng.uniform(0.0, 0.35)),
        sky_rgb=tuple(float(c) for c in sky),
    )


def _scene_obstacles(rng: np.random.Generator, cfg: DatasetConfig, cam_xy: np.ndarray) -> tuple[ObstacleSpec, ...]:
    """Obstacles of the standard generator, recoloured at random, clear of the camera positions (k, 2)."""
    density = rng.uniform(*cfg.obstacle_density_range)
    size = 2.0 * cfg.arena_half_m
    obstacles = generate_obstacles(rng, (size, size), density, cam_xy, clear_radius_m=0.6)
    out = []
    for ob in obstacles:
        rgb = rng.uniform(0.05, 0.95, 3)
        out.append(ObstacleSpec(ob.kind, ob.center_xy, ob.height_m, ob.radius_m, ob.half_extents_xy, ob.yaw, (*map(float, rgb), 1.0)))
    return tuple(out)


def render_scene(scene_seed: int, cfg: DatasetConfig = DatasetConfig(), camera: CameraConfig = CameraConfig()) -> list[LabelledFrame]:
    """Render the ``cfg.frames_per_scene`` frames of one scene seed (deterministic per seed)."""
    rng = np.random.default_rng([0xD7EC, int(scene_seed)])
    n_frames = cfg.frames_per_scene
    cam_xy = rng.uniform(-0.5 * cfg.arena_half_m, 0.5 * cfg.arena_half_m, (n_frames, 2))
    obstacles = _scene_obstacles(rng, cfg, cam_xy)
    n = cfg.n_drones_max
    renderer = make_renderer(SceneSpec(obstacles=obstacles, n_drones=n), camera)
    K = intrinsics(camera)
    K_inv = np.linalg.inv(K)
    R_cb = rotation_camera_to_body(camera.mount_pitch_deg)
    W, H = camera.width_px, camera.height_px
    frames = []
    try:
        for f in range(n_frames):
            tilt = np.radians(cfg.camera_tilt_deg)
            R_bw = _rotation_xyz(rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt), rng.uniform(-np.pi, np.pi))
            T_cw = np.eye(4)
            T_cw[:3, :3] = R_bw @ R_cb
            T_cw[:3, 3] = [cam_xy[f, 0], cam_xy[f, 1], rng.uniform(0.5, 3.0)]
            k = 0 if rng.uniform() < cfg.empty_frame_prob else int(rng.integers(1, n + 1))
            pos = np.tile(np.asarray(PARKED_POS, float), (n, 1)) + np.arange(n)[:, None] * [1.0, 0.0, 0.0]
            quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
            placed = 0
            for _try in range(30 * max(k, 1)):
                if placed >= k:
                    break
                m = cfg.border_margin
                u, v = rng.uniform(-m * W, (1 + m) * W), rng.uniform(-m * H, (1 + m) * H)
                ray_c = K_inv @ np.array([u, v, 1.0])
                d = rng.uniform(*cfg.distance_range_m)
                p = T_cw[:3, :3] @ (d * ray_c / np.linalg.norm(ray_c)) + T_cw[:3, 3]
                if p[2] < 0.15 or (obstacles and distance_to_obstacles(p[None], obstacles)[0] < 0.12):
                    continue
                if placed and np.min(np.linalg.norm(pos[:placed] - p, axis=1)) < 0.3:
                    continue
                dt = np.radians(cfg.drone_tilt_deg)
                pos[placed] = p
                quat[placed] = quat_xyzw_from_rotation(_rotation_xyz(rng.uniform(-dt, dt), rng.uniform(-dt, dt), rng.uniform(-np.pi, np.pi)))
                placed += 1
            renderer.set_drone_poses(pos, quat)
            style = _random_style(rng)
            raw = renderer.render(T_cw, own_drone=None, style=style)
            sensor = CameraConfig(**{**asdict(camera), "invalid_pixel_fraction": float(rng.uniform(0.0, cfg.max_invalid_pixel_fraction))})
            depth_m = apply_depth_sensor_model(raw.depth_true_m, np.random.default_rng([0xD7ED, int(scene_seed), f]), sensor)
            ids, boxes, counts = boxes_from_mask(raw.drone_index_mask, placed)
            w, h = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
            ignore = (w < MIN_BOX_WIDTH_PX) | (h < MIN_BOX_HEIGHT_PX) | (counts < MIN_VISIBLE_PX)
            ignore |= centre_out_of_view(pos[ids], K, T_cw, (H, W))
            frames.append(
                LabelledFrame(
                    scene_seed=int(scene_seed),
                    frame_index=f,
                    rgb=raw.rgb,
                    depth_m=depth_m,
                    K=K,
                    transform_camera_to_world=T_cw,
                    drone_index_mask=raw.drone_index_mask,
                    box_xyxy=boxes,
                    ignore=ignore,
                    distance_m=np.linalg.norm(pos[ids] - T_cw[:3, 3], axis=1) if ids.size else np.zeros(0),
                    pos_world=pos[ids].reshape(-1, 3),
                    drone_index=ids,
                )
            )
    finally:
        renderer.close()
    return frames


def _pack(frames: Sequence[LabelledFrame], with_mask: bool) -> dict[str, np.ndarray]:
    """Arrays of one shard: per-frame stacks and per-box rows with their frame index."""
    out = {
        "rgb": np.stack([f.rgb for f in frames]),
        "depth_m": np.stack([f.depth_m for f in frames]).astype(np.float16),
        "K": np.stack([f.K for f in frames]),
        "transform_camera_to_world": np.stack([f.transform_camera_to_world for f in frames]),
        "scene_seed": np.array([f.scene_seed for f in frames], np.int64),
        "frame_index": np.array([f.frame_index for f in frames], np.int64),
        "box_frame": np.concatenate([np.full(len(f.box_xyxy), i, np.int64) for i, f in enumerate(frames)]),
        "box_xyxy": np.concatenate([f.box_xyxy for f in frames]).astype(np.float32).reshape(-1, 4),
        "box_ignore": np.concatenate([f.ignore for f in frames]).astype(bool),
        "box_distance_m": np.concatenate([f.distance_m for f in frames]).astype(np.float32),
        "box_pos_world": np.concatenate([f.pos_world for f in frames]).reshape(-1, 3),
        "box_drone_index": np.concatenate([f.drone_index for f in frames]).astype(np.int64),
    }
    if with_mask:
        out["drone_index_mask"] = np.stack([f.drone_index_mask for f in frames]).astype(np.int8)
    return out


def _render_scene_job(args: tuple[int, DatasetConfig, CameraConfig]) -> list[LabelledFrame]:
    return render_scene(*args)


def iter_scenes(seeds: Sequence[int], cfg: DatasetConfig, camera: CameraConfig, workers: int) -> Iterator[list[LabelledFrame]]:
    """Rendered scenes in seed order, from a spawn pool of ``workers`` processes (1: in-process)."""
    jobs = [(s, cfg, camera) for s in seeds]
    if workers <= 1:
        for j in jobs:
            yield _render_scene_job(j)
        return
    with main_module_hidden(), sigint_ignored():  # sim/spawn.py; Ctrl-C is the parent's (the pool is terminated)
        pool = mp.get_context("spawn").Pool(workers)
    with pool:
        yield from pool.imap(_render_scene_job, jobs, chunksize=2)
