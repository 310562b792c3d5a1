"""An analytic renderer of the scene's primitives: exact depth, Lambert-Phong colour, drone mask.

Every surface of the world is a primitive with a closed-form ray intersection:
the obstacles (vertical capped cylinders, boxes turned about z), each drone's
visuals (the boxes and capped cylinders of ``data/quadrotor.urdf``, at the
drone's pose), the ground plane z = 0 and the sky. For each camera, each
primitive's oriented bounding box, clipped at the near plane, is projected to
a pixel rectangle and only the pixels inside it are intersected with the
primitive (compiled with numba; its bounding sphere rejects it first when it
lies wholly behind the near plane or beyond the far one); the nearest hit wins.
Primitives go nearest first (by their centre's depth), and a pixel already
covered nearer than a primitive's bounding sphere skips its intersection, so
a tree behind a tree costs little. Depth is the exact ray parameter along the optical axis
(rays r_c = K^-1 [u, v, 1] have unit optical z), so cylinders are round, not
tessellated as in TinyRenderer.

Colour: ``rgb = c (ambient + diffuse max(n.l, 0)) + 255 specular max(r.v, 0)^s``
with the world-space normal n, the light direction l, the reflection r of l
about n and the direction v towards the camera (s = 16). TinyRenderer shades
in clip space with interpolated vertex normals, so the two renderers agree in
depth and masks (``tests/unit/sim/test_raycast_renderer.py``) but not pixel
for pixel in colour. It is the default (:class:`sim.camera.CameraConfig`
``renderer``), ``"tiny"`` remains selectable; how the shipped detector,
trained on TinyRenderer's images, scores on this renderer's
(``mpcde eval-detector --renderer``) and what it costs are in
``docs/results/realtime.md#the-analytic-renderer``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from numba import njit

from sim.bullet.scene import RenderStyle, SceneSpec
from sim.camera import CameraConfig, intrinsics
from sim.rendering.tiny import RawRender, ground_distance, ground_tile, style_lighting
from sim.rotations import rotation_from_quat_xyzw

__all__ = ["RaycastRenderer", "drone_primitives"]

BOX, CYLINDER = 0, 1
_SHININESS = 16.0


def _rpy_matrix(r: float, p: float, y: float) -> np.ndarray:
    """URDF rpy (fixed-axis roll, pitch, yaw) -> rotation (3, 3)."""
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])  # fmt: skip


def drone_primitives(urdf: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The visuals of a one-link URDF as primitives in the body frame.

    Returns ``(kind (P,), centre (P, 3), rotation (P, 3, 3), size (P, 3), rgb (P, 3))``:
    a box's size is its half extents, a cylinder's (radius, radius, half length)
    along its local z.
    """
    root = ET.parse(urdf).getroot()
    colours = {m.get("name"): [float(x) for x in m.find("color").get("rgba").split()][:3] for m in root.iter("material") if m.find("color") is not None}
    kinds, centres, rots, sizes, rgbs = [], [], [], [], []
    for vis in root.iter("visual"):
        origin = vis.find("origin")
        xyz = [float(x) for x in origin.get("xyz", "0 0 0").split()] if origin is not None else [0.0, 0.0, 0.0]
        rpy = [float(x) for x in origin.get("rpy", "0 0 0").split()] if origin is not None else [0.0, 0.0, 0.0]
        geom = vis.find("geometry")
        box, cyl = geom.find("box"), geom.find("cylinder")
        if box is not None:
            kinds.append(BOX)
            sizes.append([0.5 * float(x) for x in box.get("size").split()])
        elif cyl is not None:
            kinds.append(CYLINDER)
            r = float(cyl.get("radius"))
            sizes.append([r, r, 0.5 * float(cyl.get("length"))])
        else:  # pragma: no cover - the shipped URDF has boxes and cylinders only
            raise ValueError(f"{urdf}: visual geometry {[c.tag for c in geom]}: allowed box or cylinder")
        mat = vis.find("material")
        rgbs.append(colours.get(mat.get("name"), [0.7, 0.7, 0.7]) if mat is not None else [0.7, 0.7, 0.7])
        centres.append(xyz)
        rots.append(_rpy_matrix(*rpy))
    return np.array(kinds, np.int64), np.array(centres), np.array(rots), np.array(sizes), np.array(rgbs)


class RaycastRenderer:
    """Renders the forward cameras of a scene analytically (same interface as :class:`sim.rendering.tiny.SceneRenderer`)."""

    def __init__(self, spec: SceneSpec, camera: CameraConfig) -> None:
        self.spec = spec
        self.camera = camera
        self.K = intrinsics(camera)
        kinds, centres, rots, sizes, rgbs = [], [], [], [], []
        for ob in spec.obstacles:
            c, s = math.cos(ob.yaw), math.sin(ob.yaw)
            kinds.append(CYLINDER if ob.kind == "tree" else BOX)
            centres.append([ob.center_xy[0], ob.center_xy[1], 0.5 * ob.height_m])
            rots.append(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))
            h = 0.5 * ob.height_m
            sizes.append([ob.radius_m, ob.radius_m, h] if ob.kind == "tree" else [ob.half_extents_xy[0], ob.half_extents_xy[1], h])
            rgbs.append(list(ob.rgba[:3]))
        n_static = len(kinds)
        dk, self._body_c, self._body_R, ds, drgb = drone_primitives(Path(spec.drone_urdf))
        n = spec.n_drones
        self.kind = np.concatenate([np.array(kinds, np.int64), np.tile(dk, n)])
        self.size = np.concatenate([np.array(sizes, float).reshape(-1, 3), np.tile(ds, (n, 1))])
        self.rgb = np.concatenate([np.array(rgbs, float).reshape(-1, 3), np.tile(drgb, (n, 1))])
        self.owner = np.concatenate([np.full(n_static, -1, np.int64), np.repeat(np.arange(n), len(dk))])
        self.centre = np.concatenate([np.array(centres, float).reshape(-1, 3), np.zeros((n * len(dk), 3))])
        self.rot = np.concatenate([np.array(rots, float).reshape(-1, 3, 3), np.tile(np.eye(3), (n * len(dk), 1, 1))])
        self._n_static, self._n_per_drone = n_static, len(dk)
        self.radius = np.sqrt(np.sum(self.size**2, axis=1))  # bounding spheres
        self.set_drone_poses(np.tile([0.0, 0.0, -100.0], (n, 1)), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))

    def close(self) -> None:
        """Nothing to release (for the interface of :class:`sim.rendering.tiny.SceneRenderer`)."""

    def set_drone_poses(self, pos_world: np.ndarray, quat_xyzw: np.ndarray) -> None:
        """Place all drones: (N, 3) positions [m], (N, 4) quaternions."""
        R = rotation_from_quat_xyzw(np.asarray(quat_xyzw, float).reshape(-1, 4))
        p = np.asarray(pos_world, float).reshape(-1, 3)
        k, m = self._n_static, self._n_per_drone
        for i in range(self.spec.n_drones):
            self.centre[k + i * m : k + (i + 1) * m] = p[i] + self._body_c @ R[i].T
            self.rot[k + i * m : k + (i + 1) * m] = R[i] @ self._body_R

    def render(self, transform_camera_to_world: np.ndarray, own_drone: int | None, style: RenderStyle | None = None) -> RawRender:
        """Render one camera at its true pose, its own drone hidden (see :meth:`sim.rendering.tiny.SceneRenderer.render`)."""
        style = style or self.spec.style
        cam = self.camera
        T = np.asarray(transform_camera_to_world, float)
        light, light_tile, dark_tile, sky = style_lighting(style)
        rgb, depth, mask = _raycast(
            cam.height_px, cam.width_px, self.K, np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]),
            float(cam.render_near_m), float(cam.render_far_m), self.kind, self.centre, self.rot, self.size, self.radius,
            self.rgb, self.owner, -1 if own_drone is None else int(own_drone), light,
            float(style.ambient), float(style.diffuse), float(style.specular), light_tile, dark_tile, sky,
        )
        return RawRender(rgb=rgb, depth_true_m=depth, drone_index_mask=mask)


@njit(cache=True)
def _hit_box(o, d, h):  # pragma: no cover - compiled
    """Entry parameter and local normal of the ray o + t d against the box |x_k| <= h_k (t = inf: miss)."""
    t0, t1 = -np.inf, np.inf
    axis, sign = -1, 0.0
    for k in range(3):
        if abs(d[k]) < 1e-12:
            if abs(o[k]) > h[k]:
                return np.inf, axis, sign
            continue
        a = (-h[k] - o[k]) / d[k]
        b = (h[k] - o[k]) / d[k]
        s = -1.0
        if a > b:
            a, b = b, a
            s = 1.0
        if a > t0:
            t0, axis, sign = a, k, s
        t1 = min(t1, b)
    if t0 > t1 or t1 < 0.0 or axis < 0:
        return np.inf, axis, sign
    return t0, axis, sign


@njit(cache=True)
def _hit_cylinder(o, d, r, hl):  # pragma: no cover - compiled
    """Entry parameter and local normal (nx, ny, nz) of the ray against the capped cylinder x^2 + y^2 <= r^2, |z| <= hl."""
    best, nx, ny, nz = np.inf, 0.0, 0.0, 0.0
    a = d[0] * d[0] + d[1] * d[1]
    if a > 1e-18:
        b = o[0] * d[0] + o[1] * d[1]
        c = o[0] * o[0] + o[1] * o[1] - r * r
        disc = b * b - a * c
        if disc >= 0.0:
            t = (-b - math.sqrt(disc)) / a
            z = o[2] + t * d[2]
            if t > 0.0 and abs(z) <= hl:
                best, nx, ny, nz = t, (o[0] + t * d[0]) / r, (o[1] + t * d[1]) / r, 0.0
    if abs(d[2]) > 1e-12:
        for cap in (hl, -hl):
            t = (cap - o[2]) / d[2]
            if 0.0 < t < best:
                x, y = o[0] + t * d[0], o[1] + t * d[1]
                if x * x + y * y <= r * r and (cap > 0.0) == (d[2] < 0.0):
                    best, nx, ny, nz = t, 0.0, 0.0, 1.0 if cap > 0.0 else -1.0
    return best, nx, ny, nz


@njit(cache=True)
def _hit(kind, o, d, size):  # pragma: no cover - compiled
    """Entry parameter and local normal (t, nx, ny, nz) of the ray o + t d against a primitive (t = inf: miss)."""
    if kind == BOX:
        t, axis, sign = _hit_box(o, d, size)
        if axis == 0:
            return t, sign, 0.0, 0.0
        if axis == 1:
            return t, 0.0, sign, 0.0
        return t, 0.0, 0.0, sign
    return _hit_cylinder(o, d, size[0], size[2])


@njit(cache=True)
def _raycast(
    H, W, K, R_wc, t_wc, near, far, kind, centre, rot, size, radius, rgb_prim, owner, own, light,
    ambient, diffuse, specular, light_tile, dark_tile, sky,
):  # pragma: no cover - compiled
    """Render one camera: (rgb (H, W, 3) uint8, depth (H, W) float32 [m], drone mask (H, W) int16)."""
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    depth = np.full((H, W), np.inf)
    hit = np.full((H, W), -1, np.int32)
    o_l = np.empty(3)
    d_l = np.empty(3)
    cam_corner = np.empty((8, 3))
    # nearest first, so that a pixel already covered nearer than a primitive's bounding sphere skips its intersection
    n_prim = kind.shape[0]
    z_centre = np.empty(n_prim)
    for p in range(n_prim):
        rel = centre[p] - t_wc
        z_centre[p] = R_wc[0, 2] * rel[0] + R_wc[1, 2] * rel[1] + R_wc[2, 2] * rel[2]
    for p in np.argsort(z_centre, kind="mergesort"):
        if owner[p] == own and own >= 0:
            continue
        # bounding sphere first (cheap reject), then the projected corners of the oriented bounding box
        rel = centre[p] - t_wc
        zc = z_centre[p]
        rad = radius[p]
        if zc + rad < near or zc - rad > far:
            continue
        z_min = zc - rad  # no point of the primitive lies nearer along the optical axis
        Rp = rot[p]
        # the box corners in the camera frame; the box clipped at the near plane is projected:
        # corners in front, and where the edges cross the near plane
        for corner in range(8):
            sx = size[p, 0] if corner & 1 else -size[p, 0]
            sy = size[p, 1] if corner & 2 else -size[p, 1]
            sz = size[p, 2] if corner & 4 else -size[p, 2]
            w0 = rel[0] + Rp[0, 0] * sx + Rp[0, 1] * sy + Rp[0, 2] * sz
            w1 = rel[1] + Rp[1, 0] * sx + Rp[1, 1] * sy + Rp[1, 2] * sz
            w2 = rel[2] + Rp[2, 0] * sx + Rp[2, 1] * sy + Rp[2, 2] * sz
            cam_corner[corner, 0] = R_wc[0, 0] * w0 + R_wc[1, 0] * w1 + R_wc[2, 0] * w2
            cam_corner[corner, 1] = R_wc[0, 1] * w0 + R_wc[1, 1] * w1 + R_wc[2, 1] * w2
            cam_corner[corner, 2] = R_wc[0, 2] * w0 + R_wc[1, 2] * w1 + R_wc[2, 2] * w2
        umin, umax, vmin, vmax = np.inf, -np.inf, np.inf, -np.inf
        for corner in range(8):
            if cam_corner[corner, 2] > near:
                zq = cam_corner[corner, 2]
                uq, vq = cx + fx * cam_corner[corner, 0] / zq, cy + fy * cam_corner[corner, 1] / zq
                umin, umax, vmin, vmax = min(umin, uq), max(umax, uq), min(vmin, vq), max(vmax, vq)
            for bit in (1, 2, 4):  # the three edges from this corner to a higher-numbered one
                other = corner | bit
                if other == corner:
                    continue
                za, zb = cam_corner[corner, 2], cam_corner[other, 2]
                if (za > near) != (zb > near):
                    f = (near - za) / (zb - za)
                    xq = cam_corner[corner, 0] + f * (cam_corner[other, 0] - cam_corner[corner, 0])
                    yq = cam_corner[corner, 1] + f * (cam_corner[other, 1] - cam_corner[corner, 1])
                    uq, vq = cx + fx * xq / near, cy + fy * yq / near
                    umin, umax, vmin, vmax = min(umin, uq), max(umax, uq), min(vmin, vq), max(vmax, vq)
        if not umin <= umax:  # entirely behind the near plane
            continue
        u0 = max(int(math.floor(max(umin, -1.0))) - 1, 0)
        u1 = min(int(math.ceil(min(umax, W + 1.0))) + 1, W - 1)
        v0 = max(int(math.floor(max(vmin, -1.0))) - 1, 0)
        v1 = min(int(math.ceil(min(vmax, H + 1.0))) + 1, H - 1)
        if u0 > u1 or v0 > v1:
            continue
        # ray origin in the primitive's frame: R^T (t - c)
        for k in range(3):
            o_l[k] = Rp[0, k] * (t_wc[0] - centre[p, 0]) + Rp[1, k] * (t_wc[1] - centre[p, 1]) + Rp[2, k] * (t_wc[2] - centre[p, 2])
        for v in range(v0, v1 + 1):
            ry = (v - cy) / fy
            for u in range(u0, u1 + 1):
                if depth[v, u] < z_min:  # a nearer primitive already covers this pixel
                    continue
                rx = (u - cx) / fx
                # world direction R_wc [rx, ry, 1], then into the primitive's frame
                dw0 = R_wc[0, 0] * rx + R_wc[0, 1] * ry + R_wc[0, 2]
                dw1 = R_wc[1, 0] * rx + R_wc[1, 1] * ry + R_wc[1, 2]
                dw2 = R_wc[2, 0] * rx + R_wc[2, 1] * ry + R_wc[2, 2]
                for k in range(3):
                    d_l[k] = Rp[0, k] * dw0 + Rp[1, k] * dw1 + Rp[2, k] * dw2
                t, _, _, _ = _hit(kind[p], o_l, d_l, size[p])
                if t < near or t > far or t >= depth[v, u]:
                    continue
                depth[v, u] = t
                hit[v, u] = p
    rgb = np.empty((H, W, 3), np.uint8)
    out_depth = np.empty((H, W), np.float32)
    mask = np.full((H, W), -1, np.int16)
    for v in range(H):
        ry = (v - cy) / fy
        for u in range(W):
            rx = (u - cx) / fx
            dw0 = R_wc[0, 0] * rx + R_wc[0, 1] * ry + R_wc[0, 2]
            dw1 = R_wc[1, 0] * rx + R_wc[1, 1] * ry + R_wc[1, 2]
            dw2 = R_wc[2, 0] * rx + R_wc[2, 1] * ry + R_wc[2, 2]
            p = hit[v, u]
            lam = ground_distance(t_wc[2], dw2)
            if p >= 0 and depth[v, u] <= lam:
                # the winning primitive's normal, from its intersection once more
                Rp = rot[p]
                for k in range(3):
                    o_l[k] = Rp[0, k] * (t_wc[0] - centre[p, 0]) + Rp[1, k] * (t_wc[1] - centre[p, 1]) + Rp[2, k] * (t_wc[2] - centre[p, 2])
                    d_l[k] = Rp[0, k] * dw0 + Rp[1, k] * dw1 + Rp[2, k] * dw2
                _, nlx, nly, nlz = _hit(kind[p], o_l, d_l, size[p])
                n0 = Rp[0, 0] * nlx + Rp[0, 1] * nly + Rp[0, 2] * nlz
                n1 = Rp[1, 0] * nlx + Rp[1, 1] * nly + Rp[1, 2] * nlz
                n2 = Rp[2, 0] * nlx + Rp[2, 1] * nly + Rp[2, 2] * nlz
                ndl = n0 * light[0] + n1 * light[1] + n2 * light[2]
                # reflection of the light about n, against the direction to the camera
                r0, r1, r2 = 2.0 * ndl * n0 - light[0], 2.0 * ndl * n1 - light[1], 2.0 * ndl * n2 - light[2]
                dn = math.sqrt(dw0 * dw0 + dw1 * dw1 + dw2 * dw2)
                rdv = -(r0 * dw0 + r1 * dw1 + r2 * dw2) / dn
                spec = specular * max(rdv, 0.0) ** _SHININESS if ndl > 0.0 else 0.0
                lit = ambient + diffuse * max(ndl, 0.0)
                for c in range(3):
                    rgb[v, u, c] = min(max(int(255.0 * (rgb_prim[p, c] * lit + spec) + 0.5), 0), 255)
                out_depth[v, u] = depth[v, u]
                if owner[p] >= 0:
                    mask[v, u] = owner[p]
            else:
                tile = ground_tile(t_wc[0], t_wc[1], dw0, dw1, lam, far)
                colour = sky if tile == 2 else (dark_tile if tile == 1 else light_tile)
                rgb[v, u, 0], rgb[v, u, 1], rgb[v, u, 2] = colour[0], colour[1], colour[2]
                out_depth[v, u] = lam if tile != 2 else np.inf
    return rgb, out_depth, mask
