"""The learned drone detector (CenterNet-style, stride 4): network, decoding, the onboard wrapper."""

from perception.detector.decode import box_iou_xyxy, decode_outputs, nms_xyxy
from perception.detector.detector import CHECKPOINT_FORMAT, DEFAULT_WEIGHTS, DroneDetector
from perception.detector.model import DetectorNet, ModelConfig

__all__ = [
    "CHECKPOINT_FORMAT",
    "DEFAULT_WEIGHTS",
    "DetectorNet",
    "DroneDetector",
    "ModelConfig",
    "box_iou_xyxy",
    "decode_outputs",
    "nms_xyxy",
]
