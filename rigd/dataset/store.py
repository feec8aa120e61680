"""Read and write a dataset directory (layout in docs/dataset.md).

Pairs are written atomically: into ``pairs/.NNNN.tmp`` first, renamed to ``pairs/NNNN`` when complete,
so a reader never sees half a pair and an interrupted writer loses nothing already written.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shutil
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from calib.elevation import raise_elevation
from calib.geometry import Transform
from rigd.dataset.lasers import VerticalOffsets, with_vertical_offsets
from rigd.dataset.pcd import Cloud, read_pcd, write_pcd
from rigd.dataset.records import (
    SINGLE_VIEW,
    CameraConfig,
    HeadConfig,
    RigConfig,
    transform_from_yaml,
    transform_to_yaml,
)
from rigd.dataset.reference import Reference, reference_from_yaml
from rigd.dataset.working import halvings, working_camera, working_image, working_mask
from rigd.errors import DatasetError
from rigd.locks import writing
from rigd.outdir import fsync_path

IMAGE_NAMES = ("image.png", "image.jpg", "image.jpeg")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class Pair:
    """One synchronised capture: ``images`` (H,W) or (H,W,3) uint8 (BGR), one per view of the rig (one for a
    single camera, one per sensor of a head, in rig.yaml's order), its cloud and ``meta``."""

    index: int
    images: tuple[NDArray[np.uint8], ...]
    cloud: Cloud
    meta: dict[str, Any]

    @property
    def image(self) -> NDArray[np.uint8]:
        """The image of a single-camera rig (a head's first sensor)."""
        return self.images[0]


def read_yaml(path: Path) -> Any:
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    try:
        with path.open() as fh:
            return yaml.safe_load(fh)
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: not valid YAML ({exc})") from exc


def read_yaml_mapping(path: Path) -> dict[str, Any]:
    """Read a YAML file that must hold a mapping (an empty file gives an empty one)."""
    data = read_yaml(path)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise DatasetError(f"{path}: expected a YAML mapping, got {type(data).__name__}")
    return data


def write_yaml(path: Path, data: Any) -> None:
    """Write YAML through a temporary file and a rename, so the file is never half written; a failed write
    leaves no temporary file and raises DatasetError naming ``path`` and the OS's reason."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with tmp.open("w") as fh:
            yaml.safe_dump(data, fh, sort_keys=False)
            fh.flush()
            os.fsync(fh.fileno())
        tmp.replace(path)
    except BaseException as exc:
        with contextlib.suppress(OSError):  # the write's own error is the one to report
            tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise DatasetError(f"{path}: cannot write ({exc.strerror or exc})") from exc
        raise


def read_image(path: Path) -> NDArray[np.uint8]:
    if not path.is_file():
        raise DatasetError(f"{path}: image file is missing")
    try:
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:  # e.g. a header claiming 60000x30000 px: OpenCV refuses to allocate it
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV refused it"
        raise DatasetError(f"{path}: not a readable PNG/JPEG image ({reason})") from exc
    except MemoryError as exc:
        raise DatasetError(f"{path}: the image is too large to load") from exc
    if image is None or image.size == 0:
        raise DatasetError(f"{path}: not a readable PNG/JPEG image")
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(float(image.max()), 1.0))
    return np.asarray(image, dtype=np.uint8)


def _image_path(folder: Path, view: str) -> Path:
    """The image file of ``view`` in pair ``folder`` (the first of .png, .jpg, .jpeg found)."""
    candidates = [folder / n for n in IMAGE_NAMES] if view == SINGLE_VIEW else \
        [folder / "images" / f"{view}{suffix}" for suffix in IMAGE_SUFFIXES]
    return next((c for c in candidates if c.is_file()), candidates[0])


@dataclass(frozen=True)
class Dataset:
    """An opened dataset; pairs are loaded lazily (a 12-pair set does not have to fit in memory).

    ``rig.camera`` is the camera at the working resolution (rigd.dataset.working): the images are halved
    ``halvings`` times on load from ``source_camera``'s size, the one on disk and in rig.yaml. ``masks``: per
    view, (H,W) bool at the working resolution, True where the image shows the scene (None: all of it)."""

    root: Path
    rig: RigConfig
    pair_dirs: tuple[Path, ...]
    ground_truth: Transform | None
    source_camera: CameraConfig | HeadConfig
    halvings: int = 0
    masks: tuple[NDArray[np.bool_] | None, ...] = (None,)
    reference: Reference | None = None  # reference.yaml: a published calibration of real data

    def __len__(self) -> int:
        return len(self.pair_dirs)

    @property
    def views(self) -> tuple[str, ...]:
        """The views of every pair: ``image`` for a single camera, the sensors' names for a head."""
        return self.rig.camera.view_names

    def _sizes(self) -> list[tuple[int, int]]:
        cam = self.source_camera
        return [(s.camera.height, s.camera.width) for s in cam.sensors] if isinstance(cam, HeadConfig) \
            else [(cam.height, cam.width)]

    def image_path(self, i: int, view: str) -> Path:
        """The image file of pair ``i`` (an index into ``pair_dirs``) for ``view`` (one of :attr:`views`)."""
        return _image_path(self.pair_dirs[i], view)

    def load_pair(self, i: int) -> Pair:
        folder = self.pair_dirs[i]
        images = []
        for view, expected in zip(self.views, self._sizes(), strict=True):
            image_path = _image_path(folder, view)
            image = read_image(image_path)
            if image.shape[:2] != expected:
                raise DatasetError(f"{image_path}: image is {image.shape[1]}x{image.shape[0]}, rig.yaml says "
                                   f"{expected[1]}x{expected[0]}")
            images.append(working_image(image, self.source_camera, self.halvings))
        cloud = read_pcd(folder / "cloud.pcd")
        if self.rig.lidar_vertical_offsets is VerticalOffsets.MANUAL:
            cloud = with_vertical_offsets(cloud, str(folder / "cloud.pcd"))
        if self.rig.lidar_elevation_offset_deg:
            cloud = dataclasses.replace(cloud, points_lidar=raise_elevation(cloud.points_lidar,
                                                                            self.rig.lidar_elevation_offset_deg))
        meta_path = folder / "meta.yaml"
        meta = read_yaml_mapping(meta_path) if meta_path.is_file() else {}
        return Pair(int(folder.name), tuple(images), cloud, meta)

    def pairs(self) -> Iterator[Pair]:
        for i in range(len(self)):
            yield self.load_pair(i)


def read_mask(path: Path, size: tuple[int, int]) -> NDArray[np.bool_]:
    """A sensor's mask file: (H,W) bool, True where non-zero (the image shows the scene); ``size`` (H, W)."""
    image = read_image(path)
    mask = np.asarray((image if image.ndim == 2 else image.max(axis=2)) > 0)
    if mask.shape != size:
        raise DatasetError(f"{path}: mask is {mask.shape[1]}x{mask.shape[0]}, its sensor {size[1]}x{size[0]}")
    if not mask.any():
        raise DatasetError(f"{path}: mask shows nothing of the scene (all zero)")
    return mask


def _masks(root: Path, camera: CameraConfig | HeadConfig, n: int) -> tuple[NDArray[np.bool_] | None, ...]:
    """Each view's mask at the working resolution (``n`` halvings)."""
    cameras = [s.camera for s in camera.sensors] if isinstance(camera, HeadConfig) else [camera]
    return tuple(None if c.mask is None else working_mask(read_mask(root / c.mask, (c.height, c.width)), n)
                 for c in cameras)


def open_dataset(root: Path, max_width: int | None = None) -> Dataset:
    """Open ``root``; raises :class:`DatasetError` naming the missing or corrupt file. ``max_width``: the
    working resolution, px (images wider are halved on load, rigd.dataset.working); None: as on disk."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"{root}: dataset directory does not exist")
    rig = RigConfig.from_yaml(read_yaml(root / "rig.yaml"), str(root / "rig.yaml"))
    dirs = pair_folders(root)
    gt_path = root / "ground_truth.yaml"
    gt = None
    if gt_path.is_file():
        gt = transform_from_yaml(read_yaml_mapping(gt_path).get("T_camera_lidar", {}), str(gt_path))
    ref_path = root / "reference.yaml"
    reference = reference_from_yaml(read_yaml_mapping(ref_path), str(ref_path)) if ref_path.is_file() else None
    n = halvings(rig.camera, max_width)
    working = dataclasses.replace(rig, camera=working_camera(rig.camera, n))
    return Dataset(root, working, tuple(dirs), gt, rig.camera, n, _masks(root, rig.camera, n), reference)


def write_rig(root: Path, rig: RigConfig) -> None:
    try:
        Path(root).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"{root}: cannot create the dataset folder ({exc.strerror})") from exc
    write_yaml(Path(root) / "rig.yaml", rig.to_yaml())


def write_ground_truth(root: Path, transform: Transform) -> None:
    write_yaml(Path(root) / "ground_truth.yaml", {"T_camera_lidar": transform_to_yaml(transform)})


def pair_number(name: str) -> int | None:
    """The number of the pair folder ``name`` (``0007``), None for a name that is no pair's (``.0007.tmp``, an
    unfinished pair; ``notes``); DatasetError for a number in another form (``7``, ``00007``, ``²``): two folders
    could then hold one pair, and the pair numbers of versions and overlays would be ambiguous."""
    if not name.isdigit():  # Unicode digits too: '²'.isdigit() is True
        return None
    number = int(name) if name.isascii() else None
    if number is None or name != f"{number:04d}":
        canonical = f" (pairs/{number:04d})" if number is not None else ""
        raise DatasetError(f"pairs/{name}: a pair folder is named by its number in ASCII digits, at least 4 "
                           f"(0007, 0123, 12345){canonical}: rename it")
    return number


def pair_folders(root: Path) -> list[Path]:
    """The complete pairs' folders of dataset ``root``, by number (DatasetError for a wrongly named one)."""
    pairs_dir = Path(root) / "pairs"
    try:
        entries = list(pairs_dir.iterdir()) if pairs_dir.is_dir() else []
    except OSError as exc:
        raise DatasetError(f"{pairs_dir}: cannot list the pairs ({exc.strerror})") from exc
    numbered = []
    for entry in entries:
        try:
            number = pair_number(entry.name)
        except DatasetError as exc:
            raise DatasetError(f"{root}/{exc}") from None
        if number is not None and entry.is_dir():
            numbered.append((number, entry))
    return [entry for _, entry in sorted(numbered)]


def next_pair_index(root: Path) -> int:
    """One past the highest complete pair of the dataset ``root`` (0 for none): where a capture resumes."""
    return max((int(p.name) for p in pair_folders(root)), default=-1) + 1


def write_pair(root: Path, index: int, image: NDArray[np.uint8] | Path | Mapping[str, NDArray[np.uint8] | Path],
               cloud: Cloud, meta: dict[str, Any], *, extras: Mapping[str, NDArray[Any]] | None = None) -> Path:
    """Write pair ``index`` atomically and return its folder; an existing pair is never overwritten.
    ``image``: the camera's image, or a head's images by sensor name (images/NAME.png); a Path is an image file
    copied as it is (image.jpg, images/NAME.jpg for a JPEG: no second lossy encoding). ``extras``: more images of
    the pair by file name (e.g. ``panorama.png`` beside a head's images), for people: calibration does not read them.
    Written under the dataset's writer lock (rigd.locks): DatasetLockedError while another process writes
    the dataset."""
    with writing(Path(root)):
        return _write_pair(Path(root), index, image, cloud, meta, dict(extras or {}))


def _write_pair(root: Path, index: int, image: NDArray[np.uint8] | Path | Mapping[str, NDArray[np.uint8] | Path],
                cloud: Cloud, meta: dict[str, Any], extras: dict[str, NDArray[Any]]) -> Path:
    pairs_dir = root / "pairs"
    final = pairs_dir / f"{index:04d}"
    if final.exists():
        raise DatasetError(f"{final}: pair already exists; refusing to overwrite it")
    tmp = pairs_dir / f".{index:04d}.tmp"
    single = f"image{image.suffix.lower()}" if isinstance(image, Path) else "image.png"
    images = {single: image} if not isinstance(image, Mapping) else \
        {f"images/{name}{im.suffix.lower() if isinstance(im, Path) else '.png'}": im for name, im in image.items()}
    images = {**images, **extras}
    try:
        pairs_dir.mkdir(parents=True, exist_ok=True)
        if tmp.exists():
            shutil.rmtree(tmp)  # under the lock no other writer is at work: a leftover of an interrupted write
        tmp.mkdir()
        for name, im in images.items():
            (tmp / name).parent.mkdir(exist_ok=True)
            if isinstance(im, Path):
                shutil.copyfile(im, tmp / name)
            elif not cv2.imwrite(str(tmp / name), im):
                raise DatasetError(f"{tmp / name}: could not write image")
        write_pcd(tmp / "cloud.pcd", cloud)
        write_yaml(tmp / "meta.yaml", meta)
        # Data on disk before the rename makes the pair visible, and the rename itself on disk after:
        # a power cut then leaves either no pair or a complete one (the rig runs on batteries).
        for name in (*images, "cloud.pcd"):
            fsync_path(tmp / name)
        if (tmp / "images").is_dir():
            fsync_path(tmp / "images")
        fsync_path(tmp)
        tmp.rename(final)
        fsync_path(pairs_dir)
    except BaseException as exc:
        with contextlib.suppress(OSError):  # ours (under the lock), and space a full disk needs back
            shutil.rmtree(tmp)
        if isinstance(exc, OSError):  # disk full, permissions, ...
            raise DatasetError(f"{tmp}: could not write pair {index:04d} ({exc})") from exc
        raise
    return final

