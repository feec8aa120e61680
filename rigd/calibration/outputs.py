"""The pictures of a calibration: per pair the LiDAR edge points over each image before and after, a close-up of
where they moved most, and the cloud coloured from the images (overlays/, clouds/)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from calib.elevation import raise_elevation
from calib.geometry import Transform
from calib.gmm import PairFeatures
from calib.pipeline import CalibParams
from calib.pipeline import edge_points as edge_points_of
from rigd.calibration.features import edge_threads, feature_at
from rigd.calibration.visuals import (
    CLOUD_STAGE,
    OVERLAY_STAGES,
    cloud_top_view,
    colour_points,
    edge_views,
    write_coloured_ply,
)
from rigd.dataset import Dataset


def overlay_stem(dataset: Dataset, pair: int, view: int) -> str:
    """The file stem of a pair's overlays: ``NNNN`` for one camera, ``NNNN_SENSOR`` for a head's sensor."""
    return f"{pair:04d}" if len(dataset.views) == 1 else f"{pair:04d}_{dataset.views[view]}"


def _write_pair_visuals(dataset: Dataset, i: int, edge_points: list[NDArray[np.float64]] | None, initial: Transform,
                        T: Transform, out: Path, elevation_deg: float = 0.0) -> None:
    """Pair ``i``'s pictures: per view, the edge points (N,3) m, LiDAR frame, of ``edge_points[view]`` (None:
    the GMM's own edge points of the cloud, for a photometric method) over the image with the initial guess and
    with the solution, the close-up of where they moved most (overlays/NNNN[_SENSOR]_{before,after,closeup}.png);
    and the cloud coloured from the pair's images with the solution (clouds/NNNN.ply, and from above:
    overlays/NNNN_cloud.png). ``elevation_deg``: the LiDAR's fitted elevation offset, every point raised by it."""
    cameras = dataset.rig.camera.models()
    pair = dataset.load_pair(i)
    if edge_points is None:
        points = edge_points_of(pair.cloud.points_lidar, pair.cloud.ring, CalibParams()).points_lidar
        edge_points = [points] * len(cameras)
    edge_points = [raise_elevation(p, elevation_deg) for p in edge_points]
    cloud_lidar = raise_elevation(pair.cloud.points_lidar, elevation_deg)
    for v, (image, camera, mask) in enumerate(zip(pair.images, cameras, dataset.masks, strict=True)):
        views = edge_views(image, camera, initial, T, edge_points[v], mask)
        for name in OVERLAY_STAGES:
            cv2.imwrite(str(out / "overlays" / f"{overlay_stem(dataset, i, v)}_{name}.png"), getattr(views, name))
    seen = list(zip(pair.images, cameras, dataset.masks, strict=True))
    coloured = colour_points(seen, T, cloud_lidar)
    write_coloured_ply(out / "clouds" / f"{i:04d}.ply", seen, T, cloud_lidar, coloured=coloured)
    top = cloud_top_view(seen, T, cloud_lidar, coloured=coloured)
    cv2.imwrite(str(out / "overlays" / f"{i:04d}_{CLOUD_STAGE}.png"), top)


def write_visuals(dataset: Dataset, feats: list[PairFeatures] | None, initial: Transform, T: Transform, out: Path,
                  workers: int = 1, elevation_deg: float = 0.0) -> None:
    """:func:`_write_pair_visuals` of every pair, side by side in ``workers`` threads."""
    (out / "overlays").mkdir(parents=True, exist_ok=True)
    (out / "clouds").mkdir(parents=True, exist_ok=True)
    views = range(len(dataset.views))
    tasks = [(dataset, i, None if feats is None else [feature_at(feats, dataset, i, v).points.points_lidar
                                                       for v in views], initial, T, out, elevation_deg)
             for i in range(len(dataset))]
    with edge_threads(workers, len(dataset)) as executor:
        if executor is None:
            for task in tasks:
                _write_pair_visuals(*task)
            return
        for future in [executor.submit(_write_pair_visuals, *task) for task in tasks]:
            future.result()


