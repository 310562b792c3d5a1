"""A rendered detector dataset on disk: written split by split in chunks, read back as arrays."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from mpcde.errors import ConfigError
from mpcde.training.dataset import LABEL_RULE, DatasetConfig, LabelledFrame, _pack, centre_out_of_view, iter_scenes, split_seeds
from sim.camera import CameraConfig

__all__ = ["load_dataset", "write_dataset"]


def write_dataset(
    out_dir: Path,
    split: str,
    n_frames: int,
    cfg: DatasetConfig = DatasetConfig(),
    camera: CameraConfig = CameraConfig(),
    frames_per_shard: int = 64,
    workers: int = 2,
    with_mask: bool = False,
    progress: bool = False,
) -> dict:
    """Render ``n_frames`` frames of ``split`` into ``out_dir/<split>/shard_XXXXX.npz``.

    Scene seeds are the first ``ceil(n_frames / frames_per_scene)`` of the
    split's range. Returns (and writes as ``manifest.json``) a summary: frames,
    labelled and ignore boxes, the seeds, the label thresholds.
    """
    if not (isinstance(n_frames, int) and n_frames >= 1):
        raise ConfigError("n_frames", n_frames, "an integer >= 1")
    n_scenes = -(-n_frames // cfg.frames_per_scene)
    seeds = split_seeds(split, n_scenes)
    folder = Path(out_dir) / split
    folder.mkdir(parents=True, exist_ok=True)
    from tqdm import tqdm

    bar = tqdm(total=n_frames, disable=not progress, desc=f"render {split}")
    buf: list[LabelledFrame] = []
    n_written, n_shards, n_boxes, n_ignore = 0, 0, 0, 0

    def flush() -> None:
        nonlocal n_shards
        if buf:
            np.savez_compressed(folder / f"shard_{n_shards:05d}.npz", **_pack(buf, with_mask))
            n_shards += 1
            buf.clear()

    for frames in iter_scenes(seeds, cfg, camera, workers):
        for fr in frames:
            if n_written >= n_frames:
                break
            buf.append(fr)
            n_written += 1
            n_boxes += int((~fr.ignore).sum())
            n_ignore += int(fr.ignore.sum())
            bar.update(1)
            if len(buf) >= frames_per_shard:
                flush()
    flush()
    bar.close()
    manifest = {
        "split": split,
        "n_frames": n_written,
        "n_shards": n_shards,
        "n_boxes": n_boxes,
        "n_ignore_boxes": n_ignore,
        "scene_seeds": [seeds[0], seeds[-1]],
        "label_rule": LABEL_RULE,
        "config": asdict(cfg),
    }
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=2))
    return manifest


def load_dataset(folder: Path, max_frames: int | None = None) -> dict[str, np.ndarray]:
    """Concatenate the shards under ``folder`` (one split) into one dict of arrays (box_frame re-indexed).

    With ``max_frames``, only the shards needed for that many frames are read
    (the result may hold up to one shard more).
    """
    shards = sorted(Path(folder).glob("shard_*.npz"))
    if not shards:
        raise ConfigError("dataset", str(folder), "a folder holding shard_*.npz files")
    parts: dict[str, list[np.ndarray]] = {}
    offset = 0
    for path in shards:
        if max_frames is not None and offset >= max_frames:
            break
        with np.load(path) as z:
            for key in z.files:
                a = z[key]
                if key == "box_frame":
                    a = a + offset
                parts.setdefault(key, []).append(a)
            offset += z["rgb"].shape[0]
    data = {k: np.concatenate(v) for k, v in parts.items()}
    f = data["box_frame"]  # the truncation rule, also for shards written before it
    data["box_ignore"] |= centre_out_of_view(data["box_pos_world"], data["K"][f], data["transform_camera_to_world"][f], data["rgb"].shape[1:3])
    return data
