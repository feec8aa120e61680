"""``rigd import pairs``: a folder of images and a folder of PCD clouds as a rigd dataset.

What users of other tools have: ``images/pose1.png`` beside ``pcd/pose1_full.pcd``, a ROS ``camera_info`` YAML,
maybe a published calibration. Files pair by the number in their names (the last run of digits of the name
without its suffix: ``pose1.png`` and ``pose1_full.pcd`` are both 1) or, asked for, by their sorted order
(names compared number-aware, so ``frame2`` comes before ``frame10``). A number two files share, or a file
without a partner, is an error that names them: nothing is paired by guess.

Written: rig.yaml (the camera of the camera_info file, rigd.importers.camera_info), the pairs (image bytes as
they are; the clouds' x y z, intensity and ring as read, rings checked to run from the lowest beam up; a VLP-16's
clouds decoded without its per-laser vertical offsets get them on load, rig.yaml ``lidar.vertical_offsets``), and
with a reference file reference.yaml (rigd.importers.reference_file).
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from calib.geometry import Transform
from rigd.dataset.lasers import VLP16, VerticalOffsets, lacks_vertical_offsets
from rigd.dataset.pcd import Cloud, read_pcd
from rigd.dataset.records import CameraConfig, RigConfig
from rigd.dataset.reference import Reference
from rigd.dataset.store import read_image, read_mask, write_pair, write_rig, write_yaml
from rigd.errors import DatasetError
from rigd.importers.camera_info import read_camera_info

IMAGE_GLOBS = ("*.png", "*.jpg", "*.jpeg")
MASK_FILE = "masks/camera.png"
SHOWN = 8  # names listed in an error about unmatched files


@dataclass(frozen=True)
class PairsSource:
    """Where the pairs come from: ``images`` and ``clouds`` folders (may be one), the files taken from each
    (``image_globs``, ``cloud_glob``), and whether they pair by sorted order instead of the number in their names."""

    images: Path
    clouds: Path
    image_globs: tuple[str, ...] = IMAGE_GLOBS
    cloud_glob: str = "*.pcd"
    by_order: bool = False


@dataclass(frozen=True)
class PairsOptions:
    """What to write beside the pairs: the ``camera_info`` file, the LiDAR's model name, an initial guess of
    ``T_camera_lidar``, a ``reference``, a ``mask`` image file (non-zero where the image shows the scene), and
    whether a VLP-16's per-laser vertical offsets are added on load (None: when every cloud lacks them,
    rigd.dataset.lasers)."""

    camera_info: Path
    lidar_model: str = VLP16
    initial_guess: Transform | None = None
    reference: Reference | None = None
    mask: Path | None = None
    vertical_offsets: VerticalOffsets | None = None


def name_key(path: Path) -> int | None:
    """The number a file pairs by: the last run of digits in its name without the suffix (None: it has none)."""
    digits = re.findall(r"\d+", path.stem)
    return int(digits[-1]) if digits else None


def _natural(path: Path) -> list[int | str]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]


def _listed(folder: Path, globs: Sequence[str], what: str) -> list[Path]:
    if not folder.is_dir():
        raise DatasetError(f"{folder}: {what} folder does not exist")
    files = sorted({p for glob in globs for p in folder.glob(glob) if p.is_file()}, key=_natural)
    if not files:
        raise DatasetError(f"{folder}: no {what} matching {' or '.join(globs)}")
    return files


def _keyed(files: list[Path], by_order: bool, what: str) -> dict[int, Path]:
    """Each file under its key (its position with ``by_order``); DatasetError naming a file without a number or
    two files under one."""
    if by_order:
        return dict(enumerate(files))
    out: dict[int, Path] = {}
    for path in files:
        key = name_key(path)
        if key is None:
            raise DatasetError(f"{path}: the {what} name has no number to pair by (pair by order instead)")
        if key in out:
            raise DatasetError(f"{out[key]} and {path}: two {what}s numbered {key} (narrow the files taken with a "
                               f"pattern, e.g. --cloud-glob '*_full.pcd')")
        out[key] = path
    return out


def _names(paths: list[Path]) -> str:
    shown = ", ".join(p.name for p in paths[:SHOWN])
    return shown + (f" and {len(paths) - SHOWN} more" if len(paths) > SHOWN else "")


def match_pairs(source: PairsSource, only: Sequence[int] | None = None) -> list[tuple[int, Path, Path]]:
    """``(key, image, cloud)`` of every pair (or of the keys ``only``, in that order); DatasetError listing the
    files without a partner, or the keys asked for that no file has."""
    images = _keyed(_listed(source.images, source.image_globs, "image"), source.by_order, "image")
    clouds = _keyed(_listed(source.clouds, (source.cloud_glob,), "cloud"), source.by_order, "cloud")
    if only is not None:
        absent = [k for k in only if k not in images or k not in clouds]
        if absent:
            raise DatasetError(f"{source.images} / {source.clouds}: no image and cloud numbered "
                               f"{', '.join(map(str, absent))} (images have {_span(images)}, clouds {_span(clouds)})")
        return [(k, images[k], clouds[k]) for k in only]
    lonely = [images[k] for k in images.keys() - clouds.keys()] + [clouds[k] for k in clouds.keys() - images.keys()]
    if lonely:
        how = "in sorted order: the folders hold different counts" if source.by_order else "by the numbers in names"
        raise DatasetError(f"{source.images} / {source.clouds}: {len(lonely)} files without a partner ({how}): "
                           f"{_names(sorted(lonely, key=_natural))}")
    return [(k, images[k], clouds[k]) for k in sorted(images)]


def _span(keyed: dict[int, Path]) -> str:
    keys = sorted(keyed)
    return ", ".join(map(str, keys)) if len(keys) <= SHOWN else f"{len(keys)} numbers from {keys[0]} to {keys[-1]}"


def check_rings(cloud: Cloud, where: Path) -> Cloud:
    """The cloud, once its rings are known to be numbered lowest beam first (rigd's numbering, and the Velodyne ROS
    driver's); DatasetError naming the file when ring 0 lies above the highest-numbered ring (a LiDAR that numbers
    from the top) or the cloud holds no point."""
    if len(cloud) == 0:
        raise DatasetError(f"{where}: cloud holds no finite point")
    if cloud.ring is None or cloud.ring.min() == cloud.ring.max():
        return cloud
    elevation = cloud.points_lidar[:, 2] / np.hypot(cloud.points_lidar[:, 0], cloud.points_lidar[:, 1])
    low, high = (float(np.median(elevation[cloud.ring == r])) for r in (cloud.ring.min(), cloud.ring.max()))
    if low > high:
        raise DatasetError(f"{where}: its rings are numbered from the top beam down; rigd numbers them from the "
                           "lowest beam up (docs/dataset.md)")
    return cloud


def _write_rig(out: Path, camera: CameraConfig, options: PairsOptions) -> None:
    """rig.yaml (with the mask copied into the dataset) and reference.yaml."""
    if options.mask is not None:
        read_mask(options.mask, (camera.height, camera.width))  # its size and content checked before copying
        (out / "masks").mkdir(parents=True, exist_ok=True)
        shutil.copyfile(options.mask, out / MASK_FILE)
        camera = replace(camera, mask=MASK_FILE)
    write_rig(out, RigConfig(camera, options.lidar_model, options.initial_guess,
                             lidar_vertical_offsets=options.vertical_offsets or VerticalOffsets.AS_RECORDED))
    if options.reference is not None:
        write_yaml(out / "reference.yaml", options.reference.to_yaml())


def import_pairs(source: PairsSource, out: Path, options: PairsOptions, only: Sequence[int] | None = None,
                 progress: Callable[[int, int], None] | None = None) -> int:
    """Write the dataset ``out`` from ``source``'s image/cloud pairs (every one, or the keys ``only``); returns
    the number of pairs. Every file is checked before the first pair is written."""
    out = Path(out)
    chosen = match_pairs(source, only)
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out}: exists and is not empty; give a new folder")
    camera = read_camera_info(options.camera_info)
    for _, image_path, _ in chosen:
        _check_image(image_path, camera.width, camera.height, options.camera_info)
    _write_rig(out, camera, replace(options, vertical_offsets=_vertical_offsets(options, chosen)))
    for index, (key, image_path, cloud_path) in enumerate(chosen):
        cloud = check_rings(read_pcd(cloud_path), cloud_path)
        meta = {"source": "pairs", "key": key, "image": image_path.name, "cloud": cloud_path.name}
        write_pair(out, index, image_path, cloud, meta)
        if progress is not None:
            progress(index + 1, len(chosen))
    return len(chosen)


def _vertical_offsets(options: PairsOptions, chosen: list[tuple[int, Path, Path]]) -> VerticalOffsets:
    """As asked, else the manual's when the LiDAR is a VLP-16 and every cloud was decoded without them (each
    cloud is read and checked here, before anything is written)."""
    if options.vertical_offsets is not None:
        return options.vertical_offsets
    clouds = (check_rings(read_pcd(path), path) for _, _, path in chosen)
    lacking = options.lidar_model == VLP16 and all(lacks_vertical_offsets(cloud) for cloud in clouds)
    return VerticalOffsets.MANUAL if lacking else VerticalOffsets.AS_RECORDED


def _check_image(path: Path, width: int, height: int, camera_info: Path) -> None:
    """A readable image of the camera's size (its bytes are copied as they are)."""
    image = read_image(path)
    if image.shape[:2] != (height, width):
        raise DatasetError(f"{path}: image is {image.shape[1]}x{image.shape[0]}, {camera_info.name} says "
                           f"{width}x{height}")
