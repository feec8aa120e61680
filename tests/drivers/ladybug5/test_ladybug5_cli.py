"""``rigd camera info`` with no camera, with a mocked one (fake pyusb backend), and without libusb;
``rigd camera export-head`` through the fake Ladybug SDK."""

from __future__ import annotations

import ctypes
import shutil

import cv2
import numpy as np
import pytest
import usb.backend.libusb0
import usb.backend.libusb1
import usb.backend.openusb
import yaml
from fake_ladybug_sdk import COMPILER, build
from ladybug5_fakes import FakeDevice, FakeUsbBackend, ladybug
from ladybug5_helpers import render_scene

import rigd.cli
from drivers.ladybug5.formats import STREAM_RESOLUTIONS
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.head_file import load_head, save_head
from drivers.ladybug5.pgr import PgrFrameData, PgrWriteOptions, bayer_planes, write_pgr
from drivers.ladybug5.rig import scaled_ladybug5_rig
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from rigd.cli.exit_codes import ERROR
from rigd.dataset.records import HeadConfig
from rigd.ladybug_head import head_config


@pytest.fixture
def usb_devices(monkeypatch):
    """Make pyusb's own backend discovery return a fake backend holding the listed devices."""
    devices: list[FakeDevice] = []
    backend = FakeUsbBackend(devices)
    monkeypatch.setattr(usb.backend.libusb1, "get_backend", lambda *a, **k: backend)
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))  # only the command under test
    return devices


def test_info_without_a_camera_says_so(usb_devices, capsys, tmp_path):
    code = rigd.cli.main(["camera", "info", "--sdk-library", str(tmp_path / "libladybug.so")])
    out = capsys.readouterr().out
    assert code == 1
    assert "no Ladybug camera found on USB (vendor 0x1e10" in out
    assert "Ladybug SDK: not available" in out


def test_info_with_a_mocked_camera(usb_devices, capsys, tmp_path):
    usb_devices.append(ladybug("17092345", bus=3, port_numbers=(2,), speed=3))
    code = rigd.cli.main(["camera", "info", "--sdk-library", str(tmp_path / "x.so")])
    out = capsys.readouterr().out
    assert "serial 17092345 at bus 3 port 2" in out and "USB 2 high speed" in out
    assert "warning: camera 17092345" in out
    assert code == 1  # found, but on a USB 2 link


def test_info_reset(usb_devices, capsys):
    device = ladybug()
    usb_devices.append(device)
    rigd.cli.main(["camera", "info", "--reset"])
    assert device.resets == 1 and "reset camera 17092345" in capsys.readouterr().out


def test_info_without_libusb_still_reports_the_rest(monkeypatch, capsys):
    for module in (usb.backend.libusb1, usb.backend.libusb0, usb.backend.openusb):
        monkeypatch.setattr(module, "get_backend", lambda *a, **k: None)
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))
    assert rigd.cli.main(["camera", "info"]) == 1
    out = capsys.readouterr().out
    assert "USB: cannot enumerate USB devices: pyusb found no backend" in out
    assert "usbfs memory limit" in out and "Ladybug SDK:" in out


def test_reset_without_a_camera_is_a_clean_error(usb_devices, capsys):
    assert rigd.cli.main(["camera", "info", "--reset"]) == ERROR
    assert "rigd: error: reset needs exactly one matching camera, found 0" in capsys.readouterr().err


@pytest.fixture(scope="module")
def fake_sdk(tmp_path_factory):
    """(library, layout file) of the fake Ladybug SDK (fake_sdk/), built once."""
    if COMPILER is None:
        pytest.skip("no C compiler (gcc/cc) to build the fake Ladybug SDK")
    out = tmp_path_factory.mktemp("fake_sdk")
    library, _ = build(out)
    return library, out / "layout.yaml"


def export(fake_sdk, tmp_path, *extra: str) -> int:
    library, layout = fake_sdk
    copy = tmp_path / "libfakeladybug.so"  # a copy per test: its globals start fresh (never overwrite a loaded one)
    if not copy.exists():
        shutil.copy(library, copy)
    return rigd.cli.main(["camera", "export-head", "--out", str(tmp_path / "head.yaml"), "--layout", str(layout),
                          "--sdk-library", str(copy), "--step", "2", *extra])


def test_export_head_from_the_camera_writes_the_head_dataset_form(fake_sdk, tmp_path, capsys):
    assert export(fake_sdk, tmp_path) == 0
    out = capsys.readouterr().out
    assert "factory head of camera 17092345" in out and "cam5: 16x12 px, f 10.00 px" in out
    data = yaml.safe_load((tmp_path / "head.yaml").read_text())
    head = HeadConfig.from_yaml(data["camera"], "head.yaml")  # what a head dataset's rig.yaml holds
    assert [s.name for s in head.sensors] == [f"cam{i}" for i in range(6)]
    assert (head.sensors[0].camera.width, head.sensors[0].camera.height) == (16, 12)
    loaded = load_head(tmp_path / "head.yaml")
    assert loaded.source is HeadSource.FACTORY and loaded.sensors[2].maps is not None
    np.testing.assert_allclose(head_config(loaded).sensors[2].camera.K, loaded.sensors[2].lens.K)
    np.testing.assert_allclose(head.sensors[2].T_head_camera.matrix[:3, :3], loaded.sensors[2].R_head_camera,
                               atol=1e-9)


def test_export_head_from_a_stream_and_from_a_configuration_file(fake_sdk, tmp_path, capsys):
    image = np.full((12, 16, 3), 128, np.uint8)
    write_pgr(tmp_path / "s.pgr", [PgrFrameData(5, 0, 1, [bayer_planes(image)] * 6)],
              calibration=b"FAKECAL -0.1 0.02 12.0", options=PgrWriteOptions(serial=17099999))
    assert export(fake_sdk, tmp_path, "--pgr", str(tmp_path / "s.pgr"), "--size", "16x12") == 0
    assert "factory head of camera 17099999" in capsys.readouterr().out
    (tmp_path / "folding.cal").write_text("FAKECAL -0.9 0.0 10.0")
    code = export(fake_sdk, tmp_path, "--calibration", str(tmp_path / "folding.cal"), "--size", "16x12", "--overwrite")
    assert code == 1 and "warning: the OpenCV lens model does not hold" in capsys.readouterr().out
    assert export(fake_sdk, tmp_path, "--calibration", str(tmp_path / "folding.cal"), "--overwrite") == ERROR
    assert "does not say the sensor size: give it (--size" in capsys.readouterr().err


def test_export_head_without_the_sdk_is_a_clear_error(tmp_path, capsys):
    code = rigd.cli.main(["camera", "export-head", "--out", str(tmp_path / "h.yaml"), "--layout",
                          str(tmp_path / "absent.yaml")])
    assert code == ERROR and "cannot read SDK layout file" in capsys.readouterr().err


@pytest.mark.parametrize("map_error", [0, 1])
def test_export_head_on_a_headless_rig(fake_sdk, tmp_path, capsys, map_error):
    copy = tmp_path / "libfakeladybug.so"
    shutil.copy(fake_sdk[0], copy)
    handle = ctypes.CDLL(str(copy))  # the same instance the command loads: steer it
    ctypes.c_int.in_dll(handle, "fake_headless").value = 1
    ctypes.c_int.in_dll(handle, "fake_map_error").value = map_error
    code = export(fake_sdk, tmp_path, "--size", "16x12")
    captured = capsys.readouterr()
    if map_error:
        assert code == ERROR and "rigd: error: cannot read the head calibration" in captured.err
        assert "xvfb-run rigd camera export-head" in captured.err and not (tmp_path / "head.yaml").exists()
        return
    assert code == 0 and "lens from ladybugGet3dMap" in captured.out
    assert "cam0: 16x12 px, raw f 10.00 px" in captured.out
    head = load_head(tmp_path / "head.yaml")
    assert head.source is HeadSource.FACTORY and head.sensors[0].maps is None
    np.testing.assert_allclose(head.sensors[0].lens.K[0, 0], 10.0, atol=1e-3)


def test_check_panorama_says_whether_another_panorama_is_in_rigds_convention(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))
    cv2.imwrite(str(tmp_path / "rigd.png"), render_scene(720))
    cv2.imwrite(str(tmp_path / "same.png"), render_scene(1024))
    cv2.imwrite(str(tmp_path / "flipped.png"), render_scene(1024, 72.0, mirrored=True))
    assert rigd.cli.main(["camera", "check-panorama", str(tmp_path / "same.png"), "--reference",
                          str(tmp_path / "rigd.png")]) == 0
    assert "turned +0.00 deg" in capsys.readouterr().out
    assert rigd.cli.main(["camera", "check-panorama", str(tmp_path / "flipped.png"), "--reference",
                          str(tmp_path / "rigd.png")]) == 1
    out = capsys.readouterr().out
    assert "turned +72.00 deg" in out and "mirrored" in out and "NOT in rigd's convention" in out


def test_check_panorama_stitches_a_pgr_frame_as_the_reference(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(rigd.cli, "COMMAND_MODULES", ("camera",))
    monkeypatch.setitem(STREAM_RESOLUTIONS, 97, (24, 20))  # a resolution code for these tests' sensors
    rig = scaled_ladybug5_rig(24)
    head = HeadCalibration.from_rig(rig, HeadSource.FACTORY, "test")
    save_head(head, tmp_path / "head.yaml")
    images = [np.full((c.height, c.width, 3), 40 * i + 20, np.uint8) for i, c in enumerate(rig.cameras)]
    write_pgr(tmp_path / "s.pgr", [PgrFrameData(5, 0, 1, [bayer_planes(im) for im in images])],
              options=PgrWriteOptions(resolution=(24, 20)))
    stitched = Stitcher(rig, PanoramaSpec(128, 64)).stitch(images)
    cv2.imwrite(str(tmp_path / "pano.png"), stitched)
    code = rigd.cli.main(["camera", "check-panorama", str(tmp_path / "pano.png"), "--pgr", str(tmp_path / "s.pgr"),
                          "--head", str(tmp_path / "head.yaml")])
    assert code == 0 and "in rigd's convention" in capsys.readouterr().out
    assert rigd.cli.main(["camera", "check-panorama", str(tmp_path / "pano.png"), "--pgr", str(tmp_path / "s.pgr"),
                          "--frame", "3", "--head", str(tmp_path / "head.yaml")]) == ERROR
    assert "no frame 3 (it holds 1)" in capsys.readouterr().err
