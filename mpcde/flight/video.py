"""H.264 MP4 of a run: the top view beside each drone's camera image.

The top view is drawn with OpenCV from ground truth (obstacles, drones, goals,
trails); camera tiles are the onboard RGB frames as delivered. Encoded by
imageio-ffmpeg with libx264 / yuv420p so browsers play it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import cv2
import imageio.v2 as imageio
import numpy as np

from mpcde.flight.plots import box_corners_xy
from sim.ground_truth import TrueState
from sim.types import ObstacleSpec, RgbdFrame

__all__ = ["FrameComposer", "VideoWriter"]

PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]


class FrameComposer:
    """Draws the video's frame: the top view (obstacles, goals, trails, headings) beside each drone's newest camera image.

    Args:
        obstacles: the scene's obstacles.
        goals: (N, 3) goals [m].
        arena_size_m: (x, y) arena size [m] (the top view's scale).
        cam_size_px: (width, height) of the camera images [px].
        top_px: the top view's side [px].
    """

    def __init__(self, obstacles: Sequence[ObstacleSpec], goals: np.ndarray, arena_size_m: tuple[float, float], cam_size_px: tuple[int, int], top_px: int = 480) -> None:
        self.goals = goals
        self.n = goals.shape[0]
        self.top_px = top_px
        self.scale = top_px / max(arena_size_m)
        self.trails: list[list[tuple[int, int]]] = [[] for _ in range(self.n)]
        cols = 3 if self.n > 4 else 2
        rows = int(np.ceil(self.n / cols))
        w, h = cam_size_px
        tile_h = top_px // max(rows, 2)
        self.tile = (int(round(w * tile_h / h)), tile_h)
        self.cols, self.rows = cols, rows
        self.background = self._draw_static(obstacles)

    def _px(self, xy: np.ndarray) -> tuple[int, int]:
        return int(self.top_px / 2 + xy[0] * self.scale), int(self.top_px / 2 - xy[1] * self.scale)

    def _draw_static(self, obstacles: Sequence[ObstacleSpec]) -> np.ndarray:
        img = np.full((self.top_px, self.top_px, 3), 235, np.uint8)
        for ob in obstacles:
            if ob.kind == "tree":
                cv2.circle(img, self._px(np.asarray(ob.center_xy)), max(1, int(ob.radius_m * self.scale)), (140, 90, 60), -1, cv2.LINE_AA)
            else:
                pts = np.array([self._px(c) for c in box_corners_xy(ob)], np.int32)
                cv2.fillPoly(img, [pts], (120, 120, 130), cv2.LINE_AA)
        for i, g in enumerate(self.goals):
            c = PALETTE[i % 10]
            x, y = self._px(g)
            cv2.drawMarker(img, (x, y), c, cv2.MARKER_CROSS, 10, 2)
        return img

    def compose(self, time_s: float, truth: TrueState, frames: list[RgbdFrame | None]) -> np.ndarray:
        """The frame (H, W, 3) uint8 RGB for time ``time_s`` [s], H and W multiples of 16 (each call extends the trails)."""
        top = self.background.copy()
        for i in range(self.n):
            c = PALETTE[i % 10]
            p = self._px(truth.pos_world[i])
            self.trails[i].append(p)
            if len(self.trails[i]) > 1:
                cv2.polylines(top, [np.array(self.trails[i], np.int32)], False, c, 1, cv2.LINE_AA)
            heading = truth.rotation_body_to_world[i, :2, 0]
            tip = self._px(truth.pos_world[i, :2] + 0.6 * heading)
            cv2.line(top, p, tip, c, 2, cv2.LINE_AA)
            cv2.circle(top, p, 4, (0, 0, 0) if truth.failed[i] else c, -1, cv2.LINE_AA)
        cv2.putText(top, f"t = {time_s:5.2f} s", (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
        tw, th = self.tile
        grid = np.zeros((self.top_px, self.cols * tw, 3), np.uint8)
        for i in range(self.n):
            r, col = divmod(i, self.cols)
            if r * th + th > self.top_px:
                break
            f = frames[i]
            if f is not None:
                tile = cv2.resize(f.rgb, (tw, th), interpolation=cv2.INTER_AREA)
            else:
                tile = np.zeros((th, tw, 3), np.uint8)
            cv2.putText(tile, f"drone {i}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, PALETTE[i % 10], 1, cv2.LINE_AA)
            grid[r * th : r * th + th, col * tw : col * tw + tw] = tile
        frame = np.concatenate([top, grid], axis=1)
        h, w = frame.shape[:2]
        return np.pad(frame, ((0, (-h) % 16), (0, (-w) % 16), (0, 0)))


class VideoWriter:
    """Writes frames as the loop delivers camera images (``frame_sink`` of the loop), drawn by :class:`FrameComposer`."""

    def __init__(self, path: Path, obstacles: Sequence[ObstacleSpec], goals: np.ndarray, arena_size_m: tuple[float, float], fps: float, cam_size_px: tuple[int, int], top_px: int = 480) -> None:
        self.path = Path(path)
        self.composer = FrameComposer(obstacles, goals, arena_size_m, cam_size_px, top_px)
        self.writer = imageio.get_writer(str(self.path), fps=fps, codec="libx264", pixelformat="yuv420p", macro_block_size=16, quality=6, ffmpeg_log_level="error")
        self.frames = 0

    def __call__(self, time_s: float, truth: TrueState, frames: list[RgbdFrame | None]) -> None:
        """Append one video frame for time ``time_s`` [s]."""
        self.writer.append_data(self.composer.compose(time_s, truth, frames))
        self.frames += 1

    def close(self) -> None:
        """Finish the file."""
        self.writer.close()
