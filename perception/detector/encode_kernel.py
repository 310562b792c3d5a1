"""The detector's input encoding in one compiled pass per frame, written straight into channels-last layout.

Same encoding as :func:`perception.detector.model.encode_frames` (the tests'
oracle): RGB / 255 - 0.5, and for RGB-D a fourth channel
``clip(depth_m, 0, DEPTH_SCALE_M) / DEPTH_SCALE_M`` with invalid (NaN) depth
read as ``DEPTH_SCALE_M``. The torch form stacks the frames, permutes,
converts and concatenates (five passes over 7.4 MB for six 320 x 240 frames);
this reads each frame once and writes the (B, H, W, C) buffer that a
channels-last (B, C, H, W) tensor views (timings: docs/results/realtime.md#the-detector-in-the-render-workers).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from numba import njit

from perception.detector.model import DEPTH_SCALE_M

__all__ = ["encode_channels_last"]


@njit(cache=True)
def _encode_into(rgb, depth, out, with_depth, depth_scale):
    """Fill out (H, W, C) float32 from rgb (H, W, 3) uint8 and depth (H, W) [m] (NaN invalid)."""
    H, W = rgb.shape[0], rgb.shape[1]
    inv255 = np.float32(1.0 / 255.0)
    half = np.float32(0.5)
    inv_scale = np.float32(1.0 / depth_scale)
    for i in range(H):
        for j in range(W):
            out[i, j, 0] = np.float32(rgb[i, j, 0]) * inv255 - half
            out[i, j, 1] = np.float32(rgb[i, j, 1]) * inv255 - half
            out[i, j, 2] = np.float32(rgb[i, j, 2]) * inv255 - half
            if with_depth:
                d = np.float32(depth[i, j])
                if d != d or d > depth_scale:  # NaN (invalid) or beyond the scale: the far value
                    d = np.float32(depth_scale)
                elif d < 0.0:
                    d = np.float32(0.0)
                out[i, j, 3] = d * inv_scale


def encode_channels_last(rgbs: Sequence[np.ndarray], depths: Sequence[np.ndarray] | None, in_channels: int) -> torch.Tensor:
    """Network input (B, C, H, W) float32 in channels-last memory from B frames.

    Args:
        rgbs: B images (H, W, 3) uint8.
        depths: B depth images (H, W) [m], NaN invalid; None only for ``in_channels == 3``.
        in_channels: 3 (RGB) or 4 (RGB-D).
    """
    if in_channels == 4 and depths is None:
        raise ValueError("depth_m=None: an RGB-D model needs depth (B, H, W)")
    H, W = rgbs[0].shape[:2]
    out = np.empty((len(rgbs), H, W, in_channels), np.float32)
    empty = np.zeros((1, 1), np.float32)
    for b, rgb in enumerate(rgbs):
        depth = np.asarray(depths[b], np.float32) if in_channels == 4 else empty
        _encode_into(np.ascontiguousarray(rgb, np.uint8), depth, out[b], in_channels == 4, DEPTH_SCALE_M)
    return torch.from_numpy(out).permute(0, 3, 1, 2)
