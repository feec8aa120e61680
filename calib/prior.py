"""A Gaussian prior on ``T_camera_lidar`` from the rig's drawing: the MAP term added to the GMM cost.

Most rigs know the lever arm to about a centimetre from CAD and the rotation only roughly. The prior is a
Gaussian per axis, in the same local coordinates as the reported uncertainty (docs/conventions.md):
rotation residual ``r = log(R_prior^T R)`` (rad, about the LiDAR's x, y, z axes: roll, pitch, yaw) and
translation residual ``t - t_prior`` (m, camera frame). Its negative log-likelihood is
``0.5 * sum((r / sigma)^2)``; the optimiser adds it times the GMM cost's own scale (see
:func:`calib.uncertainty.nll_scale`), so the prior weighs against the images as a likelihood would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from calib.errors import CalibError
from calib.geometry import left_jacobian, so3_exp, so3_log

F64 = NDArray[np.float64]


def _positive3(values: F64 | None, name: str) -> F64 | None:
    if values is None:
        return None
    v = np.broadcast_to(np.asarray(values, dtype=np.float64), (3,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise CalibError(f"prior {name} must be positive and finite, got {v.tolist()}")
    return v


@dataclass(frozen=True)
class Prior:
    """``xyz_m`` (3,) m and ``sigma_xyz_m`` (3,) m: the lever arm (``t`` of T_camera_lidar) and its sigma;
    ``rotation`` (3,3) and ``sigma_rot_rad`` (3,) rad about the LiDAR axes; either part may be None.
    ``fix_translation``: translation held at ``xyz_m`` (or at the initial guess if None), not estimated."""

    xyz_m: F64 | None = None
    sigma_xyz_m: F64 | None = None
    rotation: F64 | None = None
    sigma_rot_rad: F64 | None = None
    fix_translation: bool = False

    def __post_init__(self) -> None:
        if (self.xyz_m is None) != (self.sigma_xyz_m is None) and not self.fix_translation:
            raise CalibError("a translation prior needs both xyz_m and its sigma")
        if (self.rotation is None) != (self.sigma_rot_rad is None):
            raise CalibError("a rotation prior needs both the rotation and its sigma")
        if self.xyz_m is not None:
            xyz = np.asarray(self.xyz_m, dtype=np.float64).reshape(-1)
            if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
                raise CalibError(f"prior xyz_m must be 3 finite numbers, got {xyz.tolist()}")
            object.__setattr__(self, "xyz_m", xyz)
        object.__setattr__(self, "sigma_xyz_m", _positive3(self.sigma_xyz_m, "sigma_xyz_m"))
        object.__setattr__(self, "sigma_rot_rad", _positive3(self.sigma_rot_rad, "sigma_rot_rad"))

    @property
    def active(self) -> bool:
        return self.sigma_xyz_m is not None or self.sigma_rot_rad is not None

    def information(self) -> F64:
        """(6,6) inverse prior covariance in the local coordinates [rotation rad, translation m]; zero where
        an axis has no prior."""
        diag = np.zeros(6)
        if self.sigma_rot_rad is not None:
            diag[:3] = 1.0 / self.sigma_rot_rad**2
        if self.sigma_xyz_m is not None and not self.fix_translation:
            diag[3:] = 1.0 / self.sigma_xyz_m**2
        return np.diag(diag)

    def nll_and_gradient(self, tau: F64) -> tuple[float, F64]:
        """0.5 * sum((residual / sigma)^2) and its gradient (6,) with respect to ``tau = [omega, t]``."""
        nll = 0.0
        grad = np.zeros(6)
        if self.sigma_xyz_m is not None and self.xyz_m is not None and not self.fix_translation:
            z = (tau[3:] - self.xyz_m) / self.sigma_xyz_m
            nll += 0.5 * float(z @ z)
            grad[3:] = z / self.sigma_xyz_m
        if self.sigma_rot_rad is not None and self.rotation is not None:
            r = so3_log(self.rotation.T @ so3_exp(tau[:3]))
            z = r / self.sigma_rot_rad
            nll += 0.5 * float(z @ z)
            # d r / d omega = J_r(r)^-1 J_r(omega), with the right Jacobian J_r(a) = J_l(-a).
            dr = np.linalg.solve(left_jacobian(-r), left_jacobian(-tau[:3]))
            grad[:3] = (z / self.sigma_rot_rad) @ dr
        return nll, grad

    def distance(self, tau: F64) -> tuple[float | None, float | None]:
        """How far the pose ``tau`` lies from the prior's values, in its sigmas: the largest rotation axis's and
        the largest translation axis's (None for a part the prior does not give, or a held translation)."""
        rot = trans = None
        if self.sigma_rot_rad is not None and self.rotation is not None:
            rot = float(np.max(np.abs(so3_log(self.rotation.T @ so3_exp(tau[:3])) / self.sigma_rot_rad)))
        if self.sigma_xyz_m is not None and self.xyz_m is not None and not self.fix_translation:
            trans = float(np.max(np.abs((tau[3:] - self.xyz_m) / self.sigma_xyz_m)))
        return rot, trans
