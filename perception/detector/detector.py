"""The onboard drone detector: RGB-D frames in, boxes with scores out, batched across drones.

:class:`DroneDetector` wraps :class:`~perception.detector.model.DetectorNet`
with its BatchNorms folded, in channels-last layout under
``torch.inference_mode``, traced and frozen by ``torch.jit`` once per input
shape (``optimize_for_inference`` fuses conv + ReLU; eager when
``compile_graph=False``); one forward pass serves every frame handed to
:meth:`DroneDetector.detect` (one per drone of a swarm tick). It reads only
:class:`sim.types.RgbdFrame` (image, depth, intrinsics, pose estimate): never a
segmentation. Constructing one keeps large tensor buffers in the process heap
(:mod:`perception.detector.allocator`).

Checkpoint (``torch.save`` of a dict): ``format`` = ``CHECKPOINT_FORMAT``,
``model_config`` (dict of :class:`ModelConfig`), ``state_dict`` (training
layout, with BatchNorms), ``score_threshold`` (chosen on the validation split).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from perception.detector.allocator import keep_large_allocations
from perception.detector.decode import decode_outputs
from perception.detector.model import DetectorNet, ModelConfig, encode_frames, fold_batchnorm
from perception.types import Detection
from sim.types import RgbdFrame

__all__ = ["CHECKPOINT_FORMAT", "DEFAULT_WEIGHTS", "DroneDetector"]

CHECKPOINT_FORMAT = "mpcde-drone-detector-v1"
DEFAULT_WEIGHTS = Path(__file__).resolve().parents[2] / "data" / "detector" / "drone_detector.pt"


def _bad_weights(path: Path, why: str) -> ValueError:
    return ValueError(f"detector weights={path}: {why}")


class DroneDetector:
    """A loaded detector (use :meth:`load`).

    Attributes:
        net: the BatchNorm-folded network in eval mode.
        score_threshold: default score threshold in [0, 1] (from the checkpoint).
        max_detections: most detections per frame.
        nms_iou: IoU threshold of non-maximum suppression.
        compile_graph: run a traced, frozen graph (per input shape) instead of eager PyTorch.
    """

    def __init__(
        self, net: DetectorNet, score_threshold: float, max_detections: int = 20, nms_iou: float = 0.5, compile_graph: bool = False
    ) -> None:
        if not 0.0 <= score_threshold <= 1.0:
            raise ValueError(f"score_threshold={score_threshold!r}: in [0, 1]")
        if not (isinstance(max_detections, int) and max_detections >= 1):
            raise ValueError(f"max_detections={max_detections!r}: an integer >= 1")
        if not 0.0 < nms_iou <= 1.0:
            raise ValueError(f"nms_iou={nms_iou!r}: in (0, 1]")
        self.net = fold_batchnorm(net).to(memory_format=torch.channels_last)
        self.score_threshold = float(score_threshold)
        self.max_detections = max_detections
        self.nms_iou = nms_iou
        self.compile_graph = compile_graph
        self._graphs: dict[tuple[int, ...], torch.jit.ScriptModule] = {}
        keep_large_allocations()  # page faults per call otherwise (perception/detector/allocator.py)

    def _forward(self, x: torch.Tensor) -> torch.Tensor:
        """Network outputs; with ``compile_graph`` a traced, frozen graph per input shape (conv + ReLU fused)."""
        if not self.compile_graph:
            return self.net(x)
        key = tuple(x.shape)
        graph = self._graphs.get(key)
        if graph is None:
            try:
                with warnings.catch_warnings():  # torch.jit is deprecated in favour of torch.compile, which needs a C++ toolchain
                    warnings.simplefilter("ignore")
                    graph = torch.jit.optimize_for_inference(torch.jit.freeze(torch.jit.trace(self.net, x)))
            except Exception:  # pragma: no cover - torch builds without the JIT: stay eager
                self.compile_graph = False
                return self.net(x)
            self._graphs[key] = graph
        return graph(x)

    @classmethod
    def load(cls, path: str | Path | None = None) -> "DroneDetector":
        """Load a checkpoint (default: the shipped ``data/detector/drone_detector.pt``).

        Raises:
            ValueError: one line ``detector weights=<path>: missing`` or
                ``detector weights=<path>: not a valid mpcde detector checkpoint (<why>)``.
        """
        path = Path(path) if path is not None else DEFAULT_WEIGHTS
        if not path.is_file():
            raise _bad_weights(path, "missing")
        try:
            ckpt = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # any unreadable file: pickle, zip or torch errors
            raise _bad_weights(path, f"not a valid mpcde detector checkpoint (unreadable: {type(exc).__name__})") from None
        if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
            raise _bad_weights(path, f"not a valid mpcde detector checkpoint (format is not {CHECKPOINT_FORMAT!r})")
        try:
            net = DetectorNet(ModelConfig(**ckpt["model_config"]))
            net.load_state_dict(ckpt["state_dict"])
            threshold = float(ckpt["score_threshold"])
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise _bad_weights(path, f"not a valid mpcde detector checkpoint ({why[:120]})") from None
        return cls(net, threshold)

    @property
    def in_channels(self) -> int:
        """3 (RGB) or 4 (RGB-D)."""
        return self.net.cfg.in_channels

    def detect(self, frames: Sequence[RgbdFrame], score_threshold: float | None = None) -> list[list[Detection]]:
        """Detections per frame, one batched forward pass over all ``frames``.

        Args:
            frames: the drones' frames, all of the same (H, W) with H, W multiples of 16.
            score_threshold: keep detections scoring >= this; default :attr:`score_threshold`.

        Returns:
            for each frame, its detections, best score first.
        """
        if len(frames) == 0:
            return []
        for f in frames:
            if not isinstance(f, RgbdFrame):
                raise TypeError(f"frames: RgbdFrame expected, got {type(f).__name__}")
        shape = frames[0].shape_px
        if any(f.shape_px != shape for f in frames) or shape[0] % 16 or shape[1] % 16:
            raise ValueError(f"frames shape={shape}: all frames of one (H, W), multiples of 16")
        thr = self.score_threshold if score_threshold is None else float(score_threshold)
        if not 0.0 <= thr <= 1.0:
            raise ValueError(f"score_threshold={thr!r}: in [0, 1]")
        rgb = np.stack([f.rgb for f in frames])
        depth = np.stack([f.depth_m for f in frames]) if self.in_channels == 4 else None
        with torch.inference_mode():
            x = encode_frames(rgb, depth, self.in_channels).contiguous(memory_format=torch.channels_last)
            out = self._forward(x)
            decoded = decode_outputs(out, thr, self.max_detections, self.nms_iou, image_shape_px=shape)
        return [[Detection(box_xyxy=b, score=float(s)) for b, s in zip(boxes, scores)] for boxes, scores in decoded]
