"""The onboard drone detector: RGB-D frames in, boxes with scores out, batched across drones.

:class:`DroneDetector` wraps :class:`~perception.detector.model.DetectorNet`
with its BatchNorms folded, in channels-last layout under
``torch.inference_mode``, in float32 or bfloat16 (``precision``; "auto" takes
bfloat16 where the CPU computes it natively, see :func:`native_bfloat16`),
traced and frozen by ``torch.jit`` once per input
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

import os
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from perception.detector.allocator import keep_large_allocations
from perception.detector.decode import decode_outputs
from perception.detector.encode_kernel import encode_channels_last
from perception.detector.model import DetectorNet, ModelConfig, fold_batchnorm
from perception.types import Detection
from sim.types import RgbdFrame

__all__ = ["CHECKPOINT_FORMAT", "DEFAULT_WEIGHTS", "PRECISIONS", "DroneDetector", "native_bfloat16", "resolve_precision"]

CHECKPOINT_FORMAT = "mpcde-drone-detector-v1"
DEFAULT_WEIGHTS = Path(__file__).resolve().parents[2] / "data" / "detector" / "drone_detector.pt"
PRECISIONS = ("auto", "float32", "bfloat16")
"""Arithmetic of the network's forward pass; "auto" resolves by :func:`resolve_precision`."""
_BF16_CPU_FLAGS = ("avx512_bf16", "amx_bf16")
_ONEDNN_BF16_ISAS = ("AVX512_CORE_BF16", "AVX512_CORE_FP16", "AVX10_1_512", "AVX512_CORE_AMX", "AVX512_CORE_AMX_FP16", "AVX10_1_512_AMX", "AVX10_1_512_AMX_FP16", "AVX10_2_512", "AVX10_2_512_AMX_2", "ALL")
"""``ONEDNN_MAX_CPU_ISA`` values at or above oneDNN's first ISA with bfloat16 dot products; a lower cap emulates it."""


def native_bfloat16(cpuinfo: str | None = None, max_isa: str | None = None) -> bool:
    """Whether oneDNN computes bfloat16 natively here: the CPU has ``avx512_bf16`` or ``amx_bf16`` (Linux only)
    and oneDNN is not capped below them.

    oneDNN computes a bfloat16 convolution natively on such a CPU (what it saves
    the detector: docs/results/detector.md#bfloat16-against-float32); elsewhere it would emulate
    bfloat16 or refuse it, so "auto" keeps float32 there. The cap is
    ``ONEDNN_MAX_CPU_ISA``, which the portable numerics profile sets to AVX2
    (mpcde/numerics.py): "auto" then keeps float32 as on a CPU without bfloat16.

    Args:
        cpuinfo: text of ``/proc/cpuinfo`` (read when None; absent: False).
        max_isa: oneDNN's ISA cap (``ONEDNN_MAX_CPU_ISA`` when None; unset: no cap).
    """
    cap = (os.environ.get("ONEDNN_MAX_CPU_ISA") if max_isa is None else max_isa) or ""
    if cap and cap.strip().upper() not in _ONEDNN_BF16_ISAS:
        return False
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            return False
    flags = set()
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            flags.update(line.split(":", 1)[-1].split())
    return any(f in flags for f in _BF16_CPU_FLAGS) and torch.backends.mkldnn.is_available()


def resolve_precision(precision: str) -> str:
    """"float32" or "bfloat16" for one of :data:`PRECISIONS` ("auto": bfloat16 iff :func:`native_bfloat16`)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision={precision!r}: one of {', '.join(PRECISIONS)}")
    if precision == "auto":
        return "bfloat16" if native_bfloat16() else "float32"
    return precision


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
        precision: the forward pass's arithmetic, "float32" or "bfloat16" (resolved from the
            constructor's argument, one of :data:`PRECISIONS`). Encoding, decoding and the
            boxes stay float32 / float64; only the convolutions run in bfloat16.
    """

    def __init__(
        self,
        net: DetectorNet,
        score_threshold: float,
        max_detections: int = 20,
        nms_iou: float = 0.5,
        compile_graph: bool = False,
        precision: str = "float32",
    ) -> None:
        if not 0.0 <= score_threshold <= 1.0:
            raise ValueError(f"score_threshold={score_threshold!r}: in [0, 1]")
        if not (isinstance(max_detections, int) and max_detections >= 1):
            raise ValueError(f"max_detections={max_detections!r}: an integer >= 1")
        if not 0.0 < nms_iou <= 1.0:
            raise ValueError(f"nms_iou={nms_iou!r}: in (0, 1]")
        self.precision = resolve_precision(precision)
        self._dtype = torch.bfloat16 if self.precision == "bfloat16" else torch.float32
        self.net = fold_batchnorm(net).to(memory_format=torch.channels_last, dtype=self._dtype)
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
    def load(cls, path: str | Path | None = None, precision: str = "float32") -> "DroneDetector":
        """Load a checkpoint (default: the shipped ``data/detector/drone_detector.pt``) to run at ``precision``.

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
        return cls(net, threshold, precision=precision)

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
        return self.detect_images([f.rgb for f in frames], [f.depth_m for f in frames], thr)

    def detect_images(self, rgbs: Sequence[np.ndarray], depths: Sequence[np.ndarray], score_threshold: float) -> list[list[Detection]]:
        """:meth:`detect` on bare images: B rgb (H, W, 3) uint8 and B depth (H, W) [m] (NaN invalid), H, W multiples of 16.

        For callers that hold a drone's images without its frame (a render
        worker, :func:`mpcde.onboard.detection.frame_detector`); the arguments are
        not checked again.
        """
        if len(rgbs) == 0:
            return []
        shape = tuple(rgbs[0].shape[:2])
        with torch.inference_mode():
            x = encode_channels_last(rgbs, depths if self.in_channels == 4 else None, self.in_channels).to(self._dtype)
            out = self._forward(x).float()
            decoded = decode_outputs(out, score_threshold, self.max_detections, self.nms_iou, image_shape_px=shape)
        return [[Detection(box_xyxy=b, score=float(s)) for b, s in zip(boxes, scores)] for boxes, scores in decoded]
