"""Plots of a run: top-down trajectories with obstacles, the observed area, minimum distance, yaw."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Polygon  # noqa: E402

from sim.obstacles import ObstacleSpec  # noqa: E402

__all__ = ["box_corners_xy", "draw_obstacles", "min_inter_drone_distance", "plot_min_distance", "plot_observed_area", "plot_top_down", "plot_yaw"]


def box_corners_xy(ob: ObstacleSpec) -> np.ndarray:
    """(4, 2) footprint corners [m] of a box obstacle."""
    hx, hy = ob.half_extents_xy
    c, s = np.cos(ob.yaw), np.sin(ob.yaw)
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(ob.center_xy)


def draw_obstacles(ax, obstacles: Sequence[ObstacleSpec]) -> None:
    """Obstacle footprints on the top-view axes ``ax``: trees as discs, boxes as rotated rectangles."""
    for ob in obstacles:
        if ob.kind == "tree":
            ax.add_patch(Circle(ob.center_xy, ob.radius_m, color="saddlebrown", alpha=0.7))
        else:
            ax.add_patch(Polygon(box_corners_xy(ob), closed=True, color="slategray", alpha=0.7))


def min_inter_drone_distance(pos_world: np.ndarray) -> np.ndarray:
    """(T,) minimum centre distance [m] over drone pairs at each sample of ``pos_world`` (T, N, 3), N >= 2."""
    pos = np.asarray(pos_world, float)
    d = np.linalg.norm(pos[:, :, None, :] - pos[:, None, :, :], axis=-1)  # (T, N, N)
    n = pos.shape[1]
    d[:, np.arange(n), np.arange(n)] = np.inf
    return d.min(axis=(1, 2))


def plot_top_down(path: Path, obstacles: Sequence[ObstacleSpec], pos_world: np.ndarray, starts: np.ndarray, goals: np.ndarray, arena_size_m: tuple[float, float], title: str) -> None:
    """Top view: obstacles, each drone's true path (T, N, 3), starts (o) and goals (x)."""
    fig, ax = plt.subplots(figsize=(7, 7))
    draw_obstacles(ax, obstacles)
    colours = plt.cm.tab10(np.arange(pos_world.shape[1]) % 10)
    for i in range(pos_world.shape[1]):
        ax.plot(pos_world[:, i, 0], pos_world[:, i, 1], color=colours[i], lw=1.5, label=f"drone {i}")
        ax.plot(*starts[i, :2], "o", color=colours[i])
        ax.plot(*goals[i, :2], "x", color=colours[i], ms=9, mew=2)
    ax.set_xlim(-arena_size_m[0] / 2, arena_size_m[0] / 2)
    ax.set_ylim(-arena_size_m[1] / 2, arena_size_m[1] / 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_observed_area(
    path: Path, seen: np.ndarray, extent: tuple[float, float, float, float], obstacles: Sequence[ObstacleSpec],
    pos_world: np.ndarray, areas_m2: Sequence[float], swarm_m2: float, arena_size_m: tuple[float, float], title: str,
) -> None:
    """Top view of what the cameras saw (MP-CDE Fig. 5): each drone's seen cells ``seen`` (N, nx, ny) shaded in its colour.

    ``extent`` (x0, x1, y0, y1) [m] of the raster; ``areas_m2`` and ``swarm_m2`` the S_obs figures for the legend.
    """
    fig, ax = plt.subplots(figsize=(7, 7))
    colours = plt.cm.tab10(np.arange(seen.shape[0]) % 10)
    for i in range(seen.shape[0]):
        rgba = np.zeros((*seen.shape[2:0:-1], 4))  # (ny, nx, 4): imshow's rows are y
        rgba[..., :3] = colours[i, :3]
        rgba[..., 3] = 0.25 * seen[i].T
        ax.imshow(rgba, origin="lower", extent=extent, interpolation="nearest")
        ax.plot(pos_world[:, i, 0], pos_world[:, i, 1], color=colours[i], lw=1.2, label=f"drone {i}: S_obs {areas_m2[i]:.1f} m^2")
    draw_obstacles(ax, obstacles)
    ax.set_xlim(-arena_size_m[0] / 2, arena_size_m[0] / 2)
    ax.set_ylim(-arena_size_m[1] / 2, arena_size_m[1] / 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{title}: observed area, swarm {swarm_m2:.1f} m^2")
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_min_distance(path: Path, time_s: np.ndarray, pos_world: np.ndarray, collision_distance_m: float) -> None:
    """Minimum inter-drone centre distance over time, with the collision threshold."""
    fig, ax = plt.subplots(figsize=(7, 3.2))
    if pos_world.shape[1] > 1:
        ax.plot(time_s, min_inter_drone_distance(pos_world), label="min inter-drone distance")
    ax.axhline(collision_distance_m, color="r", ls="--", label=f"collision ({collision_distance_m:.2f} m)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance [m]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_yaw(path: Path, time_s: np.ndarray, yaw: np.ndarray) -> None:
    """Each drone's heading (T, N) [rad] over time, in degrees."""
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for i in range(yaw.shape[1]):
        ax.plot(time_s, np.degrees(np.unwrap(yaw[:, i])), label=f"drone {i}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("yaw [deg]")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
