"""Eq. 13: coordinates from distances to anchors, for many nodes at once.

Each node k minimises ``sum_i w_ik (d_ik - |a_ik - p_k|)^2`` over its position ``p_k``. All
nodes are solved together by a vectorised Levenberg-Marquardt iteration: per node, the 2x2
normal equations of the Gauss-Newton step are damped by ``lambda * diag`` and solved in closed
form; a step is kept where it lowers that node's cost (then lambda shrinks), else lambda grows.
Every iterate is clipped to the field, so estimates respect its bounds; a coordinate on a bound
whose descent leads out of the field is held there and the node steps along the bound (projected
Levenberg-Marquardt), so a node whose unbounded minimum lies outside reaches the bounded one.
Anchor lists are padded to one length; padded entries carry weight 0.
"""

from __future__ import annotations

import numpy as np

from aoass_env.validators import float_array, integer, positive, real, vec2

__all__ = ["multilaterate"]

_LAMBDA0 = 1e-3
_LAMBDA_DOWN, _LAMBDA_UP = 1 / 3, 4.0
_LAMBDA_MAX = 1e8  # a node whose damping grew this far sits at a (bounded) minimum
_MIN_RANGE = 1e-9  # [m], guards the Jacobian when an iterate sits on an anchor


def _offsets(p: np.ndarray, anchors: np.ndarray, distances: np.ndarray,
             weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Offsets dx, dy from the anchors, ranges r (S, M) and weighted costs (S,) at ``p``."""
    dx = p[:, None, 0] - anchors[..., 0]
    dy = p[:, None, 1] - anchors[..., 1]
    r = np.hypot(dx, dy)
    return dx, dy, r, np.einsum("sm,sm->s", weights, (r - distances) ** 2)


def multilaterate(anchors: np.ndarray, distances: np.ndarray, weights: np.ndarray,
                  init: np.ndarray, field: tuple[float, float], *, max_iter: int = 40,
                  tol: float = 1e-4) -> np.ndarray:
    """Weighted least-squares positions (S, 2) [m] of S nodes (Eq. 13).

    Args:
        anchors: (S, M, 2) anchor positions per node [m] (padding: any finite value).
        distances: (S, M) estimated distances to those anchors [m].
        weights: (S, M) non-negative weights (0 = padding / unused anchor).
        init: (S, 2) starting positions [m], clipped to the field.
        field: field width and height [m] (both > 0); estimates stay in ``[0, w] x [0, h]``.
        max_iter: iteration limit (>= 1).
        tol: a node has converged once an accepted step is at most this [m] (>= 0); the
            iteration stops when every node has.

    Raises:
        ValueError: shapes disagree, an input is not finite, a distance or weight is negative,
            or ``field``, ``max_iter`` or ``tol`` is out of range.
    """
    width, height = (positive(f"field[{i}]", v, "m") for i, v in enumerate(vec2("field", field,
                                                                                   "m")))
    max_iter = integer("max_iter", max_iter, low=1)
    tol = real("tol", tol, "m", low=0)
    a, d, w, p = (float_array(name, value) for name, value in (
        ("anchors", anchors), ("distances", distances), ("weights", weights), ("init", init)))
    if a.ndim != 3 or a.shape[2] != 2 or d.shape != a.shape[:2] or w.shape != d.shape \
            or p.shape != (a.shape[0], 2):
        raise ValueError(f"shapes must be anchors (S, M, 2), distances and weights (S, M), init "
                         f"(S, 2); got {a.shape}, {d.shape}, {w.shape}, {p.shape}")
    for name, value in (("anchors", a), ("distances", d), ("weights", w), ("init", p)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} must be finite")
    if np.any(w < 0):
        raise ValueError("weights must be non-negative")
    if np.any(d < 0):
        raise ValueError("distances must be non-negative")
    hi = np.array([width, height])
    out = np.clip(p, 0.0, hi)
    # working set: the nodes still iterating, compacted whenever some converge
    act = np.arange(len(out))
    p, lam = out.copy(), np.full(len(out), _LAMBDA0)
    dx, dy, r, cost = _offsets(p, a, d, w)
    for _ in range(max_iter):
        q = w / np.maximum(r, _MIN_RANGE)  # w / r: Jacobian rows are (dx, dy) / r
        qres = q * (r - d)
        gx, gy = np.einsum("sm,sm->s", qres, dx), np.einsum("sm,sm->s", qres, dy)
        q /= np.maximum(r, _MIN_RANGE)
        qx = q * dx
        hxy = np.einsum("sm,sm->s", qx, dy)
        axx = np.einsum("sm,sm->s", qx, dx) * (1 + lam) + 1e-12
        ayy = np.einsum("sm,sm,sm->s", q, dy, dy) * (1 + lam) + 1e-12
        det = axx * ayy - hxy * hxy
        step = np.stack([-(ayy * gx - hxy * gy) / det, -(axx * gy - hxy * gx) / det], axis=1)
        # a coordinate on a bound whose descent leads out of the field is held there (an
        # active bound) and the step taken along the other alone; clipping the full step
        # instead would cancel it and only grow the damping, far from the bounded minimum
        held_x = ((p[:, 0] <= 0.0) & (gx > 0)) | ((p[:, 0] >= hi[0]) & (gx < 0))
        held_y = ((p[:, 1] <= 0.0) & (gy > 0)) | ((p[:, 1] >= hi[1]) & (gy < 0))
        step[held_x | held_y] = 0.0
        only_y, only_x = held_x & ~held_y, held_y & ~held_x
        step[only_y, 1] = -gy[only_y] / ayy[only_y]
        step[only_x, 0] = -gx[only_x] / axx[only_x]
        trial = np.clip(p + step, 0.0, hi)
        tdx, tdy, tr, tcost = _offsets(trial, a, d, w)
        better = tcost < cost
        moved = np.hypot(*(trial - p).T)
        p = np.where(better[:, None], trial, p)
        cost = np.where(better, tcost, cost)
        keep = better[:, None]      # the offsets of the point each node now sits at
        dx, dy, r = np.where(keep, tdx, dx), np.where(keep, tdy, dy), np.where(keep, tr, r)
        lam = np.where(better, lam * _LAMBDA_DOWN, lam * _LAMBDA_UP)
        out[act] = p
        # a node at a corner whose descent leads out of the field on both axes is at its
        # bounded minimum
        going = ~((better & (moved <= tol)) | (lam > _LAMBDA_MAX) | (held_x & held_y))
        if not going.any():
            break
        if not going.all():
            act, p, lam, cost = act[going], p[going], lam[going], cost[going]
            a, d, w = a[going], d[going], w[going]
            dx, dy, r = dx[going], dy[going], r[going]
    return out
