"""Camera models: the equirectangular panorama (paper eqs. 11-16, 21) and an OpenCV pinhole.

Both models share one interface (:class:`CameraModel`) so the GMM cost is written once:
- ``project(points_cam)`` -> ``uv`` (N,2) px, ``valid`` (N,) bool;
- ``project_jacobian(points_cam)`` -> ``d uv / d p_cam`` (N,2,3) px/m;
- ``back_project(uv)`` -> unit rays (N,3) in the camera frame;
- ``displacement(uv_pixels, uv_centres)`` -> (N,2) px, the shortest route (paper 5.2); its derivative
  with respect to the centre is always ``-I`` so gradients need no special cases;
- ``pixel_area_ratio(uv)`` -> ``S_x / S(uv)`` of paper eq. 23 (see docs/method.md for the pinhole form);
- ``pixels_per_radian``: the scale that turns an angle at 1 m (sigma_in) into pixels.

Pixel centres are at integer coordinates: pixel (row i, column j) is ``(u, v) = (j, i)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.errors import GeometryError

F64 = NDArray[np.float64]
Mask = NDArray[np.bool_]

_MIN_DEPTH_M = 1e-6


class CameraModel(Protocol):
    @property
    def width(self) -> int: ...

    @property
    def height(self) -> int: ...

    @property
    def pixels_per_radian(self) -> float: ...

    def project(self, points_cam: F64) -> tuple[F64, Mask]: ...

    def project_jacobian(self, points_cam: F64) -> F64: ...

    def back_project(self, uv: F64) -> F64: ...

    def displacement(self, uv_pixels: F64, uv_centres: F64) -> F64: ...

    def pixel_area_ratio(self, uv: F64) -> F64: ...


@dataclass(frozen=True)
class Equirectangular:
    """Spherical panorama, camera frame x forward, y left, z up (paper Fig. 5).

    ``u = w (pi - theta) / (2 pi)``, ``v = h phi / pi`` with ``theta = atan2(y, x)``, ``phi = acos(z / r)``.
    """

    width: int
    height: int

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise GeometryError(f"panorama size must be positive, got {self.width}x{self.height}")

    @property
    def pixels_per_radian(self) -> float:
        return self.width / (2.0 * np.pi)

    def project(self, points_cam: F64) -> tuple[F64, Mask]:
        p = np.asarray(points_cam, dtype=np.float64)
        r = np.linalg.norm(p, axis=1)
        valid = r > _MIN_DEPTH_M
        theta = np.arctan2(p[:, 1], p[:, 0])  # eq. 12
        phi = np.arccos(np.clip(p[:, 2] / np.where(valid, r, 1.0), -1.0, 1.0))  # eq. 13
        u = self.width * (np.pi - theta) / (2.0 * np.pi)  # eq. 15
        v = self.height * phi / np.pi  # eq. 16
        return np.stack([np.mod(u, self.width), v], axis=1), valid

    def project_jacobian(self, points_cam: F64) -> F64:
        """d(u, v)/d(x, y, z) from eqs. 12-16 (paper eq. 29), (N,2,3) px/m."""
        p = np.asarray(points_cam, dtype=np.float64)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        rho2 = np.maximum(x * x + y * y, 1e-18)
        rho = np.sqrt(rho2)
        r2 = rho2 + z * z
        jac = np.zeros((len(p), 2, 3))
        ku = -self.width / (2.0 * np.pi)
        jac[:, 0, 0] = ku * (-y / rho2)
        jac[:, 0, 1] = ku * (x / rho2)
        kv = self.height / np.pi
        jac[:, 1, 0] = kv * x * z / (r2 * rho)
        jac[:, 1, 1] = kv * y * z / (r2 * rho)
        jac[:, 1, 2] = kv * (-rho / r2)
        return jac

    def back_project(self, uv: F64) -> F64:
        uv = np.asarray(uv, dtype=np.float64)
        theta = np.pi - 2.0 * np.pi * uv[:, 0] / self.width
        phi = np.pi * uv[:, 1] / self.height
        return np.stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)], axis=1)

    def displacement(self, uv_pixels: F64, uv_centres: F64) -> F64:
        """Shortest of the routes of paper 5.2 (Fig. 6) from each centre to its pixel, (N,2) px.

        Horizontal routes: direct or across the u = 0/w seam. Vertical routes: direct, or over the north
        or south pole, which arrives half a turn (w/2) away in azimuth. The vertical component's sign is
        chosen so that d(displacement)/d(centre) = -I on every route.
        """
        w, h = float(self.width), float(self.height)
        du = uv_pixels[:, 0] - uv_centres[:, 0]
        vp, vc = uv_pixels[:, 1], uv_centres[:, 1]
        du_direct = du - w * np.round(du / w)
        du_pole = du - w / 2.0
        du_pole = du_pole - w * np.round(du_pole / w)
        routes_u = np.stack([du_direct, du_pole, du_pole])
        routes_v = np.stack([vp - vc, -(vp + vc), 2.0 * h - vp - vc])
        best = np.argmin(routes_u**2 + routes_v**2, axis=0)
        cols = np.arange(len(du))
        return np.stack([routes_u[best, cols], routes_v[best, cols]], axis=1)

    def pixel_area_ratio(self, uv: F64) -> F64:
        """``S_x / S(v)`` of eqs. 18-23: the pixel at v covers a solid angle prop. to sin(pi v / h).

        Eq. 21 gives ``S(v) = (2 pi / w) * 2 sin(pi v / h) sin(pi / 2h)``; at ``p_x = [1, 0, 0]``
        (``v = h/2``) the sine is 1, so the ratio is ``1 / sin(pi v / h)``. It is clamped near the poles
        where the pixel area vanishes.
        """
        s = np.sin(np.pi * np.asarray(uv, dtype=np.float64)[:, 1] / self.height)
        return 1.0 / np.maximum(s, 0.05)


def _check_intrinsics(k: F64, model: str) -> None:
    """Raise GeometryError naming the first bad entry of ``k`` (3,3) px, the intrinsic matrix of a ``model`` camera.

    Checked here, at construction, because a bad K fails far from its cause: a zero fx divides by zero in the
    search's field of view, a negative one turns the texture radius into NaN, and a non-[0, 0, 1] last row is
    silently ignored by the projection (which reads fx, skew, cx, fy, cy only).
    """
    names = (("fx", "skew", "cx"), ("K[1,0]", "fy", "cy"), ("K[2,0]", "K[2,1]", "K[2,2]"))
    for i in range(3):
        for j in range(3):
            if not np.isfinite(k[i, j]):
                raise GeometryError(f"{model} K: {names[i][j]} must be finite, got {k[i, j]:g}")
    for i, name in ((0, "fx"), (1, "fy")):
        if k[i, i] <= 0:
            raise GeometryError(f"{model} K: {name} must be > 0, got {k[i, i]:g}")
    if k[1, 0] != 0:
        raise GeometryError(f"{model} K: K[1,0] must be 0 (K is upper triangular), got {k[1, 0]:g}")
    if not np.array_equal(k[2], [0.0, 0.0, 1.0]):
        raise GeometryError(f"{model} K: the last row must be [0, 0, 1], got {k[2].tolist()}")


@dataclass(frozen=True)
class Pinhole:
    """OpenCV pinhole with distortion ``D`` = (k1, k2, p1, p2[, k3]); optical frame z fwd, x right, y down.

    ``K`` (3,3) px. Points project onto the raw (distorted) image, like ``cv2.projectPoints``.
    """

    K: F64
    D: F64
    width: int
    height: int
    _max_r2: float = field(init=False, repr=False, default=0.0)

    def __post_init__(self) -> None:
        k = np.asarray(self.K, dtype=np.float64)
        d = np.zeros(5)
        d_in = np.asarray(self.D, dtype=np.float64).reshape(-1)
        if k.shape != (3, 3) or d_in.size not in (0, 4, 5) or self.width <= 0 or self.height <= 0:
            raise GeometryError("pinhole needs K (3x3), D with 0, 4 or 5 numbers and a positive size")
        _check_intrinsics(k, "pinhole")
        if not np.all(np.isfinite(d_in)):
            raise GeometryError(f"pinhole D must be finite, got {d_in.tolist()}")
        d[: d_in.size] = d_in
        object.__setattr__(self, "K", k)
        object.__setattr__(self, "D", d)
        object.__setattr__(self, "_max_r2", self._field_of_view_r2())

    def _field_of_view_r2(self) -> float:
        """Largest squared normalised radius that maps into the image (1.2x margin over the corners).

        Beyond it the polynomial distortion can fold back and put far-off-axis points inside the image.
        """
        w, h = self.width - 1.0, self.height - 1.0
        border = np.array([[0, 0], [w, 0], [0, h], [w, h], [w / 2, 0], [0, h / 2], [w, h / 2], [w / 2, h]])
        und = cv2.undistortPoints(border.reshape(-1, 1, 2), self.K, self.D).reshape(-1, 2)
        return float(1.2 * np.max(np.sum(und**2, axis=1)))

    @property
    def pixels_per_radian(self) -> float:
        return float(np.sqrt(self.K[0, 0] * self.K[1, 1]))

    def _normalised(self, points_cam: F64) -> tuple[F64, F64, F64, Mask]:
        p = np.asarray(points_cam, dtype=np.float64)
        z = p[:, 2]
        front = z > _MIN_DEPTH_M
        zs = np.where(front, z, 1.0)
        x, y = p[:, 0] / zs, p[:, 1] / zs
        return x, y, zs, front & (x * x + y * y < self._max_r2)

    def project(self, points_cam: F64) -> tuple[F64, Mask]:
        x, y, _, valid = self._normalised(points_cam)
        k1, k2, p1, p2, k3 = self.D
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        u = self.K[0, 0] * xd + self.K[0, 1] * yd + self.K[0, 2]
        v = self.K[1, 1] * yd + self.K[1, 2]
        return np.stack([u, v], axis=1), valid

    def project_jacobian(self, points_cam: F64) -> F64:
        x, y, zs, _ = self._normalised(points_cam)
        k1, k2, p1, p2, k3 = self.D
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        d_radial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        # d(xd, yd)/d(x, y)
        dxd_dx = radial + 2.0 * x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x
        dxd_dy = 2.0 * x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        dyd_dx = 2.0 * x * y * d_radial + 2.0 * p1 * x + 2.0 * p2 * y
        dyd_dy = radial + 2.0 * y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x
        # d(u, v)/d(x, y) through K, then d(x, y)/d(p) for x = X/Z, y = Y/Z: written out, as the (N,2,2) x (N,2,3)
        # product is a sixth of an iteration's time on a five-sensor head through einsum.
        du_dx = self.K[0, 0] * dxd_dx + self.K[0, 1] * dyd_dx
        du_dy = self.K[0, 0] * dxd_dy + self.K[0, 1] * dyd_dy
        dv_dx = self.K[1, 1] * dyd_dx
        dv_dy = self.K[1, 1] * dyd_dy
        inv_z = 1.0 / zs
        jac = np.empty((len(x), 2, 3))
        jac[:, 0, 0] = du_dx * inv_z
        jac[:, 0, 1] = du_dy * inv_z
        jac[:, 0, 2] = -(du_dx * x + du_dy * y) * inv_z
        jac[:, 1, 0] = dv_dx * inv_z
        jac[:, 1, 1] = dv_dy * inv_z
        jac[:, 1, 2] = -(dv_dx * x + dv_dy * y) * inv_z
        return jac

    def back_project(self, uv: F64) -> F64:
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 1, 2)
        if not self.D.any():  # a rectified image (the Ford and KITTI sets): K's inverse, without the iteration
            y = (uv[:, 0, 1] - self.K[1, 2]) / self.K[1, 1]
            xy = np.stack([(uv[:, 0, 0] - self.K[0, 2] - self.K[0, 1] * y) / self.K[0, 0], y], axis=1)
        else:
            xy = cv2.undistortPoints(uv, self.K, self.D).reshape(-1, 2)
        rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
        unit_rays: F64 = rays / np.linalg.norm(rays, axis=1, keepdims=True)
        return unit_rays

    def displacement(self, uv_pixels: F64, uv_centres: F64) -> F64:
        return np.asarray(uv_pixels, dtype=np.float64) - np.asarray(uv_centres, dtype=np.float64)

    def pixel_area_ratio(self, uv: F64) -> F64:
        """``S_x / S(uv)`` for a pinhole: a pixel's solid angle is ``cos^3(alpha) / (fx fy)``.

        ``alpha`` is the angle between the pixel's ray and the optical axis (a pixel of area dA on the
        image plane at distance f, seen at incidence alpha from a distance f / cos(alpha)). The reference
        ``S_x`` is the principal point's, so the ratio is ``1 / cos^3(alpha)`` (lens distortion is folded in
        through the undistorted ray; its own area change is a second-order effect we leave out).
        """
        rays = self.back_project(uv)
        return 1.0 / np.maximum(rays[:, 2], 0.2) ** 3


@dataclass(frozen=True)
class Mounted:
    """One sensor of a multi-camera head (a Ladybug's five side cameras), as a camera of the head frame.

    ``sensor`` projects points of its own frame (a :class:`Pinhole` in the OpenCV optical frame);
    ``rotation`` (3,3) and ``translation_m`` (3,) map head points into it, ``p_sensor = R p_head + t`` (the
    inverse of the factory pose ``T_head_sensor``). With such cameras the calibration's unknown is
    ``T_head_lidar``: every sensor of every place aligns its edges under that one transform, and a point
    seen by two sensors counts in both. ``name`` names the sensor in reports and files.
    """

    name: str
    sensor: Pinhole | Fisheye
    rotation: F64
    translation_m: F64

    def __post_init__(self) -> None:
        r = np.asarray(self.rotation, dtype=np.float64)
        t = np.asarray(self.translation_m, dtype=np.float64).reshape(-1)
        if r.shape != (3, 3) or t.shape != (3,) or not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):
            raise GeometryError(f"sensor {self.name}: its pose in the head needs a 3x3 rotation and 3 finite numbers")
        object.__setattr__(self, "rotation", r)
        object.__setattr__(self, "translation_m", t)

    @property
    def width(self) -> int:
        return self.sensor.width

    @property
    def height(self) -> int:
        return self.sensor.height

    @property
    def pixels_per_radian(self) -> float:
        return self.sensor.pixels_per_radian

    def to_sensor(self, points_head: F64) -> F64:
        """Head points (N,3) m into the sensor's frame (N,3) m."""
        out: F64 = np.asarray(points_head, dtype=np.float64) @ self.rotation.T + self.translation_m
        return out

    def project(self, points_head: F64) -> tuple[F64, Mask]:
        return self.sensor.project(self.to_sensor(points_head))

    def project_jacobian(self, points_head: F64) -> F64:
        """d uv / d p_head (N,2,3) px/m: the sensor's Jacobian times R (the chain rule through the fixed pose)."""
        jac = self.sensor.project_jacobian(self.to_sensor(points_head))
        # One (2N,3) x (3,3) product: ten times faster than numpy's N stacked (2,3) x (3,3) ones, the same values.
        out: F64 = (jac.reshape(-1, 3) @ self.rotation).reshape(jac.shape)
        return out

    def back_project(self, uv: F64) -> F64:
        """Unit rays (N,3) of the pixels, in the head frame."""
        rays: F64 = self.sensor.back_project(uv) @ self.rotation
        return rays

    def displacement(self, uv_pixels: F64, uv_centres: F64) -> F64:
        return self.sensor.displacement(uv_pixels, uv_centres)

    def pixel_area_ratio(self, uv: F64) -> F64:
        return self.sensor.pixel_area_ratio(uv)


@dataclass(frozen=True)
class Fisheye:
    """OpenCV's fisheye model (``cv2.fisheye``: equidistant with ``D`` = (k1, k2, k3, k4)) for wide lenses;
    optical frame z forward, x right, y down. ``K`` (3,3) px with OpenCV's fisheye skew ``K[0,1] = alpha fx``.

    A ray at angle ``theta`` from the optical axis lands at ``r = theta_d = theta (1 + k1 theta^2 + k2 theta^4 +
    k3 theta^6 + k4 theta^8)`` from the principal point (normalised), along its azimuth. ``theta`` is taken as
    ``atan2(sqrt(x^2 + y^2), z)``, which equals OpenCV's ``atan(sqrt(a^2 + b^2))`` (a = x/z, b = y/z) in front
    and goes on past 90 deg, where a wide lens still sees. Points beyond the image's widest ``theta`` (5 % margin)
    or where the polynomial stops growing are invalid.
    """

    K: F64
    D: F64
    width: int
    height: int
    _max_theta: float = field(init=False, repr=False, default=0.0)

    def __post_init__(self) -> None:
        k = np.asarray(self.K, dtype=np.float64)
        d = np.asarray(self.D, dtype=np.float64).reshape(-1)
        if k.shape != (3, 3) or d.size != 4 or self.width <= 0 or self.height <= 0:
            raise GeometryError("fisheye needs K (3x3), D with 4 numbers (k1..k4) and a positive size")
        _check_intrinsics(k, "fisheye")
        if not np.all(np.isfinite(d)):
            raise GeometryError(f"fisheye D must be finite, got {d.tolist()}")
        object.__setattr__(self, "K", k)
        object.__setattr__(self, "D", d)
        object.__setattr__(self, "_max_theta", self._field_of_view())

    def _theta_d(self, theta: F64) -> tuple[F64, F64]:
        """theta_d (N,) and d theta_d / d theta (N,)."""
        t2 = theta * theta
        k1, k2, k3, k4 = self.D
        poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))
        d_poly = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
        return theta * poly, d_poly

    def _field_of_view(self) -> float:
        """The widest theta that maps into the image (corners, 5 % margin), and never past where theta_d folds."""
        grid = np.linspace(0.0, np.pi, 4001)
        _, slope = self._theta_d(grid)
        folds = np.flatnonzero(slope <= 0.0)
        limit = float(grid[folds[0] - 1]) if folds.size else float(np.pi)
        w, h = self.width - 1.0, self.height - 1.0
        corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], dtype=np.float64)
        theta = np.arccos(np.clip(self._unit_rays(corners, limit)[:, 2], -1.0, 1.0))
        return float(min(1.05 * float(theta.max()), limit))

    @property
    def pixels_per_radian(self) -> float:
        return float(np.sqrt(self.K[0, 0] * self.K[1, 1]))

    def _distorted(self, points_cam: F64) -> tuple[F64, F64, F64, F64, F64, Mask]:
        p = np.asarray(points_cam, dtype=np.float64)
        rho = np.hypot(p[:, 0], p[:, 1])
        theta = np.arctan2(rho, p[:, 2])
        theta_d, d_theta_d = self._theta_d(theta)
        valid = (np.linalg.norm(p, axis=1) > _MIN_DEPTH_M) & (theta < self._max_theta)
        return p, rho, theta, theta_d, d_theta_d, valid

    def project(self, points_cam: F64) -> tuple[F64, Mask]:
        p, rho, theta, theta_d, _, valid = self._distorted(points_cam)
        # theta_d / rho -> 1 / z on the axis (theta ~ rho / z): the limit avoids 0 / 0 there.
        scale = np.where(rho > 1e-9 * np.abs(p[:, 2]) + 1e-15, theta_d / np.maximum(rho, 1e-300),
                         1.0 / np.where(np.abs(p[:, 2]) > 0, p[:, 2], 1.0))
        xd, yd = p[:, 0] * scale, p[:, 1] * scale
        u = self.K[0, 0] * xd + self.K[0, 1] * yd + self.K[0, 2]
        v = self.K[1, 1] * yd + self.K[1, 2]
        return np.stack([u, v], axis=1), valid

    def project_jacobian(self, points_cam: F64) -> F64:
        """d(u, v)/d(x, y, z) (N,2,3) px/m, analytic (through theta and the azimuth's unit vector)."""
        p, rho, theta, theta_d, d_theta_d, _ = self._distorted(points_cam)
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        rho = np.maximum(rho, 1e-9 * np.maximum(np.abs(z), 1e-12))
        r2 = rho * rho + z * z
        d_theta = np.stack([z * x / (rho * r2), z * y / (rho * r2), -rho / r2], axis=1)  # d theta / d p
        ex, ey = x / rho, y / rho
        rho3 = rho**3
        d_ex = np.stack([y * y / rho3, -x * y / rho3, np.zeros_like(x)], axis=1)
        d_ey = np.stack([-x * y / rho3, x * x / rho3, np.zeros_like(x)], axis=1)
        d_xd = (d_theta_d * ex)[:, None] * d_theta + theta_d[:, None] * d_ex
        d_yd = (d_theta_d * ey)[:, None] * d_theta + theta_d[:, None] * d_ey
        jac = np.empty((len(p), 2, 3))
        jac[:, 0, :] = self.K[0, 0] * d_xd + self.K[0, 1] * d_yd
        jac[:, 1, :] = self.K[1, 1] * d_yd
        return jac

    def _unit_rays(self, uv: F64, max_theta: float) -> F64:
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        yd = (uv[:, 1] - self.K[1, 2]) / self.K[1, 1]
        xd = (uv[:, 0] - self.K[0, 2] - self.K[0, 1] * yd) / self.K[0, 0]
        theta_d = np.hypot(xd, yd)
        theta = np.minimum(theta_d, max_theta)
        for _ in range(30):  # Newton on theta_d(theta) = r (increasing below max_theta)
            value, slope = self._theta_d(theta)
            theta = np.clip(theta - (value - theta_d) / np.maximum(slope, 1e-6), 0.0, max_theta)
        safe = np.maximum(theta_d, 1e-15)
        s = np.sin(theta)
        return np.stack([s * xd / safe, s * yd / safe, np.cos(theta)], axis=1)

    def back_project(self, uv: F64) -> F64:
        return self._unit_rays(uv, self._max_theta if self._max_theta > 0 else np.pi)

    def displacement(self, uv_pixels: F64, uv_centres: F64) -> F64:
        return np.asarray(uv_pixels, dtype=np.float64) - np.asarray(uv_centres, dtype=np.float64)

    def pixel_area_ratio(self, uv: F64) -> F64:
        """``S_x / S(uv)``: a pixel at angle theta covers the solid angle ``sin(theta) / (f^2 theta_d theta_d')``
        (rings of radius theta_d and width theta_d' d theta hold sin(theta) d theta d phi), the principal point's
        ``1 / f^2``, so the ratio is ``theta_d theta_d' / sin(theta)`` (1 on the axis)."""
        rays = self.back_project(uv)
        theta = np.arccos(np.clip(rays[:, 2], -1.0, 1.0))
        theta_d, d_theta_d = self._theta_d(theta)
        ratio = np.where(theta > 1e-6, theta_d * d_theta_d / np.maximum(np.sin(theta), 1e-12), 1.0)
        return np.asarray(np.clip(ratio, 0.2, 25.0), dtype=np.float64)


def project_rotated(camera: CameraModel, rotations: F64, translation_m: F64, points: F64) -> tuple[F64, Mask]:
    """``camera.project`` of ``points`` (N,3) m under each of ``rotations`` (K,3,3) with one ``translation_m``
    (3,): (K*N,2) px and (K*N,) valid, mount by mount. A head's sensor folds its own pose into each rotation
    first (one transform of the points, not two), and the rotations go through one batched matrix product."""
    if isinstance(camera, Mounted):
        rotations = np.einsum("ij,kjl->kil", camera.rotation, rotations)
        translation_m = camera.rotation @ translation_m + camera.translation_m
        camera_model: CameraModel = camera.sensor
    else:
        camera_model = camera
    p_cam = np.matmul(np.asarray(points, dtype=np.float64)[None], np.transpose(rotations, (0, 2, 1))) + translation_m
    return camera_model.project(p_cam.reshape(-1, 3))
