"""Detector latency per 320 x 240 frame: batched over 6 frames (one per drone) vs one frame at a time.

Run: ``OMP_NUM_THREADS=2 .venv/bin/python benchmarks/bench_detector.py [--threads N] [--repeats R]``.
Frames are the committed fixture renders (cycled to 6). Timed: the whole
``DroneDetector.detect`` call (encoding, network, peak extraction, NMS), after
warm-up; the median of ``repeats`` is printed with the ratio against the
one-frame-at-a-time baseline measured in the same run, at ``--threads`` and
at one thread (the flight's setting), in float32 and, where the CPU computes
it natively, bfloat16 (``perception.detector_precision``). The network
forward alone is also printed.

Stems: the shipped network's compiled forward pass (as the flight runs it:
one thread, ``detector_precision: auto``, batches of 3 and 6) against the same
widths with the other stem (``ModelConfig.stem``, "conv" or "patch"), random
weights: the cost of a convolution does not depend on its weights.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from perception.detector import DroneDetector
from perception.detector.detector import native_bfloat16
from perception.detector.model import DetectorNet, ModelConfig, encode_frames
from sim.types import RgbdFrame
from timing import median_ms

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "detector" / "fixture" / "test" / "shard_00000.npz"


def _frames(n: int) -> list[RgbdFrame]:
    with np.load(FIXTURE) as z:
        rgb, depth, K, T = z["rgb"], z["depth_m"].astype(np.float32), z["K"], z["transform_camera_to_world"]
    return [RgbdFrame(drone_id=i, time_s=0.0, rgb=rgb[i % len(rgb)], depth_m=depth[i % len(rgb)], K=K[0], transform_camera_to_world=T[0]) for i in range(n)]


def _median_ms(fn, repeats: int) -> float:
    """:func:`timing.median_ms` after 5 warm-up calls (torch's allocator and thread pool settle)."""
    return median_ms(fn, repeats, warmup=5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=torch.get_num_threads())
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args()
    frames = _frames(6)
    print(f"detector, 320x240, median of {args.repeats}; native bfloat16 on this CPU: {native_bfloat16()}")
    for threads in sorted({args.threads, 1}, reverse=True):
        torch.set_num_threads(threads)
        detector = DroneDetector.load(precision="float32")
        batched_ms = _median_ms(lambda: detector.detect(frames), args.repeats) / 6.0
        single_ms = _median_ms(lambda: [detector.detect([f]) for f in frames], args.repeats) / 6.0
        x = encode_frames(np.stack([f.rgb for f in frames]), np.stack([f.depth_m for f in frames]), detector.in_channels)
        x = x.contiguous(memory_format=torch.channels_last)
        with torch.inference_mode():
            forward_ms = _median_ms(lambda: detector.net(x), args.repeats) / 6.0
        n_params = sum(p.numel() for p in detector.net.parameters())
        print(f"{threads} thread(s), float32 ({n_params} parameters):")
        print(f"  batched over 6 frames : {batched_ms:7.2f} ms per frame  (network forward alone {forward_ms:.2f} ms per frame)")
        print(f"  one frame at a time   : {single_ms:7.2f} ms per frame  (baseline)")
        print(f"  speed-up of batching  : {single_ms / batched_ms:7.2f}x")
        if native_bfloat16():
            b16 = DroneDetector.load(precision="bfloat16")
            b16_ms = _median_ms(lambda: b16.detect(frames), args.repeats) / 6.0
            with torch.inference_mode():
                xb = x.to(torch.bfloat16)
                b16_fwd = _median_ms(lambda: b16.net(xb), args.repeats) / 6.0
            print(f"  bfloat16, batched     : {b16_ms:7.2f} ms per frame  (forward {b16_fwd:.2f}; x{batched_ms / b16_ms:.2f} vs float32 batched)")
        else:
            print("  bfloat16: skipped (no avx512_bf16 / amx_bf16 on this CPU; precision 'auto' keeps float32)")
    _stems(frames, args.repeats)
    print("goal <= 1.5 ms per frame in flight (the flight runs one thread per process)")


def _stems(frames: list[RgbdFrame], repeats: int) -> None:
    """Compiled forward pass per frame, shipped stem against the other one (module docstring)."""
    torch.set_num_threads(1)
    shipped = DroneDetector.load(precision="auto")
    cfg = shipped.net.cfg
    other_stem = "conv" if cfg.stem == "patch" else "patch"
    other = DroneDetector(DetectorNet(ModelConfig(cfg.in_channels, cfg.c1, cfg.c2, cfg.c3, cfg.c4, stem=other_stem)).eval(),
                          0.5, precision="auto")
    print(f"stems, 1 thread, {shipped.precision}, compiled forward pass per frame (widths {cfg.c1}/{cfg.c2}/{cfg.c3}/{cfg.c4}):")
    for batch in (3, 6):
        x = encode_frames(np.stack([f.rgb for f in frames[:batch]]), np.stack([f.depth_m for f in frames[:batch]]), cfg.in_channels)
        x = x.contiguous(memory_format=torch.channels_last).to(shipped.net.head.weight.dtype)
        times = {}
        for name, det in ((cfg.stem, shipped), (other_stem, other)):
            det.compile_graph = True
            with torch.inference_mode():
                times[name] = _median_ms(lambda: det._forward(x), repeats) / batch
        print(f"  batch of {batch}: {cfg.stem} (shipped) {times[cfg.stem]:.3f} ms, {other_stem} {times[other_stem]:.3f} ms"
              f" (x{times['conv'] / times['patch']:.2f} patch vs conv)")


if __name__ == "__main__":
    main()
