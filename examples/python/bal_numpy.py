"""The BAL camera model in numpy ("Bundle Adjustment in the Large"; the model of carat's
SnavelyReprojectionBlock): residuals and analytic Jacobians of many observations at once.

A camera is [w (3, angle-axis, radians), t (3), f (pixels), k1, k2]; a world point X maps to
P = R(w) X + t, p = -(P_x, P_y) / P_z, d = 1 + k1 |p|^2 + k2 |p|^4, image = f d p (pixels).
Every quantity is held as one array per coordinate (structure of arrays), so that each step is
one whole-array numpy operation, and the results are returned as transposed views of arrays
filled one coordinate at a time (carat reads such views in place). Observations are taken in
chunks of a few thousand: numpy runs about three times faster on arrays that stay in cache.
"""

import numpy as np


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _rodrigues_terms(w):
    """sin(t) / t, (1 - cos t) / t^2 and (t - sin t) / t^3 of t = |w| (series near 0)."""
    theta2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    small = theta2 < 1e-12
    theta = np.sqrt(np.where(small, 1.0, theta2))
    s, c = np.sin(theta), np.cos(theta)
    a = np.where(small, 1.0 - theta2 / 6.0, s / theta)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - c) / (theta * theta))
    c3 = np.where(small, 1.0 / 6.0 - theta2 / 120.0, (theta - s) / (theta * theta * theta))
    return a, b, c3


def _project_into(C, X, image, J_camera, J_point):
    """Fills image (2 x n) and, unless J_camera is None, J_camera (2 x 9 x n) and J_point
    (2 x 3 x n) for the cameras C (9 x n) and points X (3 x n)."""
    w, f, k1, k2 = C[0:3], C[6], C[7], C[8]
    a, b, c3 = _rodrigues_terms(w)
    wx = _cross(w, X)
    wwx = _cross(w, wx)
    RX = [X[i] + a * wx[i] + b * wwx[i] for i in range(3)]  # R(w) X (Rodrigues)
    P = [RX[i] + C[3 + i] for i in range(3)]
    inv_z = 1.0 / P[2]
    p = (-P[0] * inv_z, -P[1] * inv_z)
    r2 = p[0] * p[0] + p[1] * p[1]
    d = 1.0 + r2 * (k1 + k2 * r2)
    fd = f * d
    np.multiply(fd, p[0], out=image[0])
    np.multiply(fd, p[1], out=image[1])
    if J_camera is None:
        return
    e = 2.0 * f * (k1 + 2.0 * k2 * r2)
    for i in range(2):
        # Row i of d image / d P: f (d I + 2 (k1 + 2 k2 r2) p p^T) times [-I, -p] / P_z.
        A = (fd + e * p[0] * p[0], e * p[0] * p[1]) if i == 0 else (e * p[0] * p[1], fd + e * p[1] * p[1])
        G = (-A[0] * inv_z, -A[1] * inv_z, -(A[0] * p[0] + A[1] * p[1]) * inv_z)
        # d P / d w = -[R X]_x J_l(w), J_l = I + b [w]_x + c3 [w]_x^2, so G dP/dw = -(g + b g[w]_x
        # + c3 g[w]_x^2) with the row g = G [R X]_x = G x R X.
        g = _cross(G, RX)
        gw = _cross(g, w)
        gww = _cross(gw, w)
        # d P / d X = R: the row G R = R^T G, G rotated by -w.
        gx = _cross(w, G)
        gxx = _cross(w, gx)
        for k in range(3):
            J_camera[i, k] = -(g[k] + b * gw[k] + c3 * gww[k])
            J_camera[i, 3 + k] = G[k]
            J_point[i, k] = G[k] - a * gx[k] + b * gxx[k]
        J_camera[i, 6] = d * p[i]
        J_camera[i, 7] = f * r2 * p[i]
        J_camera[i, 8] = J_camera[i, 7] * r2


def project(cameras, points, jacobians=True, chunk=8192):
    """Images (N x 2, pixels) of N points (N x 3) by N cameras (N x 9); with jacobians, also
    d image / d camera (N x 2 x 9) and d image / d point (N x 2 x 3)."""
    n = len(cameras)
    C, X = cameras.T, points.T  # rows of coordinates (contiguous for column-major inputs)
    image = np.empty((2, n))
    J_camera = np.empty((2, 9, n)) if jacobians else None
    J_point = np.empty((2, 3, n)) if jacobians else None
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        _project_into(C[:, s:e], X[:, s:e], image[:, s:e],
                      None if J_camera is None else J_camera[:, :, s:e],
                      None if J_point is None else J_point[:, :, s:e])
    if not jacobians:
        return image.T
    return image.T, J_camera.transpose(2, 0, 1), J_point.transpose(2, 0, 1)
