"""``rigd doctor``: each check against the real thing on loopback (UDP packets, files), and the command."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator
from dataclasses import replace
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest
import yaml

from drivers.errors import DriverError
from drivers.ladybug5.errors import CameraNotFoundError, HeadCalibrationError
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.head_file import save_head
from drivers.vlp16 import encode_data_packets
from rigd.capture import config as capture_config
from rigd.capture.config import RigSettings, SdkSettings
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.doctor import DoctorError, DoctorOptions, Status, local
from rigd.doctor.local import camera_usb_check, data_dir_check, head_check, rig_file_check, sdk_check
from rigd.doctor.network import lidar_port_check

MISSING_SDK = "/nonexistent/libladybug.so"


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def free_tcp_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture()
def clean_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """No RIGD_* settings from outside, no rig file on the search path, a data directory in tmp, and a port
    nobody serves on."""
    for name in [n for n in os.environ if n.startswith("RIGD_")]:
        monkeypatch.delenv(name)
    monkeypatch.setattr(capture_config, "SEARCH_PATHS", (tmp_path / "rig.yaml",))
    monkeypatch.setenv("RIGD_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.setenv("RIGD_PORT", str(free_tcp_port()))
    return tmp_path


def write_rig(path: Path, lidar: str, camera: str = "sim") -> Path:
    """A rig file with these sources; the SDK library it names does not exist."""
    rig = {
        "camera": {"model": "equirectangular", "width": 256, "height": 128, "source": camera,
                   "sdk": {"library": MISSING_SDK}},
        "lidar": {"model": "VLP-16", "source": lidar},
    }
    path.write_text(yaml.safe_dump(rig))
    return path


@pytest.fixture()
def vlp16_sender() -> Iterator[list[int]]:
    """Sends a real VLP-16 data packet to 127.0.0.1:PORT every 2 ms once a port is put in the list."""
    firings = 24
    payload = encode_data_packets(np.full((firings, 16), 5.0), np.full((firings, 16), 50, np.uint8),
                                  np.linspace(0.0, 9.6, firings), 0.0).payloads[0].tobytes()
    ports: list[int] = []
    stop = threading.Event()

    def send() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            while not stop.wait(0.002):
                for port in ports:
                    sock.sendto(payload, ("127.0.0.1", port))

    thread = threading.Thread(target=send, daemon=True)
    thread.start()
    yield ports
    stop.set()
    thread.join(timeout=5)


def test_packets_arriving_on_the_vlp16_port_is_ok(vlp16_sender: list[int]) -> None:
    port = free_udp_port()
    vlp16_sender.append(port)
    check = lidar_port_check(RigSettings(lidar_source=f"udp:127.0.0.1:{port}"), listen_s=0.5)
    assert check.status is Status.OK, check
    assert f"127.0.0.1:{port} bound" in check.detail and " 0 of them" not in check.detail


def test_no_packets_on_the_vlp16_port_is_a_warning_with_a_fix() -> None:
    port = free_udp_port()
    check = lidar_port_check(RigSettings(lidar_source=f"udp:127.0.0.1:{port}"), listen_s=0.3)
    assert check.status is Status.WARN
    assert "0 datagrams" in check.detail and "power and Ethernet cable" in check.fix


def test_other_traffic_on_the_port_is_not_vlp16_data(vlp16_sender: list[int]) -> None:
    port = free_udp_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as other:
        settings = RigSettings(lidar_source=f"udp:127.0.0.1:{port}")
        result: list = []
        thread = threading.Thread(target=lambda: result.append(lidar_port_check(settings, listen_s=0.5)))
        thread.start()
        for _ in range(20):
            other.sendto(b"not a lidar packet", ("127.0.0.1", port))
            threading.Event().wait(0.01)
        thread.join()
    assert result[0].status is Status.WARN and "0 of them VLP-16 data packets" in result[0].detail


def test_a_taken_vlp16_port_fails_and_says_what_to_do() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        check = lidar_port_check(RigSettings(lidar_source=f"udp:127.0.0.1:{port}"), listen_s=0.2)
    assert check.status is Status.FAIL
    assert f"cannot bind 127.0.0.1:{port}" in check.detail and f"sport = :{port}" in check.fix


def test_a_simulated_lidar_is_not_listened_for() -> None:
    check = lidar_port_check(RigSettings(lidar_source="sim"), listen_s=5.0)
    assert check.status is Status.OK and "not used" in check.detail


def test_rig_file_found_through_the_environment_names_its_source(clean_env: Path, monkeypatch) -> None:
    path = write_rig(clean_env / "field.yaml", "udp:127.0.0.1:2368")
    monkeypatch.setenv("RIGD_CONFIG", str(path))
    check, settings = rig_file_check(None)
    assert check.status is Status.OK and str(path) in check.detail and "$RIGD_CONFIG" in check.detail
    assert settings.camera_source == "sim"


def test_no_rig_file_is_a_warning_and_a_broken_one_fails(clean_env: Path) -> None:
    check, settings = rig_file_check(None)
    assert check.status is Status.WARN and "deploy/config/rig.yaml" in check.fix
    assert settings == RigSettings()
    broken = clean_env / "broken.yaml"
    broken.write_text("lidar: [not, a, mapping]\n")
    check, _ = rig_file_check(broken)
    assert check.status is Status.FAIL and "broken.yaml" in check.detail
    check, _ = rig_file_check(clean_env / "absent.yaml")
    assert check.status is Status.FAIL and "absent.yaml" in check.detail


@pytest.mark.parametrize(("free_gib", "status"), [(0.5, Status.FAIL), (3.0, Status.WARN), (50.0, Status.OK)])
def test_data_directory_free_space(tmp_path: Path, monkeypatch, free_gib: float, status: Status) -> None:
    real = local.shutil.disk_usage

    def usage(path):
        total, used, _ = real(path)
        return type(real(path))(total, used, int(free_gib * local.GIB))

    monkeypatch.setattr(local.shutil, "disk_usage", usage)
    check = data_dir_check(tmp_path / "not-yet")
    assert check.status is status
    assert "not created yet" in check.detail and f"{free_gib:.1f} GiB free" in check.detail


def test_camera_checks_only_matter_for_the_sdk_source(monkeypatch) -> None:
    sim = RigSettings(camera_source="sim")
    assert camera_usb_check(sim).status is Status.OK
    assert sdk_check(sim, MISSING_SDK).status is Status.OK
    sdk = RigSettings(camera_source="sdk")
    missing = sdk_check(sdk, MISSING_SDK)
    assert missing.status is Status.FAIL and MISSING_SDK in missing.detail
    monkeypatch.setattr(local, "find_cameras", lambda match: ([], []))
    none = camera_usb_check(sdk)
    assert none.status is Status.FAIL and "no Ladybug camera" in none.detail

    def no_backend(match):
        raise DriverError("pyusb found no backend")

    monkeypatch.setattr(local, "find_cameras", no_backend)
    assert camera_usb_check(sdk).status is Status.FAIL


def test_doctor_command_exit_code_follows_failures(clean_env: Path, capsys, vlp16_sender: list[int]) -> None:
    port = free_udp_port()
    vlp16_sender.append(port)
    good = write_rig(clean_env / "good.yaml", f"udp:127.0.0.1:{port}")
    assert main(["doctor", "--config", str(good), "--listen", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "ok    VLP-16 UDP port" in out and "warn  service" in out  # nobody serves on RIGD_PORT
    assert out.strip().splitlines()[-1].endswith(" 0 fail")
    bad = write_rig(clean_env / "bad.yaml", f"udp:127.0.0.1:{port}", camera="sdk")
    code = main(["doctor", "--config", str(bad), "--listen", "0.2"])
    out = capsys.readouterr().out
    assert code == 1 and "fail  Ladybug SDK" in out and MISSING_SDK in out
    assert "fix: install FLIR's Ladybug SDK" in out


def test_doctor_refuses_a_listen_time_that_is_not_positive(capsys) -> None:
    with pytest.raises(DoctorError, match="listen_s"):
        DoctorOptions(listen_s=0.0)
    assert main(["doctor", "--listen", "-1"]) == ERROR
    assert "listen_s must be a positive number" in capsys.readouterr().err


def test_version_comes_from_the_package_metadata(capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"rigd {version('rigd')}"


def sdk_settings(tmp_path: Path, rig_file: Path | None = None) -> RigSettings:
    layout = tmp_path / "layout.yaml"
    layout.write_text("a layout\n")
    return RigSettings(camera_source="sdk", sdk=SdkSettings(layout=layout, library="libfake.so", rig_file=rig_file))


def test_the_head_check_names_the_head_in_a_rig_file(tmp_path: Path) -> None:
    assert head_check(RigSettings(camera_source="sim"), None).status is Status.OK
    nominal = HeadCalibration.nominal((16, 12))
    save_head(replace(nominal, source=HeadSource.FACTORY, serial=17092345, description="camera 17092345 (test)"),
              tmp_path / "factory.yaml")
    check = head_check(sdk_settings(tmp_path, tmp_path / "factory.yaml"), None)
    assert check.status is Status.OK and "factory head of camera 17092345" in check.detail
    save_head(nominal, tmp_path / "nominal.yaml")
    check = head_check(sdk_settings(tmp_path, tmp_path / "nominal.yaml"), None)
    assert check.status is Status.WARN and "NOMINAL head" in check.detail and "export-head" in check.fix
    check = head_check(sdk_settings(tmp_path, tmp_path / "absent.yaml"), None)
    assert check.status is Status.FAIL and "absent.yaml" in check.detail


def test_the_head_check_reads_the_factory_head_from_the_camera(tmp_path: Path, monkeypatch) -> None:
    settings = sdk_settings(tmp_path)
    missing = head_check(settings, MISSING_SDK)
    assert missing.status is Status.WARN and "not set up" in missing.detail and "--nominal-head" in missing.detail
    factory = replace(HeadCalibration.nominal((16, 12)), source=HeadSource.FACTORY, serial=7, description="test")
    outcome: list = [factory]

    def read(lib, step_px):
        if isinstance(outcome[0], Exception):
            raise outcome[0]
        return outcome[0]

    monkeypatch.setattr(local, "sdk_status", lambda library: f"{library} loads")
    monkeypatch.setattr(local.SdkLayout, "load", lambda path: None)
    monkeypatch.setattr(local, "LadybugLibrary", lambda layout, library: None)
    monkeypatch.setattr(local, "read_camera_head", read)
    check = head_check(settings, None)
    assert check.status is Status.OK and "read from the camera now" in check.detail and "camera 7" in check.detail
    outcome[0] = HeadCalibrationError("ladybugLoadConfig: no calibration file on the Ladybug head")
    check = head_check(settings, None)
    assert check.status is Status.FAIL and "no calibration file" in check.detail and "--nominal-head" in check.detail
    outcome[0] = CameraNotFoundError("the Ladybug SDK sees no camera on the bus")
    check = head_check(settings, None)
    assert check.status is Status.WARN and "could not read the factory head" in check.detail
