"""``rigd lidar info`` and ``rigd lidar export`` through rigd.cli.main (only the lidar command registered)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from vlp16_helpers import ELEVATION_DEG, LEGACY_PCAP, MANUAL_OFFSET_M, SMALL_PCAP

import rigd.cli
from drivers.vlp16 import PcapReplay, Vlp16Config
from rigd.cli.exit_codes import CANT_CREATE, ERROR
from rigd.dataset import read_pcd

LASER_OF_RING = np.argsort(ELEVATION_DEG)  # ring 0 is the lowest laser


@pytest.fixture(autouse=True)
def only_lidar_command(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("lidar",))


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = rigd.cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_info_on_the_small_capture(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "lidar", "info", str(SMALL_PCAP))
    assert code == 0
    for expected in (
        "84 data packets, 0 position packets",
        "return mode:     strongest",
        "product id:      0x22",
        "rpm:             600.",
        "sweeps:          2 (0 complete)",
        "duration:        0.11",
        "PPS:             no position packets",
        "bad packets:     0",
    ):
        assert expected in out, expected


def test_info_on_the_legacy_capture_needs_any_product(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "lidar", "info", str(LEGACY_PCAP))
    assert code == 0
    assert "unexpected product id: 1902 (first at record 0)" in out and "--any-product" in out
    code, out, _ = run(capsys, "lidar", "info", "--any-product", str(LEGACY_PCAP))
    assert code == 0
    for expected in (
        "1902 data packets, 367 position packets",
        "product id:      0x21",
        "rpm:             1198.",
        "sweeps:          52 (50 complete)",
        "duration:        2.52",
        "PPS:             absent",
        "host time - device time = +1430.",
    ):
        assert expected in out, expected


def test_export_writes_one_pcd_per_sweep_with_rings_by_elevation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(capsys, "lidar", "export", str(SMALL_PCAP), "--out", str(tmp_path / "out"))
    assert code == 0 and "wrote 2 sweeps" in out
    sweeps = list(PcapReplay(SMALL_PCAP, Vlp16Config()))
    files = sorted((tmp_path / "out").glob("sweep_*.pcd"))
    assert [f.name for f in files] == ["sweep_0000.pcd", "sweep_0001.pcd"]
    for path, sweep in zip(files, sweeps, strict=True):
        cloud = read_pcd(path)
        assert len(cloud) == len(sweep.points)
        assert cloud.ring is not None and cloud.intensity is not None
        # By default each laser's origin is the manual's: 41.91 mm * tan(-elevation) above the sensor's.
        lasers = LASER_OF_RING[cloud.ring]
        from_laser = cloud.points_lidar - np.c_[np.zeros((len(cloud), 2)), MANUAL_OFFSET_M[lasers]]
        elevation = np.degrees(np.arcsin(from_laser[:, 2] / np.linalg.norm(from_laser, axis=1)))
        np.testing.assert_allclose(elevation, ELEVATION_DEG[lasers], atol=0.01)


def test_nominal_geometry_moves_each_ring_by_the_manual_offset_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    clouds = {}
    for name, flags in (("manual", []), ("nominal", ["--nominal-geometry"])):
        code, _, _ = run(capsys, "lidar", "export", *flags, str(SMALL_PCAP), "--out", str(tmp_path / name))
        assert code == 0
        clouds[name] = read_pcd(tmp_path / name / "sweep_0000.pcd")
    manual, nominal = clouds["manual"], clouds["nominal"]
    np.testing.assert_array_equal(manual.ring, nominal.ring)
    np.testing.assert_array_equal(manual.points_lidar[:, :2], nominal.points_lidar[:, :2])
    dz = manual.points_lidar[:, 2] - nominal.points_lidar[:, 2]
    np.testing.assert_allclose(dz, MANUAL_OFFSET_M[LASER_OF_RING[manual.ring]], atol=2e-6)  # float32 z
    assert np.abs(dz).max() == pytest.approx(0.01123, abs=1e-5)  # the -15 and +15 deg lasers


def test_calibration_file_and_nominal_geometry_exclude_each_other(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        run(capsys, "lidar", "info", "--nominal-geometry", "--calibration", str(tmp_path / "c.yaml"), str(SMALL_PCAP))
    assert "not allowed with argument" in capsys.readouterr().err


def test_export_complete_only_and_legacy_without_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run(
        capsys,
        "lidar",
        "export",
        "--any-product",
        "--complete-only",
        str(LEGACY_PCAP),
        "--out",
        str(tmp_path / "legacy"),
    )
    assert code == 0 and "wrote 50 sweeps" in out
    assert len(list((tmp_path / "legacy").glob("*.pcd"))) == 50
    code, _, err = run(capsys, "lidar", "export", str(LEGACY_PCAP), "--out", str(tmp_path / "none"))
    assert code == ERROR and "no sweeps to export" in err and "--any-product" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["legacy"]  # nothing of the failed export is left


def test_a_second_export_never_mixes_with_the_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert run(capsys, "lidar", "export", str(SMALL_PCAP), "--out", str(out))[0] == 0
    first = sorted(p.name for p in out.iterdir())
    code, _, err = run(capsys, "lidar", "export", "--any-product", str(LEGACY_PCAP), "--out", str(out))
    assert code == CANT_CREATE and "--overwrite" in err and sorted(p.name for p in out.iterdir()) == first
    code, _, _ = run(capsys, "lidar", "export", "--any-product", "--complete-only", str(LEGACY_PCAP), "--out",
                     str(out), "--overwrite")
    assert code == 0 and len(list(out.iterdir())) == 50  # replaced as a whole: no sweep of the first is left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    code, _, err = run(capsys, "lidar", "export", str(SMALL_PCAP), "--out", str(SMALL_PCAP.parent), "--overwrite")
    assert code == CANT_CREATE and "is inside it" in err  # replacing it would delete the capture read


def test_non_pcap_file_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("not a capture\n")
    for action in (["info"], ["export", "--out", str(tmp_path / "x")]):
        code, out, err = run(capsys, "lidar", *action, str(text))
        assert code == ERROR
        assert err.startswith("rigd: error: ") and "notes.txt: not a pcap or pcapng file" in err
        assert "Traceback" not in err
    code, _, err = run(capsys, "lidar", "info", "--calibration", str(text), str(SMALL_PCAP))
    assert code == ERROR and "notes.txt" in err


def test_bad_cut_azimuth_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "lidar", "info", "--cut-azimuth", "nan", str(SMALL_PCAP))
    assert code == ERROR and "cut azimuth must be a finite angle" in err
