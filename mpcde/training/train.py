"""Train the drone detector from nothing on CPU (``mpcde train-detector``).

Data: frames rendered by :mod:`mpcde.training.dataset` (train and val splits,
disjoint scene seeds), generated into ``out_dir/data`` unless an existing
dataset folder is given. Training (CenterNet, Zhou et al. 2019):

* targets on the stride-4 grid: an elliptical Gaussian per labelled box
  (sigma = ``GAUSS_ALPHA`` * box side / 6 in cells, floor 0.5 cell; TTFNet's
  shape), peak 1 at the centre cell; log-size and sub-cell offset regressed at
  the centre cell only; cells inside ignore boxes carry no heatmap loss;
* loss = penalty-reduced focal loss on the heatmap (alpha = 2, beta = 4,
  normalised by the number of boxes) + L1 on log-size + L1 on offset;
* batches of random crops (``crop_hw_px``; with probability 0.7 placed to
  contain a random labelled drone) with horizontal flips and colour jitter;
  a box cut by the crop keeps its clipped extent and becomes an ignore box
  when the clipped part falls under the label thresholds (an approximation:
  the exact visible box inside the crop would need the mask);
* AdamW, warm-up then cosine decay of the learning rate over the larger of
  the step fraction and the wall-clock budget fraction, so a run cut by the
  budget still ends annealed.

The score threshold shipped with the weights is the one that maximises F1 on
the validation split. Writes ``out_dir/drone_detector.pt`` and
``out_dir/model_card.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from mpcde.errors import ConfigError
from mpcde.training.dataset import LABEL_RULE, MIN_BOX_HEIGHT_PX, MIN_BOX_WIDTH_PX, DatasetConfig
from mpcde.training.dataset_files import load_dataset, write_dataset
from perception.detector.decode import decode_outputs
from perception.detector.detector import CHECKPOINT_FORMAT
from perception.detector.model import STRIDE, DetectorNet, ModelConfig, encode_frames

__all__ = ["GAUSS_ALPHA", "build_targets", "run_train_detector"]

GAUSS_ALPHA = 0.54
"""Gaussian extent relative to the box (TTFNet)."""


def build_targets(boxes_xyxy: np.ndarray, ignore: np.ndarray, shape_px: tuple[int, int]) -> dict[str, np.ndarray]:
    """CenterNet targets of one image.

    Args:
        boxes_xyxy: (n, 4) boxes [px] (pixel centres at integers).
        ignore: (n,) bool ignore flags.
        shape_px: (H, W) of the image, multiples of 4.

    Returns:
        ``heat`` (h, w) in [0, 1], ``weight`` (h, w) heatmap loss weight (0 in
        ignore boxes), ``index`` (m,) flat centre cells of the labelled boxes,
        ``size`` (m, 2) log(w/4), log(h/4), ``offset`` (m, 2) in [0, 1).
    """
    H, W = shape_px
    h, w = H // STRIDE, W // STRIDE
    heat = np.zeros((h, w), np.float32)
    weight = np.ones((h, w), np.float32)
    index, size, offset = [], [], []
    jj, ii = np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32)
    for box, ign in zip(np.asarray(boxes_xyxy, np.float32).reshape(-1, 4), np.asarray(ignore, bool)):
        if ign:
            j0, j1 = int(np.floor((box[0] + 0.5) / STRIDE)), int(np.ceil((box[2] + 0.5) / STRIDE))
            i0, i1 = int(np.floor((box[1] + 0.5) / STRIDE)), int(np.ceil((box[3] + 0.5) / STRIDE))
            weight[max(i0, 0) : max(i1, 0), max(j0, 0) : max(j1, 0)] = 0.0
            continue
        bw, bh = float(box[2] - box[0]), float(box[3] - box[1])
        qu = ((box[0] + box[2]) / 2 + 0.5) / STRIDE  # centre in cell units: c = 4 (j + offset) - 0.5
        qv = ((box[1] + box[3]) / 2 + 0.5) / STRIDE
        j, i = min(max(int(qu), 0), w - 1), min(max(int(qv), 0), h - 1)
        sx = max(GAUSS_ALPHA * bw / STRIDE / 6.0, 0.5)
        sy = max(GAUSS_ALPHA * bh / STRIDE / 6.0, 0.5)
        g = np.exp(-((jj[None, :] - j) ** 2) / (2 * sx * sx) - ((ii[:, None] - i) ** 2) / (2 * sy * sy))
        np.maximum(heat, g, out=heat)
        heat[i, j] = 1.0
        index.append(i * w + j)
        size.append([np.log(max(bw, 1.0) / STRIDE), np.log(max(bh, 1.0) / STRIDE)])
        offset.append([qu - j, qv - i])
    weight[heat >= 1.0] = 1.0
    return {
        "heat": heat,
        "weight": weight,
        "index": np.asarray(index, np.int64),
        "size": np.asarray(size, np.float32).reshape(-1, 2),
        "offset": np.asarray(offset, np.float32).reshape(-1, 2),
    }


def _focal_loss(logits: torch.Tensor, heat: torch.Tensor, weight: torch.Tensor, n_pos: int) -> torch.Tensor:
    """CenterNet's penalty-reduced focal loss (alpha = 2, beta = 4) summed and divided by max(n_pos, 1)."""
    p = torch.sigmoid(logits).clamp(1e-4, 1 - 1e-4)
    pos = heat >= 1.0
    pos_loss = -torch.log(p) * (1 - p) ** 2  # -(1 - p)^2 log p at centres
    neg_loss = -torch.log(1 - p) * p**2 * (1 - heat) ** 4  # -(1 - y)^4 p^2 log(1 - p) elsewhere
    loss = torch.where(pos, pos_loss, neg_loss) * weight
    return loss.sum() / max(n_pos, 1)


def _learning_rate(peak: float, progress: float) -> float:
    """Linear warm-up over the first 5 %, then cosine decay to 2 % of ``peak``; ``progress`` in [0, 1]."""
    if progress < 0.05:
        return peak * (0.1 + 0.9 * progress / 0.05)
    t = min((progress - 0.05) / 0.95, 1.0)
    return peak * (0.02 + 0.98 * 0.5 * (1.0 + np.cos(np.pi * t)))


def _sample_crop(data: dict, frame: int, boxes_of: list[np.ndarray], rng: np.random.Generator, crop_hw: tuple[int, int]):
    """One augmented crop: (rgb (h, w, 3) uint8, depth (h, w) float32, boxes (n, 4), ignore (n,))."""
    H, W = data["rgb"].shape[1:3]
    ch, cw = crop_hw
    rows = boxes_of[frame]
    boxes, ign = data["box_xyxy"][rows], data["box_ignore"][rows]
    lab = np.nonzero(~ign)[0]
    if lab.size and rng.uniform() < 0.7:
        b = boxes[rng.choice(lab)]
        cu, cv = (b[0] + b[2]) / 2, (b[1] + b[3]) / 2
        u0 = int(np.clip(rng.uniform(cu - cw + 4, cu - 4), 0, W - cw))
        v0 = int(np.clip(rng.uniform(cv - ch + 4, cv - 4), 0, H - ch))
    else:
        u0, v0 = int(rng.integers(0, W - cw + 1)), int(rng.integers(0, H - ch + 1))
    rgb = data["rgb"][frame, v0 : v0 + ch, u0 : u0 + cw]
    depth = data["depth_m"][frame, v0 : v0 + ch, u0 : u0 + cw].astype(np.float32)
    bx = boxes - np.array([u0, v0, u0, v0], np.float32)
    bx[:, 0::2] = np.clip(bx[:, 0::2], -0.5, cw - 0.5)
    bx[:, 1::2] = np.clip(bx[:, 1::2], -0.5, ch - 0.5)
    bw, bh = bx[:, 2] - bx[:, 0], bx[:, 3] - bx[:, 1]
    inside = (bw > 0) & (bh > 0)
    ign = ign | (bw < MIN_BOX_WIDTH_PX) | (bh < MIN_BOX_HEIGHT_PX)
    bx, ign = bx[inside], ign[inside]
    if rng.uniform() < 0.5:  # horizontal flip: u -> (cw - 1) - u, so x0' = cw - 1 - x1
        rgb, depth = rgb[:, ::-1], depth[:, ::-1]
        bx = np.stack([cw - 1 - bx[:, 2], bx[:, 1], cw - 1 - bx[:, 0], bx[:, 3]], axis=1)
    return rgb, depth, bx, ign


def _jitter(x: torch.Tensor, rng: np.random.Generator) -> torch.Tensor:
    """Colour jitter of encoded RGB (B, C, h, w) in place: brightness, per-channel gain, contrast, noise."""
    B = x.shape[0]
    gain = torch.from_numpy(rng.uniform(0.7, 1.3, (B, 1, 1, 1)) * rng.uniform(0.88, 1.12, (B, 3, 1, 1))).float()
    contrast = torch.from_numpy(rng.uniform(0.75, 1.25, (B, 1, 1, 1))).float()
    rgb = (x[:, :3] + 0.5) * gain
    mean = rgb.mean(dim=(1, 2, 3), keepdim=True)
    rgb = (rgb - mean) * contrast + mean
    rgb = rgb + torch.from_numpy(rng.uniform(0.0, 0.03, (B, 1, 1, 1))).float() * torch.randn_like(rgb)
    x[:, :3] = rgb.clamp(0.0, 1.0) - 0.5
    return x


def _ensure_dataset(data_dir: Path, n_train: int, n_val: int, progress: bool) -> None:
    """Render the train / val splits into ``data_dir`` unless enough frames are there already."""
    for split, n in (("train", n_train), ("val", n_val)):
        manifest = data_dir / split / "manifest.json"
        if manifest.exists() and json.loads(manifest.read_text())["n_frames"] >= n:
            continue
        write_dataset(data_dir, split, n, DatasetConfig(), progress=progress)


def _subset(data: dict, n_frames: int) -> dict:
    """The first ``n_frames`` frames of a loaded split and their boxes."""
    keep = data["box_frame"] < n_frames
    out = {k: (v[keep] if k.startswith("box_") else v[:n_frames]) for k, v in data.items()}
    return out


def predict_dataset(net: DetectorNet, data: dict, batch: int = 16) -> list[tuple[np.ndarray, np.ndarray]]:
    """Raw-threshold (0.05) detections of every frame of a loaded split (full frames)."""
    out = []
    net.eval()
    with torch.inference_mode():
        for s in range(0, data["rgb"].shape[0], batch):
            x = encode_frames(data["rgb"][s : s + batch], data["depth_m"][s : s + batch].astype(np.float32), net.cfg.in_channels)
            out += decode_outputs(net(x), 0.05, image_shape_px=data["rgb"].shape[1:3])
    return out


def run_train_detector(
    out_dir: Path,
    n_train_frames: int = 8000,
    epochs: int = 30,
    seed: int = 0,
    progress: bool = True,
    data_dir: Path | None = None,
    n_val_frames: int = 640,
    batch_size: int = 32,
    crop_hw_px: tuple[int, int] = (160, 224),
    lr: float = 3e-3,
    max_minutes: float = 24.0,
    model: ModelConfig = ModelConfig(c1=8, c2=16, c3=32, c4=64, stem="patch"),
    threads: int = 2,
) -> dict:
    """Generate (or reuse) data, train the detector on CPU, write weights and a model card.

    Args:
        out_dir: output folder; ``drone_detector.pt`` and ``model_card.json`` go here.
        n_train_frames: training frames (rendered if ``data_dir`` lacks them).
        epochs: passes over the training frames (one crop per frame per pass).
        seed: seeds the weights init, crop sampling and augmentation.
        progress: show progress bars.
        data_dir: dataset folder with ``train/`` and ``val/``; default ``out_dir/data``.
        n_val_frames: validation frames.
        batch_size: crops per step.
        crop_hw_px: (h, w) training crop [px], multiples of 16.
        lr: peak learning rate (warm-up, then cosine).
        max_minutes: wall-clock budget for the optimisation [min]; training stops
            (and saves) when it is spent.
        model: network widths and input channels.
        threads: torch CPU threads during the run (restored afterwards).

    Returns:
        The model card (also written as JSON).
    """
    if not (isinstance(epochs, int) and epochs >= 1):
        raise ConfigError("epochs", epochs, "an integer >= 1")
    if not (isinstance(n_train_frames, int) and n_train_frames >= 16):
        raise ConfigError("n_train_frames", n_train_frames, "an integer >= 16")
    if crop_hw_px[0] % 16 or crop_hw_px[1] % 16 or not (32 <= crop_hw_px[0] <= 240 and 32 <= crop_hw_px[1] <= 320):
        raise ConfigError("crop_hw_px", crop_hw_px, "multiples of 16 within 240 x 320")
    if not max_minutes > 0:
        raise ConfigError("max_minutes", max_minutes, "> 0")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    data_dir = Path(data_dir) if data_dir is not None else out_dir / "data"
    _ensure_dataset(data_dir, n_train_frames, n_val_frames, progress)
    train = _subset(load_dataset(data_dir / "train", n_train_frames), n_train_frames)
    val = _subset(load_dataset(data_dir / "val", n_val_frames), n_val_frames)
    threads_before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        return _train(out_dir, data_dir, train, val, epochs, seed, progress, batch_size, crop_hw_px, lr, max_minutes, model)
    finally:
        torch.set_num_threads(threads_before)


def _train(out_dir, data_dir, train, val, epochs, seed, progress, batch_size, crop_hw_px, lr, max_minutes, model) -> dict:
    """The optimisation, validation and writing of :func:`run_train_detector` (arguments as there)."""
    from tqdm import tqdm

    from mpcde.training.evaluate import choose_threshold, evaluate_detections, json_safe

    n_train = train["rgb"].shape[0]
    boxes_of = [np.nonzero(train["box_frame"] == f)[0] for f in range(n_train)]
    torch.manual_seed(seed)
    rng = np.random.default_rng([seed, 0x7EA1])
    net = DetectorNet(model)
    steps_per_epoch = max(n_train // batch_size, 1)
    total_steps = steps_per_epoch * epochs
    net = net.to(memory_format=torch.channels_last)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    t_start = time.perf_counter()
    history = []
    step = 0
    stopped_early = False
    bar = tqdm(total=total_steps, disable=not progress, desc="train-detector")
    for epoch in range(epochs):
        net.train()
        order = rng.permutation(n_train)
        sums = np.zeros(3)
        for s in range(steps_per_epoch):
            frames = order[s * batch_size : (s + 1) * batch_size]
            crops = [_sample_crop(train, int(f), boxes_of, rng, crop_hw_px) for f in frames]
            x = encode_frames(np.stack([c[0] for c in crops]), np.stack([c[1] for c in crops]), model.in_channels)
            x = _jitter(x, rng).contiguous(memory_format=torch.channels_last)
            progress_frac = max(step / total_steps, (time.perf_counter() - t_start) / (60.0 * max_minutes))
            for group in opt.param_groups:
                group["lr"] = _learning_rate(lr, progress_frac)
            targets = [build_targets(c[2], c[3], crop_hw_px) for c in crops]
            out = net(x)
            heat = torch.from_numpy(np.stack([t["heat"] for t in targets]))
            weight = torch.from_numpy(np.stack([t["weight"] for t in targets]))
            n_pos = sum(t["index"].size for t in targets)
            l_heat = _focal_loss(out[:, 0], heat, weight, n_pos)
            if n_pos:
                hw = out.shape[2] * out.shape[3]
                flat = torch.from_numpy(np.concatenate([t["index"] + b * hw for b, t in enumerate(targets)]))
                reg = out[:, 1:].permute(0, 2, 3, 1).reshape(-1, 4)[flat]
                l_size = F.l1_loss(reg[:, :2], torch.from_numpy(np.concatenate([t["size"] for t in targets])))
                l_off = F.l1_loss(reg[:, 2:], torch.from_numpy(np.concatenate([t["offset"] for t in targets])))
            else:
                l_size = l_off = out.sum() * 0.0
            loss = l_heat + l_size + l_off
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            sums += [l_heat.item(), l_size.item(), l_off.item()]
            bar.update(1)
            bar.set_postfix(heat=f"{l_heat.item():.3f}", size=f"{l_size.item():.3f}", off=f"{l_off.item():.3f}")
            if time.perf_counter() - t_start > 60.0 * max_minutes:
                stopped_early = step < total_steps
                break
        history.append({"epoch": epoch + 1, "loss_heat": sums[0] / (s + 1), "loss_size": sums[1] / (s + 1), "loss_offset": sums[2] / (s + 1)})
        if stopped_early:
            break
    bar.close()
    train_s = time.perf_counter() - t_start

    predictions = predict_dataset(net, val)
    threshold = choose_threshold(predictions, val)
    val_metrics = evaluate_detections(predictions, val, threshold)
    checkpoint = {
        "format": CHECKPOINT_FORMAT,
        "model_config": model.to_dict(),
        "state_dict": net.state_dict(),
        "score_threshold": threshold,
    }
    weights_path = out_dir / "drone_detector.pt"
    torch.save(checkpoint, weights_path)
    card = {
        "model": "CenterNet-style single-stage detector, stride 4, RGB-D input" if model.in_channels == 4 else "CenterNet-style, RGB input",
        "model_config": model.to_dict(),
        "parameters": int(sum(p.numel() for p in net.parameters())),
        "weights_bytes": weights_path.stat().st_size,
        "data": {
            "dataset_dir": str(data_dir),
            "train_frames": n_train,
            "train_boxes": int((~train["box_ignore"]).sum()),
            "val_frames": int(val["rgb"].shape[0]),
            "val_boxes": int((~val["box_ignore"]).sum()),
            "label_rule": LABEL_RULE,
        },
        "training": {
            "epochs_planned": epochs,
            "epochs_run": len(history),
            "steps": step,
            "stopped_early_by_time_budget": stopped_early,
            "batch_size": batch_size,
            "crop_hw_px": list(crop_hw_px),
            "lr": lr,
            "seed": seed,
            "train_time_s": round(train_s, 1),
            "torch_threads": torch.get_num_threads(),
            "history": history,
        },
        "score_threshold": threshold,
        "val_metrics": val_metrics,
    }
    (out_dir / "model_card.json").write_text(json.dumps(json_safe(card), indent=2))
    return card
