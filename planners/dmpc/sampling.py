"""Vectorised sampling of many Hermite-interpolated plans at the round's times.

Each DMPC round evaluates every neighbour's plan (a
:class:`perception.types.NeighborPrediction`) and the drone's own previous plan
(a :class:`planners.dmpc.types.DmpcPlan`) at the K S check times of the
horizon. Calling ``NeighborPrediction.position`` once per neighbour costs too
much of the round's Python time (measured: docs/results/dmpc_qp.md#smaller-figures-from-qppy-and-samplingpy); here all
plans with the same number of samples are evaluated in one set of numpy
operations.

The interpolant is the one both types define (and this module reproduces to
rounding error, see the tests): between samples the cubic Hermite interpolant
of (pos, vel); at and beyond the last sample constant velocity from it; at and
before the first, constant velocity from the first. With s = (t - t_i) / dt_i
on [t_i, t_i+1]:

    p(t) = h00(s) p_i + h10(s) dt_i v_i + h01(s) p_i+1 + h11(s) dt_i v_i+1,
    h00 = 2 s^3 - 3 s^2 + 1,  h10 = s^3 - 2 s^2 + s,  h01 = -2 s^3 + 3 s^2,  h11 = s^3 - s^2.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from perception.types import NeighborPrediction

__all__ = ["hermite_positions", "sample_predictions"]


def hermite_positions(
    times_s: np.ndarray, pos_world: np.ndarray, vel_world: np.ndarray, t_s: np.ndarray
) -> np.ndarray:
    """Positions of M plans with the same number of samples Kp at times ``t_s``.

    Args:
        times_s: (M, Kp) increasing sample times of each plan [s], Kp >= 1.
        pos_world: (M, Kp, 3) positions at those times [m].
        vel_world: (M, Kp, 3) velocities at those times [m/s].
        t_s: (T,) absolute query times [s].

    Returns:
        (M, T, 3) positions [m].
    """
    ts = np.asarray(times_s, float)
    p, v = np.asarray(pos_world, float), np.asarray(vel_world, float)
    t = np.asarray(t_s, float).ravel()
    M, Kp = ts.shape
    rows = np.arange(M)[:, None]
    dt_first = t[None, :] - ts[:, :1]  # (M, T)
    dt_last = t[None, :] - ts[:, -1:]
    out = p[:, :1] + v[:, :1] * dt_first[..., None]  # before the first sample: constant velocity
    hi = dt_last >= 0.0
    out = np.where(hi[..., None], p[:, -1:] + v[:, -1:] * dt_last[..., None], out)  # after the last
    if Kp < 2:
        return out
    mid = (dt_first > 0.0) & ~hi
    if not np.any(mid):
        return out
    # Segment index i with t_i < t <= t_i+1 (searchsorted(ts, t) - 1), clipped to a valid segment.
    i = np.clip(np.sum(ts[:, :, None] < t[None, None, :], axis=1) - 1, 0, Kp - 2)  # (M, T)
    t_i = ts[rows, i]
    h = (ts[rows, i + 1] - t_i)[..., None]
    s = (t[None, :] - t_i)[..., None] / h
    h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
    h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
    herm = h00 * p[rows, i] + h10 * h * v[rows, i] + h01 * p[rows, i + 1] + h11 * h * v[rows, i + 1]
    return np.where(mid[..., None], herm, out)


def sample_predictions(predictions: Sequence[NeighborPrediction], t_s: np.ndarray) -> np.ndarray:
    """``[p.position(t_s) for p in predictions]`` as one (M, T, 3) array [m], vectorised.

    Predictions are grouped by their number of samples and each group is
    evaluated by :func:`hermite_positions`.

    Args:
        predictions: M neighbour predictions.
        t_s: (T,) absolute times [s].
    """
    t = np.asarray(t_s, float).ravel()
    out = np.empty((len(predictions), t.size, 3))
    groups: dict[int, list[int]] = {}
    for idx, pred in enumerate(predictions):
        groups.setdefault(np.shape(pred.times_s)[0], []).append(idx)
    for members in groups.values():
        preds = [predictions[m] for m in members]
        out[members] = hermite_positions(
            np.stack([pr.times_s for pr in preds]), np.stack([pr.pos_world for pr in preds]),
            np.stack([pr.vel_world for pr in preds]), t,
        )  # fmt: skip
    return out
