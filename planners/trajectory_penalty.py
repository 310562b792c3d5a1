"""The compiled kernels of the MINCO penalty terms: constraint points along the pieces, trilinear ESDF lookups, neighbour states and the penalty sum with its gradient (MP-CDE Eq. 13-17).

:class:`planners.trajectory_cost.TrajectoryCost` and the compiled optimiser (:mod:`planners.trajectory_optimizer`) call them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = []


@njit(cache=True)
def _sample_positions(coeffs, T, K):
    """Positions (M (K+1), 3) [m] at ``t_ij = j T_i / K``."""
    m = T.shape[0]
    out = np.empty((m * (K + 1), 3))
    for i in range(m):
        for j in range(K + 1):
            s = j * T[i] / K
            for d in range(3):
                acc = 0.0
                for r in range(5, -1, -1):
                    acc = acc * s + coeffs[6 * i + r, d]
                out[i * (K + 1) + j, d] = acc
    return out


@njit(cache=True)
def _neighbor_state(ts, ps, vs, lo, hi, t):
    """Cubic Hermite position (px, py, pz) and its time derivative (vx, vy, vz) of one neighbour,
    as NeighborPrediction.position (constant velocity outside the samples)."""
    if t <= ts[lo] or t >= ts[hi - 1]:
        k = lo if t <= ts[lo] else hi - 1
        dt = t - ts[k]
        return (ps[k, 0] + vs[k, 0] * dt, ps[k, 1] + vs[k, 1] * dt, ps[k, 2] + vs[k, 2] * dt,
                vs[k, 0], vs[k, 1], vs[k, 2])  # fmt: skip
    i = lo
    while ts[i + 1] < t:
        i += 1
    h = ts[i + 1] - ts[i]
    s = (t - ts[i]) / h
    s2 = s * s
    s3 = s2 * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    p0 = h00 * ps[i, 0] + h10 * h * vs[i, 0] + h01 * ps[i + 1, 0] + h11 * h * vs[i + 1, 0]
    p1 = h00 * ps[i, 1] + h10 * h * vs[i, 1] + h01 * ps[i + 1, 1] + h11 * h * vs[i + 1, 1]
    p2 = h00 * ps[i, 2] + h10 * h * vs[i, 2] + h01 * ps[i + 1, 2] + h11 * h * vs[i + 1, 2]
    v0 = (d00 * ps[i, 0] + d01 * ps[i + 1, 0]) / h + d10 * vs[i, 0] + d11 * vs[i + 1, 0]
    v1 = (d00 * ps[i, 1] + d01 * ps[i + 1, 1]) / h + d10 * vs[i, 1] + d11 * vs[i + 1, 1]
    v2 = (d00 * ps[i, 2] + d01 * ps[i + 1, 2]) / h + d10 * vs[i, 2] + d11 * vs[i + 1, 2]
    return p0, p1, p2, v0, v1, v2


@njit(cache=True)
def _inflation(terms, dt, n_sig, r_max):
    """Uncertainty inflation r_n = min(n_sigma sqrt(tr P_pos), r_max) [m] and its time derivative [m/s].

    ``terms``: one row of ``NeighborTable.radius_terms``; ``dt``: t - t_last [s] (the trace is constant
    for dt <= 0).
    """
    r = 0.0
    dr = 0.0
    if n_sig > 0.0:
        if dt > 0.0:
            tr = terms[0] + terms[1] * dt + terms[2] * dt * dt
            if tr > 0.0:
                sq = np.sqrt(tr)
                r = n_sig * sq  # r_n = n_sigma sqrt(tr P_pos(t))
                dr = n_sig * (terms[1] + 2.0 * terms[2] * dt) / (2.0 * sq)
        else:
            r = n_sig * np.sqrt(max(terms[0], 0.0))
        if r > r_max:
            r = r_max
            dr = 0.0
    return r, dr


@njit(cache=True)
def _cubic(w, viol, slope):
    """GCOPTER's C^2 penalty of a violation viol > 0: (w viol^3, w slope viol^2).

    ``slope`` 3 gives d pen / d viol; 6 gives d pen / d x / x for viol = ||x||^2 - bound^2
    (:func:`_limit_penalty`).
    """
    return w * viol * viol * viol, w * slope * viol * viol


@njit(cache=True)
def _limit_penalty(w, viol, vec, grad):
    """Speed or acceleration limit: w viol^3 for viol = ||vec||^2 - bound^2 > 0; adds its gradient
    6 w viol^2 vec by ``vec`` (3,) into ``grad`` (3,)."""
    pen, gv = _cubic(w, viol, 6.0)
    for d in range(3):
        grad[d] += gv * vec[d]
    return pen


@njit(cache=True)
def _penalty_kernel(
    coeffs, T, K, t0, prm, dist, dist_grad, use_field, nb_t, nb_p, nb_v, nb_off, nb_tlast, nb_cov, gdc, gdt, out, stats
):
    """Add the penalty partial gradients to gdc (6M, 3), gdt (M,); write terms and statistics to out (8,).

    With ``stats`` False the minimum swarm margin (out[7]) is not recorded, which lets far samples skip early.

    prm = (v_max, a_max, C_o + margin, C_s + margin, 1/c, n_sigma, r_max, w_v, w_a, w_o, w_s, rho, z_lo, z_hi, w_z);
    nb_cov = NeighborTable.radius_terms. The altitude band's penalty w_z viol^3, viol = z - z_hi or z_lo - z > 0,
    is added to the obstacle term (out[2]): both keep the samples in the free workspace.
    """
    v_max, a_max, c_obs, c_sw, inv_c, n_sig, r_max = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6]
    w_v, w_a, w_o, w_s, rho = prm[7], prm[8], prm[9], prm[10], prm[11]
    z_lo, z_hi, w_z = prm[12], prm[13], prm[14]
    m = T.shape[0]
    n_nb = nb_tlast.shape[0]
    vmax2 = v_max * v_max
    amax2 = a_max * a_max
    far2 = (c_sw + r_max) * (c_sw + r_max)
    piece_tgrad = np.zeros(m)
    pos = np.empty(3)
    vel = np.empty(3)
    acc = np.empty(3)
    jer = np.empty(3)
    g_p = np.empty(3)
    g_v = np.empty(3)
    g_a = np.empty(3)
    beta0 = np.empty(6)
    f_vel = f_acc = f_obs = f_sw = 0.0
    max_v2 = max_a2 = 0.0
    min_dist = min_margin = np.inf
    pos_buf = np.empty((K + 1, 3))
    box = np.empty((2, 3))
    skip = np.zeros(n_nb, np.bool_)
    t_start = t0
    for i in range(m):
        step = T[i] / K
        r0 = 6 * i
        # sample positions of the piece and their bounding box
        box[0, :] = np.inf
        box[1, :] = -np.inf
        for j in range(K + 1):
            s1 = j * step
            for d in range(3):
                p_d = coeffs[r0 + 5, d]
                for r in range(4, -1, -1):
                    p_d = p_d * s1 + coeffs[r0 + r, d]
                pos_buf[j, d] = p_d
                box[0, d] = min(box[0, d], p_d)
                box[1, d] = max(box[1, d], p_d)
        # a constant-velocity neighbour whose segment over the piece's time window stays farther than
        # C_s + margin + r_max from the box (ellipsoid metric) cannot be penalised on this piece
        for n in range(n_nb):
            skip[n] = False
            if not stats and nb_off[n + 1] - nb_off[n] == 1:
                k = nb_off[n]
                gap2 = 0.0
                for d in range(3):
                    a = nb_p[k, d] + nb_v[k, d] * (t_start - nb_t[k])
                    b = nb_p[k, d] + nb_v[k, d] * (t_start + T[i] - nb_t[k])
                    gap = max(0.0, min(a, b) - box[1, d], box[0, d] - max(a, b))
                    gap2 += gap * gap * (inv_c if d == 2 else 1.0)
                skip[n] = gap2 >= far2
        for j in range(K + 1):
            s1 = j * step
            alpha = j / K
            omg = 0.5 if (j == 0 or j == K) else 1.0
            beta0[0] = 1.0
            for r in range(1, 6):
                beta0[r] = beta0[r - 1] * s1
            for d in range(3):
                c1, c2 = coeffs[r0 + 1, d], coeffs[r0 + 2, d]
                c3, c4, c5 = coeffs[r0 + 3, d], coeffs[r0 + 4, d], coeffs[r0 + 5, d]
                pos[d] = pos_buf[j, d]
                vel[d] = c1 + s1 * (2.0 * c2 + s1 * (3.0 * c3 + s1 * (4.0 * c4 + s1 * 5.0 * c5)))
                acc[d] = 2.0 * c2 + s1 * (6.0 * c3 + s1 * (12.0 * c4 + s1 * 20.0 * c5))
                jer[d] = 6.0 * c3 + s1 * (24.0 * c4 + s1 * 60.0 * c5)
                g_p[d] = 0.0
                g_v[d] = 0.0
                g_a[d] = 0.0
            node = 0.0
            g_t = 0.0  # d node / d t_abs (explicit time dependence, swarm term)
            v2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
            a2 = acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]
            max_v2 = max(max_v2, v2)
            max_a2 = max(max_a2, a2)
            viol = v2 - vmax2  # ||v||^2 - v_max^2
            if viol > 0.0 and w_v > 0.0:
                pen = _limit_penalty(w_v, viol, vel, g_v)
                node += pen
                f_vel += omg * step * pen
            viol = a2 - amax2  # ||a||^2 - a_max^2
            if viol > 0.0 and w_a > 0.0:
                pen = _limit_penalty(w_a, viol, acc, g_a)
                node += pen
                f_acc += omg * step * pen
            if use_field:
                idx = i * (K + 1) + j
                dist_k = dist[idx]
                if not dist_k == dist_k:  # NaN from the field poisons the cost (the optimiser raises)
                    f_obs = np.nan
                min_dist = min(min_dist, dist_k)
                viol = c_obs - dist_k  # (C_o + margin) - d(p)
                if viol > 0.0 and w_o > 0.0:
                    pen, gv = _cubic(w_o, viol, 3.0)
                    node += pen
                    f_obs += omg * step * pen
                    for d in range(3):
                        g_p[d] -= gv * dist_grad[idx, d]
            viol = max(pos[2] - z_hi, z_lo - pos[2])  # outside the altitude band [z_lo, z_hi]
            if viol > 0.0 and w_z > 0.0:
                pen, gv = _cubic(w_z, viol, 3.0)
                node += pen
                f_obs += omg * step * pen
                g_p[2] += gv if pos[2] > z_hi else -gv
            t_abs = t_start + s1
            for n in range(n_nb):
                if skip[n]:
                    continue
                px, py, pz, vx, vy, vz = _neighbor_state(nb_t, nb_p, nb_v, nb_off[n], nb_off[n + 1], t_abs)
                dx = pos[0] - px
                dy = pos[1] - py
                dz = pos[2] - pz
                ell2 = dx * dx + dy * dy + dz * dz * inv_c  # ||E^{1/2}(p - p_n)||^2
                if ell2 >= far2 and not stats:  # beyond C_s + margin + r_max: no penalty, nothing to record
                    continue
                r, dr = _inflation(nb_cov[n], t_abs - nb_tlast[n], n_sig, r_max)
                if stats:
                    min_margin = min(min_margin, np.sqrt(ell2) - r)
                clr = c_sw + r
                if nb_cov[n, 3] > 0.0:  # start inside the clearance: s_n(t) = max(0, s0 - rho (t - t0))
                    cut = nb_cov[n, 3] - rho * (t_abs - t0)
                    if cut > 0.0:
                        clr -= cut
                        dr += rho  # d clr / d t_abs (enters through 2 clr dr below)
                viol = clr * clr - ell2  # MP-CDE Eq. 16
                if viol > 0.0 and w_s > 0.0:
                    pen, gv = _cubic(w_s, viol, 3.0)
                    node += pen
                    f_sw += omg * step * pen
                    g_p[0] -= gv * 2.0 * dx
                    g_p[1] -= gv * 2.0 * dy
                    g_p[2] -= gv * 2.0 * dz * inv_c
                    # d viol / d t_abs = 2 clr dr/dt + 2 (E d) . v_n
                    g_t += gv * (2.0 * clr * dr + 2.0 * (dx * vx + dy * vy + dz * inv_c * vz))
            if node == 0.0 and g_t == 0.0:
                continue
            w = omg * step
            for r in range(6):
                b0 = beta0[r]
                b1 = r * beta0[r - 1] if r >= 1 else 0.0
                b2 = r * (r - 1) * beta0[r - 2] if r >= 2 else 0.0
                for d in range(3):
                    gdc[r0 + r, d] += w * (b0 * g_p[d] + b1 * g_v[d] + b2 * g_a[d])
            chain = g_p[0] * vel[0] + g_p[1] * vel[1] + g_p[2] * vel[2]
            chain += g_v[0] * acc[0] + g_v[1] * acc[1] + g_v[2] * acc[2]
            chain += g_a[0] * jer[0] + g_a[1] * jer[1] + g_a[2] * jer[2]
            gdt[i] += omg * node / K + w * alpha * (chain + g_t)
            piece_tgrad[i] += w * g_t
        t_start += T[i]
    out[0], out[1], out[2], out[3] = f_vel, f_acc, f_obs, f_sw
    out[4], out[5], out[6], out[7] = np.sqrt(max_v2), np.sqrt(max_a2), min_dist, min_margin
    acc_t = 0.0  # t_abs of piece i moves with every T_k, k < i
    for i in range(m - 1, 0, -1):
        acc_t += piece_tgrad[i]
        gdt[i - 1] += acc_t
