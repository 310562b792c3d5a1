"""Each drone's onboard detector, run for all drones of one camera tick in one batch.

Every drone runs the same shipped detector (:class:`perception.detector.detector.DroneDetector`)
on its OWN frame; nothing crosses between drones. The loop hands the frames of
one camera tick to :meth:`BatchedDetector.detect` so that the network runs one
forward pass over the batch (DESIGN.md: "Inference is batched across drones";
measured: docs/results/detector.md#batched-across-drones-against-one-frame-at-a-time), then gives each agent its own frame's
detections with its frame. Only agents that ask for detections (a
``detector_request`` that is not None) are served; with none, no detector is
loaded.

Where it runs: with render workers, each worker runs the detector over its
share of a tick's frames right after rendering them (:func:`frame_detector`,
the render pool's frame processor; the main process then only reads the
boxes), which moves the network off the main process's core (measured in
``docs/results/realtime.md#where-the-time-goes``). With none
(``run.render_workers: 0``) the main process runs :meth:`BatchedDetector.detect`. A frame's detections do not
depend on where they ran beyond float rounding of the batch size.

Threads: in flight the detector shares the machine with the render workers,
so :meth:`BatchedDetector.single_threaded` runs torch on one intra-op thread
for the flight. With torch's default (one thread per core) its OpenMP team
spin-waits on the cores the renderers need (measured in
``docs/results/realtime.md#thread-oversubscription``).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Sequence

from mpcde.config.perception import DetectorRequest
from mpcde.errors import ConfigError
from perception.types import Detection
from sim.types import RgbdFrame

__all__ = ["BatchedDetector", "DetectorRequest", "frame_detector"]


class BatchedDetector:
    """The drones' detector (one network, batched over the drones that use it).

    Args:
        request: weights and threshold.

    Raises:
        ConfigError: ``<request.field>=<path>: <why>`` for a missing or corrupt checkpoint.
    """

    def __init__(self, request: DetectorRequest) -> None:
        from perception.detector.detector import DroneDetector

        try:
            self.detector = DroneDetector.load(request.weights, precision=request.precision)
        except ValueError as exc:
            raise ConfigError(request.field, request.weights, str(exc).split(": ", 1)[-1]) from None
        self.score_threshold = request.score_threshold
        self.request = request

    @classmethod
    def for_agents(cls, agents: Sequence[object]) -> "BatchedDetector | None":
        """The detector the agents ask for (their ``detector_request``), or None if none asks.

        Agents of one run share one scenario, hence one request; the first is used.
        """
        requests = [a.detector_request for a in agents if getattr(a, "detector_request", None) is not None]
        if not requests:
            return None
        return cls(requests[0])

    @contextmanager
    def single_threaded(self) -> Iterator[None]:
        """Run torch on one intra-op thread inside the ``with`` block (module docstring), then restore."""
        import torch

        before = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            yield
        finally:
            torch.set_num_threads(before)

    def detect(self, frames: Sequence[RgbdFrame], wanted: Sequence[bool]) -> list[list[Detection] | None]:
        """Detections of each frame whose ``wanted`` flag is set (None for the others), one forward pass."""
        idx = [i for i, w in enumerate(wanted) if w]
        out: list[list[Detection] | None] = [None] * len(frames)
        if idx:
            for i, dets in zip(idx, self.detector.detect([frames[i] for i in idx], self.score_threshold)):
                out[i] = dets
        return out


def frame_detector(request: DetectorRequest):  # noqa: ANN201 - sim.rendering.pool.FrameProcessor
    """A render worker's detector: loads ``request``'s checkpoint once, torch on one thread.

    Returns:
        ``run(rgbs, depths) -> [list[Detection], ...]``, one list per frame
        (:data:`sim.rendering.pool.FrameProcessor`), at the request's threshold.
    """
    import torch

    torch.set_num_threads(1)  # one worker per core: an OpenMP team would spin on the other worker's core
    detector = BatchedDetector(request).detector
    threshold = detector.score_threshold if request.score_threshold is None else float(request.score_threshold)

    def run(rgbs, depths):  # noqa: ANN001, ANN202
        return detector.detect_images(rgbs, depths, threshold)

    return run
