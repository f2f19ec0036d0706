"""A known planar map of walls and the distance along a ray to the nearest one, with its Jacobian
with respect to a Pose2 (docs/models/epuck.md#known-map-and-ray-distance). Pure numpy, vectorized
over poses, rays and wall segments.

A sensor mounted at m (body frame, m) looking along angle phi has, at pose X = (R, t), its origin
o = t + R m and direction u = R (cos phi, sin phi). The ray o + d u meets segment p0 + s D
(0 <= s <= 1) at d = n.(p0 - o) / n.u, n = (-D_y, D_x); the distance is the smallest such d > 0
(inf when the ray meets no wall). GTSAM perturbs a Pose2 on the right, X Exp(xi), xi = (v_x, v_y,
w) in the body frame: do/dxi = [R, R J m], du/dxi = [0, 0, J u] with J the 90-degree rotation, so

    dd/dxi = -(n^T do/dxi + d n^T du/dxi) / n.u
"""

from __future__ import annotations

import numpy as np

PARALLEL = 1e-12  # |n.u| below this (per unit segment length): the ray runs along the wall


def segments_of(segments: list, polygons: list) -> np.ndarray:
    """(M, 2, 2) wall segments: the listed ones, then every polygon's edges (closed: last to first)."""
    out = [np.asarray(s, float).reshape(2, 2) for s in segments]
    for poly in polygons:
        p = np.asarray(poly, float).reshape(-1, 2)
        out += [np.stack([p[i], p[(i + 1) % len(p)]]) for i in range(len(p))]
    return np.asarray(out, float).reshape(-1, 2, 2)


def box_walls(width: float, height: float) -> np.ndarray:
    """The four walls of a width x height box (m) with a corner at the origin."""
    return segments_of([], [[[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]]])


def _nearest_hit(walls: np.ndarray, ox, oy, ux, uy) -> tuple[np.ndarray, np.ndarray]:
    """Distance from origins (ox, oy) (R,) along unit directions (ux, uy) to the nearest wall, and its
    index (-1 and inf: none)."""
    p0x, p0y = walls[:, 0, 0], walls[:, 0, 1]
    Dx, Dy = walls[:, 1, 0] - p0x, walls[:, 1, 1] - p0y                 # (M,)
    wx, wy = p0x - ox[:, None], p0y - oy[:, None]                        # (R, M)
    cross = ux[:, None] * Dy - uy[:, None] * Dx
    ok = np.abs(cross) > PARALLEL * np.hypot(Dx, Dy)
    den = np.where(ok, cross, 1.0)
    t = (wx * Dy - wy * Dx) / den                                        # along the ray
    s = (wx * uy[:, None] - wy * ux[:, None]) / den                      # along the segment
    t = np.where(ok & (t > 0.0) & (s >= 0.0) & (s <= 1.0), t, np.inf)
    index = np.argmin(t, axis=1)
    d = t[np.arange(len(index)), index]
    return d, np.where(np.isfinite(d), index, -1)


def ray_distances(walls: np.ndarray, pose: np.ndarray, mount: np.ndarray, angle: np.ndarray,
                  jacobian: bool = False):
    """Distance d (R,) along each ray to the nearest wall: ray r from the sensor at mount[r] (m, body
    frame) along angle[r] (rad, body frame) on a body at pose[r] = (x, y, theta); with `jacobian`,
    also dd/dxi (R, 3) in GTSAM's Pose2 tangent (zero where d is inf)."""
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    Rmx, Rmy = c * mount[:, 0] - s * mount[:, 1], s * mount[:, 0] + c * mount[:, 1]   # R m
    heading = pose[:, 2] + angle
    ux, uy = np.cos(heading), np.sin(heading)
    d, index = _nearest_hit(walls, pose[:, 0] + Rmx, pose[:, 1] + Rmy, ux, uy)
    if not jacobian:
        return d
    hit = index >= 0
    wall = walls[np.maximum(index, 0)]
    nx, ny = wall[:, 0, 1] - wall[:, 1, 1], wall[:, 1, 0] - wall[:, 0, 0]             # n = (-D_y, D_x)
    nu = np.where(hit, nx * ux + ny * uy, 1.0)
    # n^T do/dxi = [n^T R, n^T R J m] with R J m = J R m = (-Rmy, Rmx); n^T du/dxi = [0, 0, n^T J u]
    turn = -nx * Rmy + ny * Rmx + np.where(hit, d, 0.0) * (-nx * uy + ny * ux)
    H = np.empty((len(d), 3))
    H[:, 0], H[:, 1], H[:, 2] = nx * c + ny * s, -nx * s + ny * c, turn
    H *= np.where(hit, -1.0 / nu, 0.0)[:, None]
    return d, H


def sensor_distances(walls: np.ndarray, pose: np.ndarray, mounts: np.ndarray, angles: np.ndarray,
                     jacobian: bool = False):
    """Distances d (N, S) of S sensors (mounts (S, 2) m, angles (S,) rad) to the walls at N poses
    (N, 3); with `jacobian`, also dd/dxi (N, S, 3)."""
    N, S = len(pose), len(angles)
    out = ray_distances(walls, np.repeat(pose, S, 0), np.tile(mounts, (N, 1)), np.tile(angles, N), jacobian)
    if not jacobian:
        return out.reshape(N, S)
    return out[0].reshape(N, S), out[1].reshape(N, S, 3)
