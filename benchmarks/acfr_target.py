"""The chessboard (target-based) estimate of T_camera_lidar on the ACFR VLP-16 + fisheye frames, and how much a
candidate LiDAR error moves it: a benchmark that prints numbers, not a product path.

Run: .venv/bin/python benchmarks/acfr_target.py ../shared/data/acfr_vlp16 [--frames 1,3,5] [--range-bias-m -0.03]
         [--ring-elevation-offsets 0.1 | FILE] [--vertical-offsets] [--range-trend-m 0.005] [--edges] [--no-jackknife]

Per frame: the board's 5 x 7 inner corners (95 mm squares, cfg/params.yaml) found in the fisheye image
(cv2.findChessboardCorners, refined to sub-pixel), undistorted with cv2.fisheye and passed to solvePnP: the board's
pose in the camera, so its plane ``n . p = d`` in the camera frame. The board's LiDAR points are the authors' segment
``pcd/poseN_target.pcd`` (a plane is fitted to them for the closed-form start and the plane's rms). The estimate: the
6-DoF ``T_camera_lidar`` minimising the point-to-plane distances of every frame's board points to that frame's camera
plane (scipy least_squares, Huber loss at 2 cm, each frame weighted alike), started from the closed form (normals
aligned by Kabsch, then the offsets). ``--edges`` adds, per point, how far it lies outside the 610 x 850 mm board
(centred on the pattern), which pins the in-plane translation the planes leave to their tilts.

Printed: the result, its distance from the reference (the mean of calibration_quickstart.csv's rows within 2 std,
as rigd import pairs reads it): whole, and per axis as rotation about the LiDAR's x, y, z (deg) and translation of
the LiDAR's origin along the camera's and along the LiDAR's axes (cm), and as the CSV's own columns (the camera's
roll, pitch, yaw in the LiDAR frame, deg; x, y, z, cm); a jackknife over frames gives each axis' sigma.
Candidate causes, applied to the board points before the fit (rigd's conventions, docs/conventions.md):
``--range-bias-m B`` adds B to every range along its ray; ``--ring-elevation-offsets`` raises every point by an
elevation offset in deg, one value for every ring, or a file of 16 values (ring 0 first), range and azimuth kept;
``--vertical-offsets`` adds the VLP-16 manual's per-laser vertical offsets (the clouds were decoded without them,
rigd.dataset.lasers); ``--range-trend-m T`` adds a per-laser range offset running linearly from -T on the lowest
ring to +T on the highest (the part of the lasers' range offsets that tilts every board alike, so the boards cannot
measure it). With any of them, the shift from the uncorrected estimate is printed too.
"""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from calib.elevation import raise_elevation
from calib.geometry import Transform, rotation_angle_deg, so3_exp, so3_log
from calib.uncertainty import TO_DISPLAY, xi_of
from rigd.dataset import read_pcd
from rigd.dataset.lasers import with_vertical_offsets
from rigd.importers.camera_info import read_camera_info
from rigd.importers.reference_file import parse_convention, read_reference

F64 = NDArray[np.float64]
PATTERN = (5, 7)  # inner corners along the board's short and long side (cfg/params.yaml: width 5, height 7)
SQUARE_M = 0.095
BOARD_M = (0.610, 0.850)  # the board's short and long side, centred on the pattern
HUBER_M = 0.02  # VLP-16 range noise is ~2-3 cm: beyond it a residual counts linearly
REFERENCE_CONVENTION = "camera-in-lidar:rpy-rad-xyz"


@dataclass(frozen=True)
class Board:
    """One frame: the board in the camera (``R_cb``, ``t_cb``: board points to camera, m) with its plane's unit
    ``normal_cam`` (3,) and offset ``d_cam`` m (``normal . p = d``, d > 0), the corners' reprojection rms px, and
    the board's LiDAR points ``points_lidar`` (N,3) m."""

    frame: int
    R_cb: F64
    t_cb: F64
    normal_cam: F64
    d_cam: float
    reprojection_px: float
    points_lidar: F64


def detect_board(gray: NDArray[np.uint8], K: F64, D: F64) -> tuple[F64, F64, float] | None:
    """The board's pose in the camera (R (3,3), t (3,) m) from its corners in the fisheye image, and the corners'
    reprojection rms (px); None when the pattern is not found."""
    found, corners = cv2.findChessboardCorners(gray, PATTERN, flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                               | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria)
    grid = np.array([[x * SQUARE_M, y * SQUARE_M, 0.0] for y in range(PATTERN[1]) for x in range(PATTERN[0])])
    normalised = cv2.fisheye.undistortPoints(corners.reshape(-1, 1, 2).astype(np.float64), K, D)
    ok, rvec, tvec = cv2.solvePnP(grid, normalised, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(grid, normalised, np.eye(3), None, rvec, tvec)
    projected, _ = cv2.fisheye.projectPoints(grid.reshape(-1, 1, 3), rvec, tvec, K, D)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - corners.reshape(-1, 2)) ** 2, axis=1))))
    return np.asarray(cv2.Rodrigues(rvec)[0], np.float64), np.asarray(tvec, np.float64).reshape(3), rms


def plane(points: F64) -> tuple[F64, float, float]:
    """Least-squares plane of ``points`` (N,3): unit normal (facing away from the origin), offset d > 0 (m) and
    the points' rms distance from it (m)."""
    centroid = points.mean(axis=0)
    normal = np.linalg.svd(points - centroid)[2][2]
    if normal @ centroid < 0:
        normal = -normal
    return normal, float(normal @ centroid), float(np.sqrt(np.mean(((points - centroid) @ normal) ** 2)))


def ring_offsets(text: str | None) -> F64 | None:
    """``--ring-elevation-offsets``: one number (deg, every ring) or a file of one per ring, ring 0 first."""
    if text is None:
        return None
    if Path(text).is_file():
        return np.array([float(v) for v in re.split(r"[,\s]+", Path(text).read_text().strip())], np.float64)
    return np.array([float(text)], np.float64)


def corrected(points: F64, ring: NDArray[np.int16] | None, range_bias_m: float, offsets_deg: F64 | None,
              range_trend_m: float = 0.0) -> F64:
    """The board points with the candidate corrections: every range + ``range_bias_m`` (and the ring's share of
    ``range_trend_m``, -1 on ring 0 to +1 on ring 15) along its ray, then each ring raised by its elevation offset
    (deg; one value: every ring)."""
    bias = np.full(len(points), range_bias_m)
    if range_trend_m:
        if ring is None:
            raise SystemExit("--range-trend-m needs the clouds' ring field")
        bias = bias + range_trend_m * (ring.astype(np.float64) - 7.5) / 7.5
    out = np.asarray(points * (1.0 + bias / np.linalg.norm(points, axis=1))[:, None], np.float64)
    if offsets_deg is None:
        return out
    if len(offsets_deg) == 1:
        return np.asarray(raise_elevation(out, float(offsets_deg[0])), np.float64)
    if ring is None or ring.max() >= len(offsets_deg):
        raise SystemExit(f"--ring-elevation-offsets gives {len(offsets_deg)} rings; the clouds need a ring field "
                         "with that many")
    for r in np.unique(ring):
        out[ring == r] = raise_elevation(out[ring == r], float(offsets_deg[r]))
    return out


def load_boards(root: Path, frames: list[int], K: F64, D: F64, args: argparse.Namespace) -> list[Board]:
    boards = []
    offsets = ring_offsets(args.ring_elevation_offsets)
    for frame in frames:
        gray = cv2.imread(str(root / "images" / f"pose{frame}.png"), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            raise SystemExit(f"{root / 'images' / f'pose{frame}.png'}: missing or unreadable")
        pose = detect_board(np.asarray(gray, np.uint8), K, D)
        if pose is None:
            print(f"frame {frame}: chessboard not found, left out")
            continue
        R_cb, t_cb, rms = pose
        normal, d = R_cb[:, 2], float(R_cb[:, 2] @ t_cb)
        normal, d = (normal, d) if d > 0 else (-normal, -d)
        path = root / "pcd" / f"pose{frame}_target.pcd"
        cloud = with_vertical_offsets(read_pcd(path), str(path)) if args.vertical_offsets else read_pcd(path)
        points = corrected(cloud.points_lidar, cloud.ring, args.range_bias_m, offsets, args.range_trend_m)
        boards.append(Board(frame, R_cb, t_cb, normal, d, rms, points))
    return boards


def closed_form(boards: list[Board]) -> Transform:
    """The start: rotation aligning the LiDAR planes' normals with the camera's (Kabsch), then the translation
    from the planes' offsets (``n_cam . t = d_cam - d_lidar``)."""
    lidar = [plane(b.points_lidar) for b in boards]
    normals_lidar = np.array([n for n, _, _ in lidar])
    normals_cam = np.array([b.normal_cam for b in boards])
    u, _, vt = np.linalg.svd(normals_cam.T @ normals_lidar)
    R = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    t = np.linalg.lstsq(normals_cam, np.array([b.d_cam - d for b, (_, d, _) in zip(boards, lidar, strict=True)]),
                        rcond=None)[0]
    return Transform(R, t)


def residuals(tau: F64, boards: list[Board], edges: bool) -> F64:
    """Per board point: its distance from its frame's camera plane (m), and with ``edges`` how far outside the
    board it lies in the board's plane (m); each frame weighted alike whatever its point count."""
    R, t = so3_exp(tau[:3]), tau[3:]
    mean_count = np.mean([len(b.points_lidar) for b in boards])
    out = []
    for b in boards:
        points_cam = b.points_lidar @ R.T + t
        weight = np.sqrt(mean_count / len(b.points_lidar))
        out.append(weight * (points_cam @ b.normal_cam - b.d_cam))
        if edges:
            centre = np.array([(PATTERN[0] - 1) * SQUARE_M / 2, (PATTERN[1] - 1) * SQUARE_M / 2, 0.0])
            in_board = (points_cam - b.t_cb) @ b.R_cb - centre
            outside = np.maximum(np.abs(in_board[:, :2]) - np.array(BOARD_M) / 2, 0.0)
            out.append(weight * np.hypot(outside[:, 0], outside[:, 1]))
    return np.concatenate(out)


def estimate(boards: list[Board], edges: bool, start: Transform | None = None) -> Transform:
    start = start or closed_form(boards)
    x0 = np.concatenate([so3_log(start.rotation), start.translation_m])
    fit = least_squares(residuals, x0, args=(boards, edges), loss="huber", f_scale=HUBER_M, x_scale=0.01)
    return Transform(so3_exp(fit.x[:3]), fit.x[3:])


def local(T: Transform, around: Transform) -> F64:
    """(6,) ``T`` around ``around``: rotation about the LiDAR's x, y, z (deg), the LiDAR origin's shift in the
    camera frame (cm), rigd's local coordinates (docs/conventions.md)."""
    return np.asarray(xi_of(around.tau, T.tau) * TO_DISPLAY, dtype=np.float64)


def csv_form(T: Transform) -> F64:
    """(6,) the camera's pose in the LiDAR frame as the CSV writes it: roll, pitch, yaw (deg), x, y, z (cm)."""
    pose = T.inverse()
    return np.concatenate([pose.rpy_deg, pose.translation_m * 100.0])


def describe(T: Transform, reference: Transform, label: str) -> None:
    d = local(T, reference)
    lidar_axes = reference.rotation.T @ (T.translation_m - reference.translation_m) * 100.0
    print(f"{label}: T_camera_lidar rpy_deg {np.round(T.rpy_deg, 3).tolist()} xyz_m "
          f"{np.round(T.translation_m, 4).tolist()}")
    print(f"  from the reference: {rotation_angle_deg(reference.rotation, T.rotation):.3f} deg, "
          f"{np.linalg.norm(T.translation_m - reference.translation_m) * 100:.2f} cm")
    print(f"  about the LiDAR's x, y, z (deg): {fmt(d[:3], 3)}; along the camera's x, y, z (cm): {fmt(d[3:], 2)}; "
          f"along the LiDAR's x, y, z (cm): {fmt(lidar_axes, 2)}")
    print(f"  as the CSV's columns (camera in LiDAR; roll, pitch, yaw deg; x, y, z cm): "
          f"{fmt(csv_form(T) - csv_form(reference), 3)}")


def fmt(values: F64, digits: int) -> str:
    return " ".join(f"{v:+.{digits}f}" for v in values)


def jackknife(boards: list[Board], solution: Transform, edges: bool) -> F64:
    """(6,) the jackknife sigma over frames per axis of :func:`local` (deg, cm)."""
    leave_out = np.array([local(estimate(boards[:i] + boards[i + 1:], edges, solution), solution)
                          for i in range(len(boards))])
    n = len(boards)
    return np.asarray(np.sqrt((n - 1) / n * np.sum((leave_out - leave_out.mean(axis=0)) ** 2, axis=0)))


def frames_of(root: Path, text: str | None) -> list[int]:
    if text:
        return [int(v) for v in text.split(",")]
    found = {int(m.group(1)) for p in (root / "images").glob("pose*.png") if (m := re.match(r"pose(\d+)$", p.stem))}
    return sorted(n for n in found if (root / "pcd" / f"pose{n}_target.pcd").is_file())


def report_frames(boards: list[Board], solution: Transform) -> None:
    print("frame  corners_rms_px  board_m  points  plane_rms_cm  residual_rms_cm")
    for b in boards:
        _, _, plane_rms = plane(b.points_lidar)
        residual = solution.apply(b.points_lidar) @ b.normal_cam - b.d_cam
        print(f"{b.frame:5d}  {b.reprojection_px:14.2f}  {np.linalg.norm(b.t_cb):7.2f}  {len(b.points_lidar):6d}  "
              f"{plane_rms * 100:12.2f}  {np.sqrt(np.mean(residual ** 2)) * 100:15.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="the ACFR data folder (images/, pcd/, cfg/, the CSV)")
    parser.add_argument("--frames", default=None, help="frame numbers, e.g. 1,3,5 (default: every one found)")
    parser.add_argument("--range-bias-m", type=float, default=0.0, help="added to every range, m (e.g. -0.03)")
    parser.add_argument("--ring-elevation-offsets", default=None, metavar="DEG_OR_FILE",
                        help="raise every point by this elevation, deg, or by a file's per-ring values")
    parser.add_argument("--range-trend-m", type=float, default=0.0,
                        help="per-laser range offset from -T (lowest ring) to +T (highest), m (e.g. 0.005)")
    parser.add_argument("--vertical-offsets", action="store_true",
                        help="add the VLP-16 manual's per-laser vertical offsets to the board points")
    parser.add_argument("--edges", action="store_true", help="also keep the board points within the board")
    parser.add_argument("--no-jackknife", action="store_true")
    args = parser.parse_args()
    camera = read_camera_info(args.root / "cfg" / "camera_info.yaml")
    assert camera.K is not None and camera.D is not None
    reference = read_reference(args.root / "calibration_quickstart.csv", parse_convention(REFERENCE_CONVENTION))
    boards = load_boards(args.root, frames_of(args.root, args.frames), camera.K, camera.D, args)
    print(f"{len(boards)} frames; range bias {args.range_bias_m:+.3f} m; ring elevation offsets "
          f"{args.ring_elevation_offsets or 0} deg; range trend {args.range_trend_m:+.3f} m; vertical offsets "
          f"{'added' if args.vertical_offsets else 'none'}; edges {'on' if args.edges else 'off'}")
    solution = estimate(boards, args.edges)
    report_frames(boards, solution)
    describe(closed_form(boards), reference.T_camera_lidar, "closed form (start)")
    describe(solution, reference.T_camera_lidar, "target-based estimate")
    if args.range_bias_m or args.ring_elevation_offsets or args.vertical_offsets or args.range_trend_m:
        plain = argparse.Namespace(**{**vars(args), "range_bias_m": 0.0, "ring_elevation_offsets": None,
                                      "vertical_offsets": False, "range_trend_m": 0.0})
        base = estimate(load_boards(args.root, [b.frame for b in boards], camera.K, camera.D, plain), args.edges)
        shift = local(solution, base)
        print(f"  the corrections moved it by: about the LiDAR's x, y, z (deg) {fmt(shift[:3], 3)}; along the "
              f"camera's x, y, z (cm) {fmt(shift[3:], 2)}")
    if not args.no_jackknife:
        sigma = jackknife(boards, solution, args.edges)
        print(f"jackknife sigma over {len(boards)} frames: about the LiDAR's x, y, z (deg) {fmt(sigma[:3], 3)}; "
              f"along the camera's x, y, z (cm) {fmt(sigma[3:], 2)}")


if __name__ == "__main__":
    main()
