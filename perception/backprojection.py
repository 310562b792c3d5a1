"""Detections to 3-D neighbour measurements (MP-CDE Sec. IV-B, Eq. 7-8).

For a box with centre ``(u, v)`` [px] in a frame with intrinsics K and pose
estimate ``T_wc = transform_camera_to_world``::

    p_c = d K^-1 [u, v, 1]^T                       (MP-CDE Eq. 7)
    p_w = R_wc p_c + t_wc                           (MP-CDE Eq. 8; R_wc, t_wc
                                                     hold the paper's extrinsics
                                                     and body pose composed)

Which depth ``d`` (:func:`box_depth_m`). The paper takes the 3x3 spatial median
at the box centre. On a quadrotor that window often falls between the arms
onto the background (the box centre of a drone seen from above is the body,
but of one seen edge-on or half-occluded it can be sky or a tree behind), so
this module takes:

1. the valid depths in a central sub-window of the box (``window_fraction`` of
   the box's width and height, never smaller than the 3x3 neighbourhood of the
   centre pixel that MP-CDE uses, clipped to the image);
2. the foreground among them: the depths within ``band_m + 3 sigma(z)`` of the
   window's ``foreground_percentile``-th percentile ``z_p``, with sigma(z) the
   depth sensor's noise at ``z_p``; background behind the drone is farther than
   that band, and a sparse nearer outlier (stereo noise) is below it;
3. ``d`` = the median of that foreground (the paper's median filter, on the
   pixels that belong to the drone).

The depth camera sees the drone's near surface; the drone's position is its
body centre, on average ``surface_to_centre_m`` farther along the ray, which is
added along the unit ray (0.03 m, the median offset on validation renders;
measured: docs/results/tracker.md#back-projection-backprojectionpy).

Covariance (anisotropic, in world): along the ray the depth error dominates,
std_r^2 = (pi / 2) sigma(d)^2 |r|^2 / n + model_std_m^2 (variance of a median of
n samples with sensor noise sigma(d) = base + q d^2, plus the spread of the
surface-to-centre offset); across the ray the box centre's pixel error
dominates, std_t = range * std_px / f + across_floor_m with
std_px = centre_std_px + centre_std_box_fraction * box size. Then
``cov = R_wc (std_t^2 (I - e e^T) + std_r^2 e e^T) R_wc^T`` with ``e`` the unit
ray in the camera frame (:func:`ray_covariance`). Calibration: ``model_std_m``
= 0.01 m, ``centre_std_px`` = 0.15 px, ``centre_std_box_fraction`` = 0.02 and
``across_floor_m`` = 0 fit the errors of render -> detect -> back-project with a
perfect pose on the tracking tuning seeds (``mpcde eval-tracking``'s
pipeline source; the errors: docs/results/tracker.md#back-projection-backprojectionpy). The white noise of the drone's own pose estimate
is added (:func:`pose_noise_cov`): its position noise
``pose_pos_std_m`` moves every measurement with it, and its heading noise
``pose_yaw_std_rad`` swings the measurement about the vertical through the
camera, ``delta p = delta psi (e_z x o)`` for a point at offset ``o`` from it.
The pose estimate's slow drift is a bias shared by consecutive frames, not
frame noise, so it is left out (a filter cannot average it away, and adding it
to R would only make the tracker trust its measurements less).

A box whose window holds no valid depth (NaN: sky, too near, too far) gives no
measurement; its index is reported in :attr:`BackprojectionResult.skipped`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numba import njit

from perception.backprojection_config import BackprojectionConfig
from perception.tracker import Measurement
from perception.types import Detection
from sim.types import RgbdFrame

__all__ = [
    "BackprojectionConfig",
    "BackprojectionResult",
    "backproject",
    "box_depth_m",
    "measurement_from_pixel",
    "pose_noise_cov",
    "ray_covariance",
]


@dataclass(frozen=True)
class BackprojectionResult:
    """Measurements of one frame's detections.

    Attributes:
        measurements: one :class:`Measurement` per detection with valid depth.
        detection_index: (k,) index into the detections of each measurement.
        skipped: (s,) indices of detections without valid depth (no measurement).
    """

    measurements: tuple[Measurement, ...]
    detection_index: np.ndarray
    skipped: np.ndarray


def _depth_std_m(z: float, cfg: BackprojectionConfig) -> float:
    return cfg.depth_noise_base_m + cfg.depth_noise_quadratic_per_m * z * z


def box_depth_m(depth_m: np.ndarray, box_xyxy: np.ndarray, cfg: BackprojectionConfig = BackprojectionConfig()) -> tuple[float, int]:
    """Depth [m] of the drone in a box and how many pixels support it (see the module docstring).

    Args:
        depth_m: (H, W) depth [m], NaN invalid.
        box_xyxy: (4,) box [px] (pixel centres at integers).

    Returns:
        (d, n): the foreground median depth [m] (NaN when the window holds no
        valid pixel) and the number of foreground pixels.
    """
    window = _box_window(depth_m, box_xyxy, cfg)
    if window is None:
        return float("nan"), 0
    d, n = _foreground_depth(
        window, float(cfg.foreground_percentile) / 100.0, cfg.band_m, cfg.depth_noise_base_m, cfg.depth_noise_quadratic_per_m
    )
    return float(d), int(n)


def box_depth_numpy(depth_m: np.ndarray, box_xyxy: np.ndarray, cfg: BackprojectionConfig = BackprojectionConfig()) -> tuple[float, int]:
    """Vectorised numpy reference of :func:`box_depth_m` (the tests compare them to the bit)."""
    window = _box_window(depth_m, box_xyxy, cfg)
    if window is None:
        return float("nan"), 0
    z = window.ravel()
    z = z[np.isfinite(z)].astype(np.float64)
    if z.size == 0:
        return float("nan"), 0
    z_p = float(np.percentile(z, cfg.foreground_percentile, method="lower"))  # a sample: the band is never empty
    band = cfg.band_m + 3.0 * _depth_std_m(z_p, cfg)
    fg = z[np.abs(z - z_p) <= band]
    return float(np.median(fg)), int(fg.size)


def _box_window(depth_m: np.ndarray, box_xyxy: np.ndarray, cfg: BackprojectionConfig) -> np.ndarray | None:
    """The central ``window_fraction`` sub-window (h, w) of the box in ``depth_m``, clipped to the image (None: empty)."""
    H, W = depth_m.shape
    x0, y0, x1, y1 = (float(c) for c in box_xyxy)
    cu, cv = int(round((x0 + x1) / 2)), int(round((y0 + y1) / 2))
    half_u = max(int(round(cfg.window_fraction * (x1 - x0) / 2)), 1)  # >= 1: never less than MP-CDE's 3x3
    half_v = max(int(round(cfg.window_fraction * (y1 - y0) / 2)), 1)
    u_lo, u_hi = max(cu - half_u, 0), min(cu + half_u + 1, W)
    v_lo, v_hi = max(cv - half_v, 0), min(cv + half_v + 1, H)
    if u_lo >= u_hi or v_lo >= v_hi:
        return None
    return depth_m[v_lo:v_hi, u_lo:u_hi]


@njit(cache=True)
def _foreground_depth(window, q, band_m, noise_base_m, noise_quad_per_m):  # pragma: no cover - compiled
    """(median of the foreground band, its pixel count) of a depth window (h, w) [m] (module docstring; NaN, 0 when
    no pixel is valid): ``z_p`` the ``q``-quantile of the valid depths (numpy's ``method="lower"``, a sample), the band
    ``|z - z_p| <= band_m + 3 sigma(z_p)`` (``sigma = noise_base + noise_quad z^2``), its median as ``np.median``."""
    h, w = window.shape
    z = np.empty(h * w)
    n = 0
    for i in range(h):
        for j in range(w):
            x = window[i, j]
            if np.isfinite(x):
                z[n] = np.float64(x)
                n += 1
    if n == 0:
        return np.nan, 0
    z = np.sort(z[:n])
    z_p = z[int(np.floor((n - 1) * q))]
    band = band_m + 3.0 * (noise_base_m + noise_quad_per_m * z_p * z_p)
    lo = 0
    while lo < n and abs(z[lo] - z_p) > band:  # z is sorted: the band is one run of it, z_p inside (band >= 0)
        lo += 1
    hi = n
    while hi > lo and abs(z[hi - 1] - z_p) > band:
        hi -= 1
    m = hi - lo
    if m % 2 == 1:
        return z[lo + m // 2], m
    return (z[lo + m // 2 - 1] + z[lo + m // 2]) / 2.0, m


def measurement_from_pixel(
    u_px: float,
    v_px: float,
    depth_m: float,
    n_pixels: int,
    box_side_px: float,
    K: np.ndarray,
    transform_camera_to_world: np.ndarray,
    time_s: float,
    cfg: BackprojectionConfig = BackprojectionConfig(),
) -> Measurement:
    """World position and anisotropic covariance of the drone seen at pixel (u, v) with depth ``depth_m``.

    Args:
        u_px, v_px: box centre [px].
        depth_m: foreground depth along the optical axis [m].
        n_pixels: pixels supporting the depth (>= 1).
        box_side_px: mean box side [px] (centre uncertainty grows with it).
        K: (3, 3) intrinsics.
        transform_camera_to_world: (4, 4) camera pose (the drone's estimate).
        time_s: capture time [s].
    """
    K = np.asarray(K, float)
    T = np.asarray(transform_camera_to_world, float)
    ray_c = np.linalg.solve(K, np.array([u_px, v_px, 1.0]))  # K^-1 [u, v, 1]^T, unit optical z
    ray_norm = float(np.linalg.norm(ray_c))
    e_c = ray_c / ray_norm
    p_c = depth_m * ray_c  # MP-CDE Eq. 7: p_c = d K^-1 [u, v, 1]^T
    p_c = p_c + cfg.surface_to_centre_m * e_c  # near surface -> drone centre
    p_w = T[:3, :3] @ p_c + T[:3, 3]  # MP-CDE Eq. 8: p_w = R_wc p_c + t_wc
    range_m = float(np.linalg.norm(p_c))
    sigma_z = _depth_std_m(depth_m, cfg)
    var_r = (np.pi / 2.0) * sigma_z**2 * ray_norm**2 / max(n_pixels, 1) + cfg.model_std_m**2
    f = 0.5 * (K[0, 0] + K[1, 1])
    std_t = range_m * (cfg.centre_std_px + cfg.centre_std_box_fraction * box_side_px) / f + cfg.across_floor_m
    R = T[:3, :3]
    cov_w = ray_covariance(R @ e_c, np.sqrt(var_r), std_t)
    cov_w += pose_noise_cov(p_w - T[:3, 3], cfg.pose_pos_std_m, cfg.pose_yaw_std_rad)
    return Measurement(pos_world=p_w, cov_world=cov_w, time_s=float(time_s))


def ray_covariance(ray_unit: np.ndarray, std_along_m: float, std_across_m: float) -> np.ndarray:
    """Covariance (3, 3) [m^2] with std ``std_along_m`` along the unit ``ray_unit`` (3,) and ``std_across_m`` across it.

    ``cov = std_across^2 (I - e e^T) + std_along^2 e e^T``, in the frame ``ray_unit`` is given in.
    """
    e = np.asarray(ray_unit, float)
    outer = np.outer(e, e)
    return std_across_m**2 * (np.eye(3) - outer) + std_along_m**2 * outer


def pose_noise_cov(offset_world: np.ndarray, pos_std_m: float, yaw_std_rad: float) -> np.ndarray:
    """Covariance (3, 3) [m^2] the pose estimate's white noise adds to a point at ``offset_world`` (3,) [m] from the camera.

    Position noise moves the point with the drone (``pos_std_m^2 I``); a heading
    error ``delta psi`` rotates it about the vertical through the camera,
    ``delta p = delta psi (e_z x o)`` (first order), so
    ``cov = pos_std^2 I + yaw_std^2 (e_z x o)(e_z x o)^T``.
    """
    o = np.asarray(offset_world, float)
    swing = np.array([-o[1], o[0], 0.0])  # e_z x o
    return pos_std_m**2 * np.eye(3) + yaw_std_rad**2 * np.outer(swing, swing)


def backproject(frame: RgbdFrame, detections: Sequence[Detection], cfg: BackprojectionConfig = BackprojectionConfig()) -> BackprojectionResult:
    """Measurements (MP-CDE Eq. 7-8) of ``detections`` in ``frame`` (its depth, K and pose estimate)."""
    measurements, index, skipped = [], [], []
    for i, det in enumerate(detections):
        box = np.asarray(det.box_xyxy, float)
        d, n = box_depth_m(frame.depth_m, box, cfg)
        if not np.isfinite(d):
            skipped.append(i)
            continue
        side = 0.5 * ((box[2] - box[0]) + (box[3] - box[1]))
        u, v = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        measurements.append(measurement_from_pixel(u, v, d, n, side, frame.K, frame.transform_camera_to_world, frame.time_s, cfg))
        index.append(i)
    return BackprojectionResult(tuple(measurements), np.asarray(index, np.int64), np.asarray(skipped, np.int64))
