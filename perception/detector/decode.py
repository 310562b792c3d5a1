"""From the detector's head outputs to boxes: peak extraction and non-maximum suppression.

Peaks: a cell is a peak when its heatmap score equals the 3x3 max-pool of the
heatmap (CenterNet's peak finder) and exceeds the score threshold; at most
``max_detections`` peaks per frame are kept, best first. Each peak becomes a
box from its size and offset heads (conventions in
:mod:`perception.detector.model`). Two peaks of the same drone can survive the
3x3 pool when the drone is large, so greedy IoU NMS (:func:`nms_xyxy`) runs
after the boxes are formed. The converse limit (CenterNet's "centre point
collision"): two drones whose image centres fall within about one cell
(4-8 px) of each other leave one peak, so the smaller, usually farther one is
not reported in that frame.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from numba import njit

from perception.detector.model import STRIDE

__all__ = ["box_iou_xyxy", "decode_outputs", "decode_outputs_reference", "nms_xyxy"]


def box_iou_xyxy(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pairwise IoU (n, m) of boxes ``a`` (n, 4) and ``b`` (m, 4), ``[x0, y0, x1, y1]`` [px]."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    iw = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0.0, None)
    ih = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0.0, None)
    inter = iw * ih
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def nms_xyxy(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy non-maximum suppression.

    Repeatedly keeps the best remaining box and drops every remaining box whose
    IoU with it exceeds ``iou_threshold``.

    Args:
        boxes: (n, 4) ``[x0, y0, x1, y1]`` [px].
        scores: (n,) scores.
        iou_threshold: boxes overlapping a kept one by more than this are dropped.

    Returns:
        (k,) int64 indices of the kept boxes, by decreasing score (ties: lower index first).
    """
    scores = np.asarray(scores, np.float64).reshape(-1)
    order = np.argsort(-scores, kind="stable")
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)[order]
    iou = box_iou_xyxy(boxes, boxes)
    alive = np.ones(order.size, bool)
    keep = []
    for i in range(order.size):
        if not alive[i]:
            continue
        keep.append(order[i])
        alive[i + 1 :] &= iou[i, i + 1 :] <= iou_threshold
    return np.asarray(keep, np.int64)


def decode_outputs(
    outputs: torch.Tensor,
    score_threshold: float,
    max_detections: int = 20,
    nms_iou: float = 0.5,
    image_shape_px: tuple[int, int] | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Boxes and scores per frame from raw head outputs (B, 5, h, w), in one compiled pass.

    The same rules as :func:`decode_outputs_reference` (torch and numpy, the
    tests' oracle): a peak is a cell whose heatmap logit is >= its 3 x 3
    neighbours' (the sigmoid is monotone, so this is the max-pool rule on
    scores), kept when its score is >= ``score_threshold``; the best
    ``max_detections`` by score, boxes from the size and offset heads, greedy
    NMS (timings: docs/results/realtime.md#the-detector-in-the-render-workers). Arguments and result as the reference's.
    """
    out = np.ascontiguousarray(outputs.detach().float().numpy())
    H, W = image_shape_px if image_shape_px is not None else (-1, -1)
    boxes, scores, counts = _decode_kernel(out, np.float32(score_threshold), int(max_detections), float(nms_iou), float(W), float(H), STRIDE)
    return [(boxes[b, : counts[b]].copy(), scores[b, : counts[b]].copy()) for b in range(out.shape[0])]


@njit(cache=True)
def _decode_kernel(out, threshold, max_det, nms_iou, W, H, stride):  # pragma: no cover - compiled
    """(B, k, 4) boxes, (B, k) scores and (B,) counts of :func:`decode_outputs` (W, H < 0: no clipping)."""
    B, _, h, w = out.shape
    k_max = min(max_det, h * w)
    boxes = np.zeros((B, k_max, 4))
    scores = np.zeros((B, k_max))
    counts = np.zeros(B, np.int64)
    one = np.float32(1.0)
    cand_s = np.empty(h * w)
    cand_i = np.empty(h * w, np.int64)
    for b in range(B):
        n = 0
        for i in range(h):
            for j in range(w):
                x = out[b, 0, i, j]
                peak = True
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        ii, jj = i + di, j + dj
                        if 0 <= ii < h and 0 <= jj < w and out[b, 0, ii, jj] > x:
                            peak = False
                if not peak:
                    continue
                score = one / (one + np.exp(-x))  # float32, as torch.sigmoid
                if score >= threshold and score > 0.0:
                    cand_s[n] = score
                    cand_i[n] = i * w + j
                    n += 1
        order = np.argsort(-cand_s[:n], kind="mergesort")[:k_max]  # best first, ties: lower cell first
        m = order.shape[0]
        bx = np.empty((m, 4))
        sc = np.empty(m)
        for r in range(m):
            idx = cand_i[order[r]]
            i, j = idx // w, idx % w
            cu = stride * (j + np.float64(out[b, 3, i, j])) - 0.5  # centre [px]: c = 4 (j + offset) - 0.5
            cv = stride * (i + np.float64(out[b, 4, i, j])) - 0.5
            bw = stride * np.exp(np.float64(out[b, 1, i, j]))
            bh = stride * np.exp(np.float64(out[b, 2, i, j]))
            x0, y0, x1, y1 = cu - bw / 2, cv - bh / 2, cu + bw / 2, cv + bh / 2
            if W >= 0:
                x0, x1 = min(max(x0, -0.5), W - 0.5), min(max(x1, -0.5), W - 0.5)
                y0, y1 = min(max(y0, -0.5), H - 0.5), min(max(y1, -0.5), H - 0.5)
            bx[r, 0], bx[r, 1], bx[r, 2], bx[r, 3] = x0, y0, x1, y1
            sc[r] = cand_s[order[r]]
        # greedy NMS in score order (the candidates are already sorted)
        alive = np.ones(m, np.bool_)
        kept = 0
        for r in range(m):
            if not alive[r]:
                continue
            boxes[b, kept] = bx[r]
            scores[b, kept] = sc[r]
            kept += 1
            area_r = (bx[r, 2] - bx[r, 0]) * (bx[r, 3] - bx[r, 1])
            for q in range(r + 1, m):
                if not alive[q]:
                    continue
                iw = max(min(bx[r, 2], bx[q, 2]) - max(bx[r, 0], bx[q, 0]), 0.0)
                ih = max(min(bx[r, 3], bx[q, 3]) - max(bx[r, 1], bx[q, 1]), 0.0)
                inter = iw * ih
                union = area_r + (bx[q, 2] - bx[q, 0]) * (bx[q, 3] - bx[q, 1]) - inter
                iou = inter / union if union > 0 else 0.0
                if iou > nms_iou:
                    alive[q] = False
        counts[b] = kept
    return boxes, scores, counts


def decode_outputs_reference(
    outputs: torch.Tensor,
    score_threshold: float,
    max_detections: int = 20,
    nms_iou: float = 0.5,
    image_shape_px: tuple[int, int] | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Boxes and scores per frame from raw head outputs (B, 5, h, w) with torch and numpy (the oracle of :func:`decode_outputs`).

    Args:
        outputs: (B, 5, h, w) raw outputs of :class:`~perception.detector.model.DetectorNet`.
        score_threshold: keep peaks with score >= this, in [0, 1].
        max_detections: most peaks per frame before NMS.
        nms_iou: NMS IoU threshold.
        image_shape_px: (H, W) to clip boxes to ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``; None: no clipping.

    Returns:
        per frame: boxes (k, 4) float64 ``[x0, y0, x1, y1]`` [px] and scores (k,), best first.
    """
    heat = torch.sigmoid(outputs[:, 0])
    peaks = heat == F.max_pool2d(heat[:, None], 3, stride=1, padding=1)[:, 0]
    heat = torch.where(peaks & (heat >= score_threshold), heat, torch.zeros_like(heat))
    B, h, w = heat.shape
    k = min(max_detections, h * w)
    top_scores, top_idx = torch.topk(heat.reshape(B, -1), k, dim=1)
    top_scores, top_idx = top_scores.numpy(), top_idx.numpy()
    regress = outputs[:, 1:].reshape(B, 4, -1).numpy()
    result = []
    for b in range(B):
        n = int(np.count_nonzero(top_scores[b] > 0.0))
        if n == 0:
            result.append((np.zeros((0, 4)), np.zeros(0)))
            continue
        idx, score = top_idx[b, :n], top_scores[b, :n].astype(np.float64)
        i, j = idx // w, idx % w
        r = regress[b][:, idx].astype(np.float64)  # (4, n): log w/4, log h/4, offset u, offset v
        cu = STRIDE * (j + r[2]) - 0.5  # centre [px]: c = 4 (j + offset) - 0.5
        cv = STRIDE * (i + r[3]) - 0.5
        bw, bh = STRIDE * np.exp(r[0]), STRIDE * np.exp(r[1])
        boxes = np.stack([cu - bw / 2, cv - bh / 2, cu + bw / 2, cv + bh / 2], axis=1)
        if image_shape_px is not None:
            H, W = image_shape_px
            boxes[:, 0::2] = np.clip(boxes[:, 0::2], -0.5, W - 0.5)
            boxes[:, 1::2] = np.clip(boxes[:, 1::2], -0.5, H - 0.5)
        keep = nms_xyxy(boxes, score, nms_iou)
        result.append((boxes[keep], score[keep]))
    return result
