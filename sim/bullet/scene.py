"""What a PyBullet client needs to rebuild the same world: obstacles, drones, look.

The physics client and every render client build their bodies from one
:class:`SceneSpec`, so a scene is rebuilt identically per seed and per process.
The ground is a collision plane in the physics client only; renderers draw it
analytically (see :mod:`sim.rendering.tiny`), which is exact and much cheaper than
rasterising a ground mesh in TinyRenderer.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.bullet import pb
from sim.types import ObstacleSpec

__all__ = ["DRONE_URDF", "RenderStyle", "SceneSpec", "build_obstacles", "load_drones"]

DRONE_URDF = Path(__file__).resolve().parents[2] / "data" / "quadrotor.urdf"


@dataclass(frozen=True)
class RenderStyle:
    """Lighting and colours of a render (randomised for detector training).

    Attributes:
        light_direction: (3,) direction *towards* the light in world.
        ambient: ambient coefficient of PyBullet's TinyRenderer shading.
        diffuse: diffuse coefficient.
        specular: specular coefficient.
        ground_rgb: (3,) ground colour in [0, 1]; a 1 m checker darkens alternate tiles.
        ground_checker_contrast: relative darkening of alternate tiles in [0, 1).
        sky_rgb: (3,) colour where no surface is hit.
    """

    light_direction: tuple[float, float, float] = (0.4, 0.3, 1.0)
    ambient: float = 0.6
    diffuse: float = 0.35
    specular: float = 0.05
    ground_rgb: tuple[float, float, float] = (0.42, 0.5, 0.36)
    ground_checker_contrast: float = 0.12
    sky_rgb: tuple[float, float, float] = (0.68, 0.8, 0.92)


@dataclass(frozen=True)
class SceneSpec:
    """Everything static about a world.

    Attributes:
        obstacles: the static obstacles.
        n_drones: number of quadrotors.
        drone_urdf: path of the quadrotor model.
        style: render lighting and colours.
    """

    obstacles: tuple[ObstacleSpec, ...]
    n_drones: int
    drone_urdf: str = str(DRONE_URDF)
    style: RenderStyle = field(default_factory=RenderStyle)


def build_obstacles(client: int, obstacles: tuple[ObstacleSpec, ...], with_collision: bool) -> list[int]:
    """Create the obstacles as static bodies in ``client``; returns their body ids."""
    ids = []
    for ob in obstacles:
        z = ob.height_m / 2.0
        if ob.kind == "tree":
            vis = pb.createVisualShape(pb.GEOM_CYLINDER, radius=ob.radius_m, length=ob.height_m, rgbaColor=ob.rgba, physicsClientId=client)
            col = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=ob.radius_m, height=ob.height_m, physicsClientId=client) if with_collision else -1
        else:
            he = [ob.half_extents_xy[0], ob.half_extents_xy[1], ob.height_m / 2.0]
            vis = pb.createVisualShape(pb.GEOM_BOX, halfExtents=he, rgbaColor=ob.rgba, physicsClientId=client)
            col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=he, physicsClientId=client) if with_collision else -1
        quat = pb.getQuaternionFromEuler([0.0, 0.0, ob.yaw])
        ids.append(
            pb.createMultiBody(0.0, col, vis, basePosition=[ob.center_xy[0], ob.center_xy[1], z], baseOrientation=quat, physicsClientId=client)
        )
    return ids


def load_drones(client: int, spec: SceneSpec, pos_world: np.ndarray, quat_xyzw: np.ndarray, fixed: bool) -> list[int]:
    """Load ``spec.n_drones`` quadrotors at (N, 3) positions and (N, 4) attitudes."""
    ids = []
    for i in range(spec.n_drones):
        ids.append(
            pb.loadURDF(
                spec.drone_urdf,
                basePosition=pos_world[i].tolist(),
                baseOrientation=quat_xyzw[i].tolist(),
                useFixedBase=fixed,
                flags=pb.URDF_USE_INERTIA_FROM_FILE,
                physicsClientId=client,
            )
        )
    return ids
