"""Detector evaluation on held-out renders (``mpcde eval-detector``).

Frames come from :func:`mpcde.training.dataset.render_scene` with scene seeds
of the *test* split (never seen in training or validation). Scoring:

* a detection is a true positive when it matches a labelled box at IoU >= 0.5;
  matching is greedy by decreasing score, each box matched at most once, to the
  unmatched box of highest IoU. An unmatched detection that overlaps an
  *ignore* box (a drone under the label thresholds, see
  :mod:`mpcde.training.dataset`) at IoU >= 0.3 or has its centre inside it is
  neither a true nor a false positive;
* precision and recall at the detector's own score threshold (the one shipped
  in the checkpoint);
* AP@0.5: area under the interpolated precision-recall curve (precision made
  monotone from the right, summed over every recall step; PASCAL VOC 2010+ /
  COCO's all-point form) over all detections scoring >= 0.05;
* distance bins: a labelled box belongs to the bin of its true distance; a true
  positive to its box's bin; a false positive to the bin of its back-projected
  range (:func:`perception.backprojection.box_depth_m` along the box centre
  ray), or, without valid depth, of the range a 0.2 m wide drone of that box
  width would have (``fx * 0.2 / width``).

Back-projection through the full pipeline (render -> detect -> back-project):
for every true positive at the operating threshold, the 3-D error between
:func:`perception.backprojection.backproject` and the drone's true centre; the
frames carry the *true* camera pose here (no self-localisation error), so the
figure isolates detection + depth. Goal: median <= 5 cm + 1 % of range.

Writes ``out_dir/results.json``, ``out_dir/backprojection.json`` and
``out_dir/results.txt``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from mpcde.errors import ConfigError
from mpcde.flight.run_folder import staged_output
from mpcde.training.dataset import SPLIT_SEED_BASE, SPLIT_SIZE, DatasetConfig, LabelledFrame, iter_scenes, split_seeds
from perception.backprojection import backproject, box_depth_m
from perception.detector.decode import box_iou_xyxy
from perception.types import Detection
from sim.camera import CameraConfig
from sim.types import RgbdFrame

__all__ = [
    "DISTANCE_BINS_M",
    "average_precision",
    "choose_threshold",
    "evaluate_detections",
    "format_table",
    "json_safe",
    "match_frame",
    "run_eval_detector",
]

DISTANCE_BINS_M = ((0.0, 2.0), (2.0, 4.0), (4.0, 6.0), (6.0, 8.0), (8.0, 10.0))
AP_MIN_SCORE = 0.05
IGNORE_IOU = 0.3
TP, FP, IGNORED = 1, 0, -1


def match_frame(
    boxes: np.ndarray, scores: np.ndarray, gt_boxes: np.ndarray, gt_ignore: np.ndarray, iou_threshold: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Match one frame's detections (k, 4), scores (k,) to labelled boxes (m, 4) with ignore flags (m,).

    Returns:
        status (k,) in {TP = 1, FP = 0, IGNORED = -1} and matched box index (k,) (-1 if none).
    """
    boxes = np.asarray(boxes, float).reshape(-1, 4)
    order = np.argsort(-np.asarray(scores, float), kind="stable")
    gt_boxes = np.asarray(gt_boxes, float).reshape(-1, 4)
    gt_ignore = np.asarray(gt_ignore, bool)
    status = np.full(boxes.shape[0], FP, np.int64)
    matched = np.full(boxes.shape[0], -1, np.int64)
    iou = box_iou_xyxy(boxes, gt_boxes)
    taken = gt_ignore.copy()
    for k in order:
        cand = np.where(taken, -1.0, iou[k]) if gt_boxes.size else np.zeros(0)
        if cand.size and cand.max() >= iou_threshold:
            g = int(np.argmax(cand))
            status[k], matched[k] = TP, g
            taken[g] = True
            continue
        if gt_ignore.any():
            cu, cv = (boxes[k, 0] + boxes[k, 2]) / 2, (boxes[k, 1] + boxes[k, 3]) / 2
            ig = gt_boxes[gt_ignore]
            inside = (ig[:, 0] - 1 <= cu) & (cu <= ig[:, 2] + 1) & (ig[:, 1] - 1 <= cv) & (cv <= ig[:, 3] + 1)
            if np.any(inside) or np.max(iou[k][gt_ignore]) >= IGNORE_IOU:
                status[k] = IGNORED
    return status, matched


def average_precision(scores: np.ndarray, is_tp: np.ndarray, n_gt: int) -> float:
    """All-point interpolated AP: area under the precision-recall curve with precision made monotone.

    Args:
        scores: (k,) detection scores; is_tp: (k,) bool; n_gt: number of labelled boxes.
    """
    if n_gt == 0:
        return float("nan")
    order = np.argsort(-np.asarray(scores, float), kind="stable")
    tp = np.asarray(is_tp, bool)[order]
    ctp, cfp = np.cumsum(tp), np.cumsum(~tp)
    recall = np.concatenate([[0.0], ctp / n_gt])
    precision = np.concatenate([[1.0], ctp / np.maximum(ctp + cfp, 1)])
    precision = np.maximum.accumulate(precision[::-1])[::-1]  # p_interp(r) = max_{r' >= r} p(r')
    return float(np.sum((recall[1:] - recall[:-1]) * precision[1:]))


def _fp_distance_m(box: np.ndarray, depth_m: np.ndarray, K: np.ndarray) -> float:
    """Range [m] assigned to a false positive: back-projected, else from the box width."""
    d, _ = box_depth_m(depth_m, box)
    if np.isfinite(d):
        ray = np.linalg.solve(K, np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2, 1.0]))
        return float(d * np.linalg.norm(ray))
    return float(K[0, 0] * 0.2 / max(box[2] - box[0], 1.0))


def _scored(predictions: Sequence[tuple[np.ndarray, np.ndarray]], data: dict) -> list[dict]:
    """Per-frame matching of all predictions (score >= AP_MIN_SCORE)."""
    out = []
    for f, (boxes, scores) in enumerate(predictions):
        keep = scores >= AP_MIN_SCORE
        boxes, scores = boxes[keep], scores[keep]
        rows = np.nonzero(data["box_frame"] == f)[0]
        status, matched = match_frame(boxes, scores, data["box_xyxy"][rows], data["box_ignore"][rows])
        depth = np.asarray(data["depth_m"][f], np.float32) if np.any(status == FP) else None
        dist = np.array(
            [data["box_distance_m"][rows[m]] if s == TP else _fp_distance_m(b, depth, data["K"][f]) if s == FP else np.nan
             for b, s, m in zip(boxes, status, matched)]
        )
        out.append({"boxes": boxes, "scores": scores, "status": status, "dist": dist})
    return out


def _metrics(scored: list[dict], data: dict, threshold: float, lo: float, hi: float) -> dict:
    """Precision, recall at ``threshold`` and AP@0.5 for labelled boxes / detections with distance in [lo, hi)."""
    gt = (~data["box_ignore"]) & (data["box_distance_m"] >= lo) & (data["box_distance_m"] < hi)
    n_gt = int(gt.sum())
    scores = np.concatenate([s["scores"] for s in scored]) if scored else np.zeros(0)
    status = np.concatenate([s["status"] for s in scored]) if scored else np.zeros(0, int)
    dist = np.concatenate([s["dist"] for s in scored]) if scored else np.zeros(0)
    sel = (status != IGNORED) & (dist >= lo) & (dist < hi)
    scores, is_tp = scores[sel], status[sel] == TP
    at = scores >= threshold
    n_tp, n_det = int(is_tp[at].sum()), int(at.sum())
    return {
        "min_m": lo,
        "max_m": hi,
        "n": n_gt,
        "precision": n_tp / n_det if n_det else float("nan"),
        "recall": n_tp / n_gt if n_gt else float("nan"),
        "ap50": average_precision(scores, is_tp, n_gt),
    }


def evaluate_detections(predictions: Sequence[tuple[np.ndarray, np.ndarray]], data: dict, threshold: float) -> dict:
    """``{"overall": {...}, "by_distance": [...]}`` of per-frame (boxes (k, 4), scores (k,)) against a loaded split."""
    scored = _scored(predictions, data)
    overall = _metrics(scored, data, threshold, 0.0, np.inf)
    return {
        "overall": {k: overall[k] for k in ("precision", "recall", "ap50")},
        "within_5m": {k: v for k, v in _metrics(scored, data, threshold, 0.0, 5.0).items() if k not in ("min_m", "max_m")},
        "within_8m": {k: v for k, v in _metrics(scored, data, threshold, 0.0, 8.0).items() if k not in ("min_m", "max_m")},
        "by_distance": [_metrics(scored, data, threshold, lo, hi) for lo, hi in DISTANCE_BINS_M],
    }


def choose_threshold(predictions: Sequence[tuple[np.ndarray, np.ndarray]], data: dict) -> float:
    """The score threshold in [0.1, 0.9] (steps of 0.025) that maximises overall F1."""
    scored = _scored(predictions, data)
    best, best_f1 = 0.3, -1.0
    for thr in np.arange(0.1, 0.9001, 0.025):
        m = _metrics(scored, data, float(thr), 0.0, np.inf)
        p, r = np.nan_to_num(m["precision"]), np.nan_to_num(m["recall"])
        f1 = 2 * p * r / (p + r) if p + r > 0 else 0.0
        if f1 > best_f1 + 1e-9:
            best, best_f1 = float(round(thr, 3)), f1
    return best


def _stack_frames(frames: Sequence[LabelledFrame]) -> dict:
    """A loaded-split-like dict of rendered frames (labels only; images stay in the frames)."""
    rows = [(i, j) for i, f in enumerate(frames) for j in range(len(f.box_xyxy))]
    return {
        "depth_m": [f.depth_m for f in frames],
        "K": [f.K for f in frames],
        "box_frame": np.array([i for i, _ in rows], np.int64),
        "box_xyxy": np.array([frames[i].box_xyxy[j] for i, j in rows], np.float64).reshape(-1, 4),
        "box_ignore": np.array([frames[i].ignore[j] for i, j in rows], bool),
        "box_distance_m": np.array([frames[i].distance_m[j] for i, j in rows], np.float64),
        "box_pos_world": np.array([frames[i].pos_world[j] for i, j in rows], np.float64).reshape(-1, 3),
    }


def _backprojection_table(frames: Sequence[LabelledFrame], detections: list[list[Detection]], data: dict, threshold: float) -> dict:
    """Median 3-D error of back-projected true positives per distance bin."""
    errors, ranges, skipped = [], [], 0
    for f, (fr, dets) in enumerate(zip(frames, detections)):
        dets = [d for d in dets if d.score >= threshold]
        if not dets:
            continue
        rows = np.nonzero(data["box_frame"] == f)[0]
        status, matched = match_frame(np.array([d.box_xyxy for d in dets]), np.array([d.score for d in dets]), data["box_xyxy"][rows], data["box_ignore"][rows])
        rgbd = RgbdFrame(drone_id=0, time_s=0.0, rgb=fr.rgb, depth_m=fr.depth_m, K=fr.K, transform_camera_to_world=fr.transform_camera_to_world)
        result = backproject(rgbd, dets)
        skipped += int(sum(status[i] == TP for i in result.skipped))
        for m, i in zip(result.measurements, result.detection_index):
            if status[i] == TP:
                row = rows[matched[i]]
                errors.append(float(np.linalg.norm(m.pos_world - data["box_pos_world"][row])))
                ranges.append(float(data["box_distance_m"][row]))
    errors, ranges = np.asarray(errors), np.asarray(ranges)
    table = []
    for lo, hi in DISTANCE_BINS_M:
        sel = (ranges >= lo) & (ranges < hi)
        n = int(sel.sum())
        goal = 0.05 + 0.01 * ranges[sel]
        table.append(
            {
                "min_m": lo,
                "max_m": hi,
                "n": n,
                "median_error_m": float(np.median(errors[sel])) if n else float("nan"),
                "p90_error_m": float(np.percentile(errors[sel], 90)) if n else float("nan"),
                "median_goal_m": float(np.median(goal)) if n else float("nan"),
                "share_within_goal": float(np.mean(errors[sel] <= goal)) if n else float("nan"),
            }
        )
    return {"goal": "median error <= 0.05 m + 0.01 * range", "true_positives_without_depth": skipped, "by_distance": table}


def json_safe(obj):  # noqa: ANN001 - any JSON-like value
    """NaN / inf floats -> None (strict JSON), recursively."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def _fmt(x, width: int, digits: int = 3) -> str:
    """A number right-aligned, '-' for missing / NaN."""
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return f"{'-':>{width}}"
    return f"{x:>{width}.{digits}f}"


def format_table(results: dict, backprojection: dict | None = None) -> str:
    """Human-readable tables of ``results`` (and of a back-projection table when given)."""
    o = results["overall"]
    lines = [
        f"detector: precision {_fmt(o['precision'], 0)}  recall {_fmt(o['recall'], 0)}  AP@0.5 {_fmt(o['ap50'], 0)}  "
        f"latency {_fmt(results['latency_ms_per_frame'], 0, 2)} ms/frame (batch of 6, 320x240)",
        f"{'range [m]':>10} {'n':>6} {'precision':>10} {'recall':>8} {'AP@0.5':>8}",
    ]
    for b in results["by_distance"]:
        lines.append(f"{b['min_m']:>4.0f}-{b['max_m']:<5.0f} {b['n']:>6d} {_fmt(b['precision'], 10)} {_fmt(b['recall'], 8)} {_fmt(b['ap50'], 8)}")
    if backprojection is not None:
        lines.append("back-projection (true positives, render -> detect -> back-project), goal median <= 5 cm + 1 % range:")
        lines.append(f"{'range [m]':>10} {'n':>6} {'median [m]':>11} {'p90 [m]':>8} {'goal [m]':>9} {'<= goal':>8}")
        for b in backprojection["by_distance"]:
            lines.append(
                f"{b['min_m']:>4.0f}-{b['max_m']:<5.0f} {b['n']:>6d} {_fmt(b['median_error_m'], 11)} {_fmt(b['p90_error_m'], 8)} "
                f"{_fmt(b['median_goal_m'], 9)} {_fmt(b['share_within_goal'], 8, 2)}"
            )
    return "\n".join(lines)


def run_eval_detector(
    out_dir: Path,
    weights: Path | None = None,
    n_frames: int = 800,
    seeds: Sequence[int] | None = None,
    progress: bool = True,
    workers: int = 2,
    renderer: str | None = None,
    precision: str = "auto",
) -> dict:
    """Render held-out frames, detect, score, back-project; write the results (see the module docstring).

    Args:
        out_dir: output folder (written all-or-nothing, :func:`mpcde.flight.run_folder.staged_output`).
        weights: checkpoint path; default the shipped ``data/detector/drone_detector.pt``.
        n_frames: frames to evaluate.
        seeds: scene seeds (must lie in the test split's range); default the
            first ``ceil(n_frames / frames_per_scene)`` test seeds.
        progress: show progress bars.
        workers: render processes (1: in-process).
        renderer: ``camera.renderer`` of the held-out renders (None: the camera's default;
            ``"tiny"``: the renderer the shipped detector was trained on).
        precision: the detector's arithmetic ("auto", "float32", "bfloat16"; as a flight's
            ``perception.detector_precision``).

    Returns:
        The results dict written to ``results.json``.
    """
    from tqdm import tqdm

    from perception.detector.detector import DroneDetector

    if not (isinstance(n_frames, int) and n_frames >= 1):
        raise ConfigError("n_frames", n_frames, "an integer >= 1")
    cfg = DatasetConfig()
    lo = SPLIT_SEED_BASE["test"]
    if seeds is None:
        seeds = split_seeds("test", -(-n_frames // cfg.frames_per_scene))
    bad = [s for s in seeds if not lo <= int(s) < lo + SPLIT_SIZE]
    if bad:
        raise ConfigError("seeds", bad[0], f"held-out test scene seeds in [{lo}, {lo + SPLIT_SIZE})")
    detector = DroneDetector.load(weights, precision=precision)

    frames: list[LabelledFrame] = []
    bar = tqdm(total=n_frames, disable=not progress, desc="render test")
    camera = CameraConfig() if renderer is None else CameraConfig(renderer=renderer)
    for scene in iter_scenes(list(seeds), cfg, camera, workers):
        take = scene[: n_frames - len(frames)]
        frames += take
        bar.update(len(take))
        if len(frames) >= n_frames:
            break
    bar.close()

    detections: list[list[Detection]] = []
    raw_predictions = []
    batch_ms = []
    for s in range(0, len(frames), 6):
        batch = [
            RgbdFrame(drone_id=i, time_s=0.0, rgb=f.rgb, depth_m=f.depth_m, K=f.K, transform_camera_to_world=f.transform_camera_to_world)
            for i, f in enumerate(frames[s : s + 6])
        ]
        t0 = time.perf_counter()
        dets = detector.detect(batch, score_threshold=AP_MIN_SCORE)
        if len(batch) == 6:
            batch_ms.append((time.perf_counter() - t0) * 1e3)
        detections += dets
        raw_predictions += [(np.array([d.box_xyxy for d in ds]).reshape(-1, 4), np.array([d.score for d in ds])) for ds in dets]
    data = _stack_frames(frames)
    metrics = evaluate_detections(raw_predictions, data, detector.score_threshold)
    results = {
        "overall": metrics["overall"],
        "by_distance": metrics["by_distance"],
        "latency_ms_per_frame": float(np.median(batch_ms) / 6.0) if batch_ms else float("nan"),
    }
    extra = {
        "within_5m": metrics["within_5m"],
        "within_8m": metrics["within_8m"],
        "score_threshold": detector.score_threshold,
        "n_frames": len(frames),
        "scene_seeds": [int(seeds[0]), int(seeds[-1])],
        "weights": str(weights) if weights is not None else "data/detector/drone_detector.pt",
        "precision": detector.precision,
    }
    bp = _backprojection_table(frames, detections, data, detector.score_threshold)
    w5, w8 = extra["within_5m"], extra["within_8m"]
    text = format_table(results, bp) + (
        f"\nwithin 5 m: precision {_fmt(w5['precision'], 0)} recall {_fmt(w5['recall'], 0)} AP@0.5 {_fmt(w5['ap50'], 0)} (n {w5['n']})"
        f"\nwithin 8 m: precision {_fmt(w8['precision'], 0)} recall {_fmt(w8['recall'], 0)} AP@0.5 {_fmt(w8['ap50'], 0)} (n {w8['n']})"
        f"\nframes {extra['n_frames']}, test scene seeds {extra['scene_seeds']}, score threshold {extra['score_threshold']}, "
        f"weights {extra['weights']}, precision {extra['precision']}\n"
    )
    with staged_output(Path(out_dir)) as stage:  # all-or-nothing: moved into out_dir when complete
        (stage / "results.json").write_text(json.dumps(json_safe(results), indent=2))
        (stage / "backprojection.json").write_text(json.dumps(json_safe(bp), indent=2))
        (stage / "results.txt").write_text(text)
    return results
