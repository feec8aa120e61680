"""Pictures people look at: LiDAR edge points over the image coloured by range (before and after a
calibration, and an enlarged close-up of where they moved most), and the point cloud coloured from the image
(as a file, and seen from above)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.camera import CameraModel, Mounted
from calib.geometry import Transform
from calib.gmm import in_image

DIM = 0.6  # the photo is darkened so that the dots stand out on bright walls
CLOSEUP_MIN_WIDTH_PX = 480  # each half of a close-up is enlarged to at least this width
DOT_ALPHA = 0.7  # dots are partly transparent: the image edge under a dot still shows through it
F64 = NDArray[np.float64]
OVERLAY_STAGES = ("before", "after", "closeup")  # the EdgeViews fields, and the overlay files' suffixes
CLOUD_STAGE = "cloud"  # overlays/NNNN_cloud.png: the cloud from above, coloured from the image
UNSEEN_BGR = (90, 90, 90)  # points the camera does not see


def project_visible(
    camera: CameraModel, T_camera_lidar: Transform, points_lidar: NDArray[np.float64],
    mask: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """(indices of points that land in the image, on a pixel ``mask`` (H,W) keeps if given, their uv (K,2) px,
    camera range (K,) m)."""
    p_cam = T_camera_lidar.apply(points_lidar)
    uv, valid = camera.project(p_cam)
    inside = np.flatnonzero(in_image(camera, uv, valid))
    if mask is not None:
        px = np.rint(uv[inside]).astype(np.intp)
        px = np.clip(px, 0, [mask.shape[1] - 1, mask.shape[0] - 1])
        inside = inside[mask[px[:, 1], px[:, 0]]]
    return inside, uv[inside], np.linalg.norm(p_cam[inside], axis=1)


def dot_radius_px(width: int, height: int) -> int:
    """Dots about 1/600 of the larger image side: 1 px up to 900 px, 2 px at 1024, 3 px on a 1920-wide pinhole's
    or a 2048-wide panorama's (at 1/1000 they were all but lost at full size and in screen copies)."""
    return max(1, round(max(width, height) / 600))


def dot_gap_px(radius_px: int) -> int:
    """The spacing kept between dots of ``radius_px`` (:func:`thin`): a dot and its rim take 2 r + 3 px, and about
    as much of the image stays visible between two dots, so the edge they sit on can be judged."""
    return 2 * radius_px + 5


def thin(uv: F64, priority: NDArray[np.intp], gap_px: float) -> NDArray[np.intp]:
    """Indices of the points ``uv`` (N,2) px kept so that dots do not cover the image: taken in ``priority`` order
    (indices into ``uv``), a point is dropped when one taken before it lies in the same ``gap_px`` square, on two
    grids half a square apart (so two kept points are rarely closer than ``gap_px / 2``)."""
    kept = np.asarray(priority, dtype=np.intp)
    for offset in (0.0, gap_px / 2):
        cells = np.floor((uv[kept] + offset) / gap_px).astype(np.int64)
        if len(cells) == 0:
            break
        _, first = np.unique(cells, axis=0, return_index=True)
        kept = kept[np.sort(first)]  # np.unique's first occurrences, back in priority order
    return kept


def range_scale_m(ranges_m: NDArray[np.float64]) -> float:
    """The range shown as the last turbo colour: the 95th percentile, so one far wall does not make every
    nearer point the same blue (at least 1 m)."""
    return max(1.0, float(np.percentile(ranges_m, 95))) if len(ranges_m) else 1.0


def turbo_bgr(ranges_m: NDArray[np.float64], max_range_m: float) -> NDArray[np.uint8]:
    """(N,3) uint8 BGR turbo colours of ``ranges_m`` (N,) m: near blue, far red."""
    if not len(ranges_m):  # cv2.applyColorMap returns None for an empty image
        return np.zeros((0, 3), np.uint8)
    levels = np.clip(ranges_m / max_range_m * 255.0, 0, 255).astype(np.uint8)
    return cast(NDArray[np.uint8], cv2.applyColorMap(levels.reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(-1, 3))


def _dimmed_bgr(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    canvas = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return (canvas * DIM).astype(np.uint8)


def draw_dots(canvas: NDArray[np.uint8], uv: F64, colours_bgr: NDArray[np.uint8],
              radius_px: int) -> NDArray[np.uint8]:
    """Dots of ``radius_px`` at ``uv`` (N,2) px with a dark rim (visible on light and dark pixels), blended with
    the image at DOT_ALPHA. All rims go first, so close dots keep their colour; give far points first so that
    near ones, which occlude them in the scene, stay on top. Returns ``canvas``, drawn on."""
    layer = canvas.copy()
    centres = [(int(u), int(v)) for u, v in np.rint(uv).astype(int)]
    for centre in centres:
        cv2.circle(layer, centre, radius_px + 1, (0, 0, 0), -1, cv2.LINE_AA)
    for centre, colour in zip(centres, colours_bgr, strict=True):
        cv2.circle(layer, centre, radius_px, tuple(int(c) for c in colour), -1, cv2.LINE_AA)
    # Pixels without a dot are the same in both, so the blend changes only the dots.
    cv2.addWeighted(layer, DOT_ALPHA, canvas, 1.0 - DOT_ALPHA, 0.0, dst=canvas)
    for centre, colour in zip(centres, colours_bgr, strict=True):  # an opaque core: the colour survives a copy
        cv2.circle(canvas, centre, radius_px - 1, tuple(int(c) for c in colour), -1, cv2.LINE_AA)
    return canvas


@dataclass(frozen=True)
class Upright:
    """How a camera's image is shown to people: its rows or columns stretched to square pixels (``scale`` (2,):
    shown px per image px along u and v), then turned by ``turns`` quarter turns clockwise so that up is up. Maps
    the image (H, W) and pixel coordinates uv (N,2) px alike."""

    width: int
    height: int
    scale: tuple[float, float]
    turns: int

    @classmethod
    def of(cls, camera: CameraModel) -> Upright:
        """A head's sensor turned so that the head's up (+z) is the image's top (a Ladybug's sensors lie on their
        side), by the multiple of 90 deg nearest to it, and stretched where its pixels are not square (the Ford
        head's fy = fx / 2); any other camera as it is."""
        if not isinstance(camera, Mounted):
            return cls(camera.width, camera.height, (1.0, 1.0), 0)
        k = camera.sensor.K
        fx, fy = float(k[0, 0]), float(k[1, 1])
        width, height = camera.width, camera.height
        shown = (max(1, round(width * max(1.0, fy / fx))), max(1, round(height * max(1.0, fx / fy))))
        # The head's +z in the sensor's optical frame (x right, y down): its direction in the image as shown, where
        # the pixels are square.
        up_x, up_y, _ = camera.rotation[:, 2]
        if np.hypot(up_x, up_y) < 0.5:  # looking (nearly) straight up or down: no up in the image
            turns = 0
        elif abs(up_x) > abs(up_y):
            turns = 1 if up_x < 0 else 3  # up towards column 0: a quarter turn clockwise brings it to the top
        else:
            turns = 0 if up_y < 0 else 2
        return cls(width, height, (shown[0] / width, shown[1] / height), turns)

    @property
    def stretched(self) -> tuple[int, int]:
        return round(self.width * self.scale[0]), round(self.height * self.scale[1])

    def image(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """``image`` (H, W[, 3]) as shown."""
        out = image
        if self.stretched != (self.width, self.height):
            out = cast(NDArray[np.uint8], cv2.resize(out, self.stretched, interpolation=cv2.INTER_LINEAR))
        if self.turns:
            codes = {1: cv2.ROTATE_90_CLOCKWISE, 2: cv2.ROTATE_180, 3: cv2.ROTATE_90_COUNTERCLOCKWISE}
            out = cast(NDArray[np.uint8], cv2.rotate(out, codes[self.turns]))
        return out

    def points(self, uv: F64) -> F64:
        """Pixel coordinates uv (N,2) px (centres at integers) as shown."""
        edge = (np.asarray(uv, dtype=np.float64) + 0.5) * self.scale  # pixel-edge coordinates, stretched
        w, h = self.stretched
        x, y = edge[:, 0], edge[:, 1]
        turned = {0: (x, y), 1: (h - y, x), 2: (w - x, h - y), 3: (y, w - x)}[self.turns]
        return np.stack(turned, axis=1) - 0.5

    def box(self, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """A box (u0, v0, width, height) px of the image as shown."""
        u0, v0, bw, bh = box
        corners = self.points(np.array([[u0 - 0.5, v0 - 0.5], [u0 + bw - 0.5, v0 + bh - 0.5]])) + 0.5
        lo, hi = np.rint(corners.min(axis=0)).astype(int), np.rint(corners.max(axis=0)).astype(int)
        return int(lo[0]), int(lo[1]), int(hi[0] - lo[0]), int(hi[1] - lo[1])


@dataclass(frozen=True)
class EdgeViews:
    """Overlays of one pair's edge points: ``before`` (initial guess) and ``after`` (solution) at the image's
    full resolution, and ``closeup``: before | after of the region where the points moved most, enlarged."""

    before: NDArray[np.uint8]
    after: NDArray[np.uint8]
    closeup: NDArray[np.uint8]


def edge_views(image: NDArray[np.uint8], camera: CameraModel, before: Transform, after: Transform,
               edge_points_lidar: NDArray[np.float64], mask: NDArray[np.bool_] | None = None) -> EdgeViews:
    """The edge points (N,3) m, LiDAR frame, drawn as range-coloured dots with each transform, on the image shown
    upright (:class:`Upright`), none on pixels ``mask`` (H,W) leaves out (the rig, a sensor's dark border). The
    dots are thinned so that the image's edges stay visible between them, the same points in both (a point seen
    with the solution is kept or dropped in both), so one sees each dot move."""
    idx_b, uv_b, rng_b = project_visible(camera, before, edge_points_lidar, mask)
    idx_a, uv_a, rng_a = project_visible(camera, after, edge_points_lidar, mask)
    box = largest_change_box(camera, idx_b, uv_b, idx_a, uv_a)  # found in the image's own pixels
    upright = Upright.of(camera)
    base = _dimmed_bgr(upright.image(image))
    shown_b, shown_a = upright.points(uv_b), upright.points(uv_a)
    scale = range_scale_m(rng_a)
    radius = dot_radius_px(base.shape[1], base.shape[0])
    keep = _kept(idx_b, shown_b, rng_b, idx_a, shown_a, rng_a, dot_gap_px(radius))
    views = {}
    for name, idx, uv, rng in (("before", idx_b, shown_b, rng_b), ("after", idx_a, shown_a, rng_a)):
        drawn = np.isin(idx, keep)
        order = np.argsort(-rng[drawn])
        views[name] = draw_dots(base.copy(), uv[drawn][order], turbo_bgr(rng[drawn][order], scale), radius)
    u0, v0, bw, bh = upright.box(box)
    factor = max(2, -(-CLOSEUP_MIN_WIDTH_PX // bw))
    closeup_radius = max(2, radius * factor // 2)
    # Thinned again at the close-up's scale: points that merged into one dot in the whole view are apart here.
    inside = [_inside(uv, (u0, v0, bw, bh)) for uv in (shown_b, shown_a)]
    keep_close = _kept(idx_b[inside[0]], shown_b[inside[0]] * factor, rng_b[inside[0]], idx_a[inside[1]],
                       shown_a[inside[1]] * factor, rng_a[inside[1]], dot_gap_px(closeup_radius))
    halves = [_closeup(base, (u0, v0, bw, bh), factor, uv[np.isin(idx, keep_close)], rng[np.isin(idx, keep_close)],
                       scale, closeup_radius, label)
              for label, idx, uv, rng in (("before", idx_b, shown_b, rng_b), ("after", idx_a, shown_a, rng_a))]
    gap = np.full((halves[0].shape[0], max(4, halves[0].shape[1] // 100), 3), 255, np.uint8)
    return EdgeViews(views["before"], views["after"], np.hstack([halves[0], gap, halves[1]]))


def _kept(idx_before: NDArray[np.intp], uv_before: F64, rng_before: F64, idx_after: NDArray[np.intp],
          uv_after: F64, rng_after: F64, gap_px: float) -> NDArray[np.intp]:
    """Point indices to draw: those seen with the solution thinned where they land with it (nearest first: they
    occlude), and those seen only with the initial guess thinned where they land with it."""
    kept_after = idx_after[thin(uv_after, np.argsort(rng_after, kind="stable"), gap_px)]
    only_before = np.flatnonzero(~np.isin(idx_before, idx_after))
    order = only_before[np.argsort(rng_before[only_before], kind="stable")]
    kept_before = idx_before[thin(uv_before, order, gap_px)]
    return np.union1d(kept_after, kept_before)


def _inside(uv: F64, box: tuple[int, int, int, int]) -> NDArray[np.bool_]:
    u0, v0, bw, bh = box
    return (uv[:, 0] >= u0 - 0.5) & (uv[:, 0] < u0 + bw - 0.5) & (uv[:, 1] >= v0 - 0.5) & (uv[:, 1] < v0 + bh - 0.5)


def largest_change_box(camera: CameraModel, idx_before: NDArray[np.intp], uv_before: NDArray[np.float64],
                       idx_after: NDArray[np.intp], uv_after: NDArray[np.float64]) -> tuple[int, int, int, int]:
    """(u0, v0, width, height) px of the window (a sixth of the width, a third of the height, at least
    32 px, inside the image) holding the largest summed image-space displacement of the points seen both
    before and after; the image's centre window when none is."""
    w, h = camera.width, camera.height
    bw, bh = min(w, max(32, w // 6)), min(h, max(32, h // 3))
    common, ib, ia = np.intersect1d(idx_before, idx_after, return_indices=True)
    if len(common) == 0:
        return (w - bw) // 2, (h - bh) // 2, bw, bh
    moved = np.linalg.norm(camera.displacement(uv_after[ia], uv_before[ib]), axis=1)
    # Each point's displacement at its mid position, summed over every window by a box filter.
    mid = np.clip(np.rint((uv_after[ia] + uv_before[ib]) / 2), 0, [w - 1, h - 1]).astype(int)
    heat = np.zeros((h, w), np.float64)
    np.add.at(heat, (mid[:, 1], mid[:, 0]), moved)
    summed = cv2.boxFilter(heat, -1, (bw, bh), normalize=False, borderType=cv2.BORDER_CONSTANT)
    cv, cu = np.unravel_index(int(np.argmax(summed)), summed.shape)
    # Many windows hold the same points (argmax takes the first): centre the best one on what moved in it.
    inside = (np.abs(mid[:, 0] - cu) <= bw // 2) & (np.abs(mid[:, 1] - cv) <= bh // 2)
    if moved[inside].sum() > 0:
        cu, cv = np.average(mid[inside], axis=0, weights=moved[inside])
    u0 = int(np.clip(round(cu) - bw // 2, 0, w - bw))
    v0 = int(np.clip(round(cv) - bh // 2, 0, h - bh))
    return u0, v0, bw, bh


def _closeup(base: NDArray[np.uint8], box: tuple[int, int, int, int], factor: int, uv: F64, rng: F64,
             scale_m: float, radius_px: int, label: str) -> NDArray[np.uint8]:
    """The box of ``base`` enlarged ``factor`` times with the dots at ``uv`` (N,2) px of ``base`` drawn at the
    enlarged scale (sharp, not blown-up pixels) and ``label`` in a corner."""
    u0, v0, bw, bh = box
    crop = cast(NDArray[np.uint8], cv2.resize(base[v0:v0 + bh, u0:u0 + bw], (bw * factor, bh * factor),
                                              interpolation=cv2.INTER_CUBIC))
    inside = _inside(uv, box)
    local = (uv[inside] - [u0, v0] + 0.5) * factor
    order = np.argsort(-rng[inside])
    draw_dots(crop, local[order], turbo_bgr(rng[inside][order], scale_m), radius_px)
    height = crop.shape[0]
    font_scale = max(0.5, height / 400)
    cv2.putText(crop, label, (8, 8 + int(22 * font_scale)), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (0, 0, 0),
                max(3, int(4 * font_scale)), cv2.LINE_AA)
    cv2.putText(crop, label, (8, 8 + int(22 * font_scale)), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (255, 255, 255),
                max(1, int(2 * font_scale)), cv2.LINE_AA)
    return crop


# An image, the camera that took it, and its mask ((H,W) bool, True where it shows the scene; None: all of it).
View = tuple[NDArray[np.uint8], CameraModel, NDArray[np.bool_] | None]


def colour_points(views: list[View], T_camera_lidar: Transform,
                  points_lidar: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.uint8]]:
    """(indices of the points (N,3) m that some view sees, their BGR (K,3) uint8): each point in the colour of
    the pixel it projects to in the first view that sees it there (a head's sensors overlap at their edges; a
    masked pixel shows the rig, not the point)."""
    colours = np.zeros((len(points_lidar), 3), np.uint8)
    seen = np.zeros(len(points_lidar), bool)
    for image, camera, mask in views:
        idx, uv, _ = project_visible(camera, T_camera_lidar, points_lidar)
        photo = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        px = np.clip(np.rint(uv).astype(np.int64), 0, [photo.shape[1] - 1, photo.shape[0] - 1])
        fresh = ~seen[idx] & (True if mask is None else mask[px[:, 1], px[:, 0]])
        colours[idx[fresh]] = photo[px[fresh, 1], px[fresh, 0]]
        seen[idx[fresh]] = True
    idx_seen = np.flatnonzero(seen)
    return idx_seen, colours[idx_seen]


Coloured = tuple[NDArray[np.intp], NDArray[np.uint8]]  # colour_points' result


def write_coloured_ply(path: Path, views: list[View], T_camera_lidar: Transform,
                       points_lidar: NDArray[np.float64], *, coloured: Coloured | None = None) -> int:
    """Binary little-endian PLY of the points that see an image, coloured from it (paper Fig. 15).
    ``coloured``: :func:`colour_points` of these arguments if already made (projecting a 64-ring cloud into
    every sensor of a head is most of the work)."""
    idx, bgr = colour_points(views, T_camera_lidar, points_lidar) if coloured is None else coloured
    rec = np.zeros(len(idx), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                                    ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    pts = points_lidar[idx]
    rec["x"], rec["y"], rec["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    rec["red"], rec["green"], rec["blue"] = bgr[:, 2], bgr[:, 1], bgr[:, 0]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(rec)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    with Path(path).open("wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(rec.tobytes())
    return len(rec)


def cloud_top_view(views: list[View], T_camera_lidar: Transform, points_lidar: NDArray[np.float64],
                   size_px: int = 900, *, coloured: Coloured | None = None) -> NDArray[np.uint8]:
    """(size_px, size_px, 3) uint8 BGR: the cloud (N,3) m, LiDAR frame, seen from above (x forward up the
    picture, y left to the left), each point in the colour of the pixel it projects to with
    ``T_camera_lidar`` (:func:`colour_points`), grey where no camera sees it. With wrong extrinsics the colours of walls
    and cars spill onto the ground beside them: the check people make in a coloured cloud.

    The square spans the 95th percentile of the horizontal range (at least 2 m) around the LiDAR; higher
    points are drawn last (they are what one sees from above). 1-m grid lines every 5 m, the LiDAR at the
    centre as a white cross. ``coloured``: as :func:`write_coloured_ply`'s."""
    canvas = np.full((size_px, size_px, 3), 24, np.uint8)
    horizontal = np.linalg.norm(points_lidar[:, :2], axis=1) if len(points_lidar) else np.zeros(0)
    extent_m = max(2.0, float(np.percentile(horizontal, 95))) if len(horizontal) else 2.0
    px_per_m = (size_px / 2 - 4) / extent_m
    centre = size_px / 2
    _grid(canvas, extent_m, px_per_m)
    colours = np.empty((len(points_lidar), 3), np.uint8)
    colours[:] = UNSEEN_BGR
    idx, bgr = colour_points(views, T_camera_lidar, points_lidar) if coloured is None else coloured
    colours[idx] = bgr
    col = np.rint(centre - points_lidar[:, 1] * px_per_m).astype(np.int64)  # y left -> picture left
    row = np.rint(centre - points_lidar[:, 0] * px_per_m).astype(np.int64)  # x forward -> picture up
    order = np.argsort(points_lidar[:, 2], kind="stable")
    dot = max(1, size_px // 450)
    for dr in range(dot):
        for dc in range(dot):
            r, c = row[order] + dr, col[order] + dc
            keep = (r >= 0) & (r < size_px) & (c >= 0) & (c < size_px)
            canvas[r[keep], c[keep]] = colours[order][keep]  # later (higher) points overwrite lower ones
    arm = max(4, size_px // 60)
    cv2.line(canvas, (int(centre) - arm, int(centre)), (int(centre) + arm, int(centre)), (255, 255, 255), 1)
    cv2.line(canvas, (int(centre), int(centre) - arm), (int(centre), int(centre) + arm), (255, 255, 255), 1)
    return canvas


def _grid(canvas: NDArray[np.uint8], extent_m: float, px_per_m: float) -> None:
    """Lines every 5 m (every 1 m when the view spans less than 10 m) and the spacing written in a corner."""
    step_m = 5.0 if extent_m >= 5.0 else 1.0
    size = canvas.shape[0]
    centre = size / 2
    k = int(extent_m // step_m) + 1
    for i in range(-k, k + 1):
        at = int(round(centre + i * step_m * px_per_m))
        if 0 <= at < size:
            cv2.line(canvas, (at, 0), (at, size - 1), (48, 48, 48), 1)
            cv2.line(canvas, (0, at), (size - 1, at), (48, 48, 48), 1)
    cv2.putText(canvas, f"from above, x forward up; grid {step_m:g} m; grey: not in the image", (8, size - 10),
                cv2.FONT_HERSHEY_SIMPLEX, max(0.4, size / 2000), (200, 200, 200), 1, cv2.LINE_AA)
