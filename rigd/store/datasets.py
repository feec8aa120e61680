"""Datasets of the service: directories ``DATA_DIR/datasets/ID``, referenced by id, never by a path."""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rigd.dataset import Dataset, open_dataset
from rigd.dataset.records import HeadConfig
from rigd.dataset.store import read_yaml_mapping
from rigd.errors import DatasetError
from rigd.store.errors import NotFoundError
from rigd.store.jsonsafe import json_safe

# Starts with a letter or digit (so never "." or ".."), no separators: always one folder below the root.
DATASET_ID_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
# The pattern in words, for a person typing an id (the page's dataset field).
DATASET_ID_RULE = ("1 to 64 letters, digits, '_', '.' or '-', beginning with a letter or digit (no spaces, no '/'), "
                   "e.g. site-a_2026.11")
_ID = re.compile(DATASET_ID_PATTERN)
_HASH_CHUNK = 1 << 20


@dataclass(frozen=True)
class PairInfo:
    number: int  # the pair folder's number (pairs/NNNN)
    image: str  # file name of its image
    meta: dict[str, Any]


class DatasetCatalog:
    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def path(self, dataset_id: str) -> Path:
        """The folder of ``dataset_id`` (which need not exist yet); a malformed id names no dataset, and a
        folder that is a symbolic link, or holds one leading out of the datasets folder, is refused."""
        if not _ID.fullmatch(dataset_id):
            raise NotFoundError(f"dataset id {dataset_id!r} is not of the form {DATASET_ID_PATTERN}")
        path = self.root / dataset_id
        self._refuse_links_out(path)
        return path

    def _refuse_links_out(self, folder: Path) -> None:
        """DatasetError naming the first symbolic link by which ``folder`` leads out of the datasets folder.

        Ids keep requests inside ``root``, but a link would still let a capture write, and the API read,
        wherever it points. Links between datasets (a shared rig.yaml) stay allowed; the folder itself must
        not be one (its id would name another dataset, or a place outside).
        """
        if folder.is_symlink():
            raise self._link_error(folder, folder)
        root = Path(os.path.realpath(self.root))
        for parent, dirs, files in os.walk(folder):  # does not descend into linked folders: they are checked here
            for link in (Path(parent) / name for name in (*dirs, *files)):
                # realpath, not resolve(): a link loop must be refused, not raise RuntimeError
                if link.is_symlink() and not Path(os.path.realpath(link)).is_relative_to(root):
                    raise self._link_error(folder, link)

    def _link_error(self, folder: Path, link: Path) -> DatasetError:
        name = f"{self.root.name}/{folder.name}" if link == folder else link.relative_to(folder).as_posix()
        return DatasetError(f"dataset {folder.name}: {name} is a symbolic link (to {os.path.realpath(link)}); "
                            f"datasets must be folders and files inside {self.root}: copy the data in instead of "
                            "linking it")

    def open(self, dataset_id: str) -> Dataset:
        path = self.path(dataset_id)
        if not (path / "rig.yaml").is_file():
            raise NotFoundError(f"dataset {dataset_id} does not exist")
        return open_dataset(path)

    def ids(self) -> list[str]:
        if not self.root.is_dir():
            return []
        return sorted(p.name for p in self.root.iterdir() if _ID.fullmatch(p.name) and (p / "rig.yaml").is_file())

    def pairs(self, dataset: Dataset) -> list[PairInfo]:
        infos = []
        for folder in dataset.pair_dirs:
            image = next((p.name for p in sorted(folder.glob("image.*"))), "")
            meta_path = folder / "meta.yaml"
            meta = read_yaml_mapping(meta_path) if meta_path.is_file() else {}
            infos.append(PairInfo(int(folder.name), image, json_safe(meta)))
        return infos


def _files_of(dataset: Dataset) -> list[Path]:
    """Every file a calibration of ``dataset`` reads: rig.yaml, the masks it names, and each complete pair's files
    at any depth (a head's ``images/``), in a fixed order; hidden ones (``.rigd.lock``) left out."""
    cameras = [s.camera for s in dataset.source_camera.sensors] if isinstance(dataset.source_camera, HeadConfig) \
        else [dataset.source_camera]
    files = [dataset.root / "rig.yaml", *(dataset.root / c.mask for c in cameras if c.mask is not None)]
    for folder in dataset.pair_dirs:
        inside = {p.relative_to(folder).as_posix(): p for p in folder.rglob("*") if p.is_file()}
        files.extend(inside[name] for name in sorted(inside) if not any(n.startswith(".") for n in name.split("/")))
    return files


def content_hash(dataset: Dataset) -> str:
    """sha256 over every file a calibration of ``dataset`` reads (names and bytes, :func:`_files_of`).

    Two datasets with the same hash calibrate identically; unfinished ``.NNNN.tmp`` pairs are left out.
    """
    digest = hashlib.sha256()
    for path in _files_of(dataset):
        name = path.relative_to(dataset.root).as_posix().encode()
        digest.update(len(name).to_bytes(4, "little") + name)
        try:
            digest.update(path.stat().st_size.to_bytes(8, "little"))
            with path.open("rb") as fh:
                while chunk := fh.read(_HASH_CHUNK):
                    digest.update(chunk)
        except OSError as exc:
            raise DatasetError(f"{path}: cannot read it for the dataset hash ({exc.strerror})") from exc
    return "sha256:" + digest.hexdigest()
