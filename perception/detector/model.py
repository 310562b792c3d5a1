"""A small single-stage drone detector: CenterNet-style heads at stride 4.

Architecture (``DetectorNet``; B frames, input (B, C, H, W) with H, W
multiples of 16, C = 3 for RGB or 4 for RGB-D)::

    stem    3x3 s2 C->c1, 3x3 s2 c1->c2            (stride 4; stem = "conv")
         or 4x4 s4 C->c2, one patch per cell        (stride 4; stem = "patch", c1 unused)
    s4      3x3 c2->c2                              (stride 4)   = a
    s8      3x3 s2 c2->c3, 3x3 c3->c3               (stride 8)   = b
    s16     3x3 s2 c3->c4, 3x3 c4->c4               (stride 16)  = c
    top-down  b' = b + up2(1x1 c4->c3 (c)),  a' = a + up2(1x1 c3->c2 (b'))
    fuse    3x3 c2->c2 on a'
    heads   1x1 c2->5: [heatmap logit, log w, log h, offset u, offset v]

Every 3x3 conv is conv + BatchNorm + ReLU in training; :func:`fold_batchnorm`
folds each BatchNorm into its conv for inference. The stride-16 level gives
the receptive field (about 200 px) that near drones (boxes up to ~150 px)
need; the costly convolutions stay at stride 4 and 8. The "patch" stem
(a 4x4 stride-4 convolution, as in ConvNeXt's patchify stem) reads each input
pixel once and replaces two convolutions, the first of which works on only
four input channels at stride 2; its cost against the "conv" stem is in
``docs/results/detector.md#the-patch-stem-retrained-2026-11-26-issue-25``.

Outputs on the (H/4, W/4) grid, cell (i, j) covering input pixels
``[4j, 4j + 4) x [4i, 4i + 4)``:

* heatmap: logit of "a drone centre lies in this cell" (sigmoid -> score);
* size: ``log(w_px / 4), log(h_px / 4)`` of the box;
* offset: the centre's position inside its cell in [0, 1) (cell units), so a
  centre ``c`` [px] (pixel centres at integers, as in K) is
  ``c = 4 (j + offset) - 0.5``.

Input encoding (:func:`encode_frames`): RGB / 255 - 0.5, and for RGB-D a fourth
channel ``depth_m / 10`` with invalid (NaN) depth read as 10 m (beyond the
sensor's range, as the sky is).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from sim.checks import ConfigError

__all__ = ["STRIDE", "STEMS", "DEPTH_SCALE_M", "ModelConfig", "DetectorNet", "encode_frames", "fold_batchnorm"]

STRIDE = 4
"""Output stride of the heads [px per cell]."""
STEMS = ("conv", "patch")
"""The stem choices of :class:`ModelConfig`."""
DEPTH_SCALE_M = 10.0
"""Depth channel = depth_m / DEPTH_SCALE_M; invalid depth reads as DEPTH_SCALE_M [m]."""


@dataclass(frozen=True)
class ModelConfig:
    """Widths of the detector.

    Attributes:
        in_channels: 3 (RGB) or 4 (RGB-D).
        c1: stem width at stride 2.
        c2: width at stride 4 (heads).
        c3: width at stride 8.
        c4: width at stride 16.
        stem: "conv" (two 3x3 stride-2 convolutions through width c1) or
            "patch" (one 4x4 stride-4 convolution; c1 unused).
    """

    in_channels: int = 4
    c1: int = 8
    c2: int = 16
    c3: int = 32
    c4: int = 64
    stem: str = "conv"

    def __post_init__(self) -> None:
        if self.in_channels not in (3, 4):
            raise ConfigError("in_channels", self.in_channels, "3 (RGB) or 4 (RGB-D)")
        if self.stem not in STEMS:
            raise ConfigError("stem", self.stem, " or ".join(repr(s) for s in STEMS))
        for name in ("c1", "c2", "c3", "c4"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 4 <= v <= 256):
                raise ConfigError(name, v, "an integer in [4, 256]")

    def to_dict(self) -> dict:
        """Plain dict (for the checkpoint)."""
        return asdict(self)


def _cbr(c_in: int, c_out: int, stride: int = 1, kernel: int = 3) -> nn.Sequential:
    """kernel x kernel conv (no bias; "same" padding for 3x3, none for a patch kernel = stride) + BatchNorm + ReLU."""
    pad = 1 if kernel == 3 else 0
    return nn.Sequential(nn.Conv2d(c_in, c_out, kernel, stride, pad, bias=False), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True))


class DetectorNet(nn.Module):
    """The network; see the module docstring. ``forward`` maps (B, C, H, W) -> (B, 5, H/4, W/4)."""

    def __init__(self, cfg: ModelConfig = ModelConfig()) -> None:
        super().__init__()
        self.cfg = cfg
        if cfg.stem == "patch":
            self.stem = _cbr(cfg.in_channels, cfg.c2, STRIDE, kernel=STRIDE)
        else:
            self.stem = nn.Sequential(_cbr(cfg.in_channels, cfg.c1, 2), _cbr(cfg.c1, cfg.c2, 2))
        self.s4 = _cbr(cfg.c2, cfg.c2)
        self.s8 = nn.Sequential(_cbr(cfg.c2, cfg.c3, 2), _cbr(cfg.c3, cfg.c3))
        self.s16 = nn.Sequential(_cbr(cfg.c3, cfg.c4, 2), _cbr(cfg.c4, cfg.c4))
        self.lat16 = nn.Conv2d(cfg.c4, cfg.c3, 1)
        self.lat8 = nn.Conv2d(cfg.c3, cfg.c2, 1)
        self.fuse = _cbr(cfg.c2, cfg.c2)
        self.head = nn.Conv2d(cfg.c2, 5, 1)
        with torch.no_grad():  # CenterNet's prior: heatmap starts near 0.01 so the focal loss is stable
            self.head.bias.zero_()
            self.head.bias[0] = -4.6

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Raw head outputs (B, 5, H/4, W/4) of the encoded input (B, C, H, W)."""
        a = self.s4(self.stem(x))
        b = self.s8(a)
        c = self.s16(b)
        b = b + F.interpolate(self.lat16(c), scale_factor=2.0, mode="nearest")
        a = a + F.interpolate(self.lat8(b), scale_factor=2.0, mode="nearest")
        return self.head(self.fuse(a))


def fold_batchnorm(net: DetectorNet) -> DetectorNet:
    """In place: fold every eval-mode BatchNorm into the preceding conv (weights W' = W g / s, b' = beta - g mu / s)."""
    net.eval()
    for module in net.modules():
        if isinstance(module, nn.Sequential) and len(module) == 3 and isinstance(module[1], nn.BatchNorm2d):
            conv, bn = module[0], module[1]
            scale = bn.weight.detach() / torch.sqrt(bn.running_var + bn.eps)  # g / s
            fused = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride, conv.padding, bias=True)
            with torch.no_grad():
                fused.weight.copy_(conv.weight.detach() * scale[:, None, None, None])
                fused.bias.copy_(bn.bias.detach() - bn.running_mean * scale)
            module[0] = fused
            module[1] = nn.Identity()
    return net


def encode_frames(rgb: np.ndarray, depth_m: np.ndarray | None, in_channels: int) -> torch.Tensor:
    """Network input (B, C, H, W) float32 from rgb (B, H, W, 3) uint8 and depth (B, H, W) [m] (NaN invalid).

    ``depth_m`` may be None only for ``in_channels == 3``.
    """
    x = torch.from_numpy(np.ascontiguousarray(rgb)).permute(0, 3, 1, 2).float().mul_(1.0 / 255.0).sub_(0.5)
    if in_channels == 3:
        return x
    if depth_m is None:
        raise ValueError("depth_m=None: an RGB-D model needs depth (B, H, W)")
    d = torch.from_numpy(np.array(depth_m, np.float32))  # a copy: the in-place ops below never touch the caller's array
    d = d.nan_to_num_(nan=DEPTH_SCALE_M).clamp_(0.0, DEPTH_SCALE_M).mul_(1.0 / DEPTH_SCALE_M)
    return torch.cat([x, d[:, None]], dim=1)
