"""Paths to the real data in ``tests/data/`` (see its README): part of the repository, so a missing file is a
broken checkout. Asking for one that is absent raises at once, naming it: a test never skips for want of data."""

from __future__ import annotations

from pathlib import Path

DATA = Path(__file__).resolve().parent / "data"


def data_file(relative: str) -> Path:
    """``tests/data/<relative>``; FileNotFoundError naming the path if it is not there."""
    path = DATA / relative
    if not path.is_file():
        raise FileNotFoundError(
            f"test data file {path} is missing: it is part of the repository (tests/data/README.md); "
            "restore it with 'git checkout -- tests/data'"
        )
    return path


SMALL_PCAP = data_file("vlp16/vlp16_strongest_600rpm_84pkts.pcap")
LEGACY_PCAP = data_file("vlp16/vlp16_legacyfw_1200rpm_50rot.pcap")
PINHOLE_FRAME = data_file("pinhole_sample/ours_3/calib.pcd").parent  # calib.pcd, cloud.pcd, calibration.yaml, image.jpg
