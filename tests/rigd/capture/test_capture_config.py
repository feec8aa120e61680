"""Source strings, the rig file's capture settings, the CLI's option precedence, its status line and errors."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
import yaml
from capture_helpers import REPO

from rigd.capture import CaptureStatus, ConfigError, SourceSpecError
from rigd.capture import config as capture_config
from rigd.capture.config import find_config, load_settings
from rigd.capture.engine import settings_for
from rigd.capture.specs import CameraKind, LidarKind, parse_camera, parse_lidar
from rigd.cli import build_parser, main
from rigd.cli.capture import StatusPrinter, request_from_args
from rigd.cli.exit_codes import ERROR

DEPLOY_RIG = REPO / "deploy" / "config" / "rig.yaml"
PANORAMA = {"model": "equirectangular", "width": 64, "height": 32}


@pytest.mark.parametrize("text, kind, host, data, position, path", [
    ("udp", LidarKind.UDP, "0.0.0.0", 2368, 8308, None),
    ("udp:192.168.1.77:2369", LidarKind.UDP, "192.168.1.77", 2369, 8308, None),
    ("udp:127.0.0.1:4000:4001", LidarKind.UDP, "127.0.0.1", 4000, 4001, None),
    ("pcap:/data/run 1.pcap", LidarKind.PCAP, "0.0.0.0", 2368, 8308, Path("/data/run 1.pcap")),
    ("sim", LidarKind.SIM, "0.0.0.0", 2368, 8308, None),
    ("sim:rig.yaml", LidarKind.SIM, "0.0.0.0", 2368, 8308, Path("rig.yaml")),
])
def test_lidar_sources(text: str, kind: LidarKind, host: str, data: int, position: int, path: Path | None) -> None:
    spec = parse_lidar(text)
    assert (spec.kind, spec.host, spec.data_port, spec.position_port, spec.path) == (kind, host, data, position, path)


@pytest.mark.parametrize("text, match", [("tcp:1.2.3.4:5", "unknown source 'tcp'"), ("udp:1.2.3.4", "udp:HOST:PORT"),
                                         ("udp:host:70000", "1..65535"), ("udp:host:x", "PORT must be a number"),
                                         ("pcap", "pcap:FILE"), ("pcap:", "pcap:FILE")])
def test_bad_lidar_sources_say_what_is_expected(text: str, match: str) -> None:
    with pytest.raises(SourceSpecError, match=match):
        parse_lidar(text)


def test_camera_sources() -> None:
    assert parse_camera("sdk").kind is CameraKind.SDK
    assert parse_camera("replay:/frames").path == Path("/frames")
    assert parse_camera("sim").path is None and parse_camera("sim:x.yaml").path == Path("x.yaml")
    for text in ("usb", "replay", "sdk:0"):
        with pytest.raises(SourceSpecError, match="--camera"):
            parse_camera(text)


def test_the_deployed_rig_file_gives_its_values() -> None:
    data = yaml.safe_load(DEPLOY_RIG.read_text())
    settings = load_settings(DEPLOY_RIG)
    assert (settings.width, settings.height) == (data["camera"]["width"], data["camera"]["height"])
    assert settings.camera_source == data["camera"]["source"] and settings.lidar_source == data["lidar"]["source"]
    assert settings.capture.n == data["capture"]["n"] and settings.capture.sweeps == data["capture"]["sweeps"]
    assert settings.capture.still_seconds == data["capture"]["still_seconds"]
    assert settings.initial_guess is not None
    parse_lidar(settings.lidar_source), parse_camera(settings.camera_source)  # both are valid sources


@pytest.mark.parametrize("capture, match", [({"n": 0}, "capture.n"), ({"n": "twelve"}, "capture.n"),
                                            ({"still_seconds": -1}, "still_seconds"), ({"sweep": 5}, "'sweep'"),
                                            ({"min_move": "far"}, "min_move"),
                                            ({"min_sweep_fraction": 0}, "min_sweep_fraction"),
                                            ({"min_sweep_fraction": 1.2}, "at most 1")])
def test_bad_capture_settings_name_the_key(tmp_path: Path, capture: dict, match: str) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"capture": capture}))
    with pytest.raises(ConfigError, match=match):
        load_settings(path)


def test_a_pinhole_rig_file_cannot_drive_a_panorama_capture(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"camera": {"model": "pinhole", "width": 4, "height": 4,
                                               "K": [[1, 0, 2], [0, 1, 2], [0, 0, 1]]}}))
    with pytest.raises(ConfigError, match="equirectangular"):
        load_settings(path)


def test_config_search_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RIGD_CONFIG", raising=False)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(capture_config, "SEARCH_PATHS", (Path("rig.yaml"), tmp_path / "etc.yaml"))
    assert find_config() is None
    (tmp_path / "etc.yaml").write_text("{}")
    assert find_config() == tmp_path / "etc.yaml"
    (tmp_path / "rig.yaml").write_text("{}")
    assert find_config() == Path("rig.yaml")
    monkeypatch.setenv("RIGD_CONFIG", str(tmp_path / "etc.yaml"))
    assert find_config() == tmp_path / "etc.yaml"
    assert find_config(tmp_path / "rig.yaml") == tmp_path / "rig.yaml"
    with pytest.raises(ConfigError, match="does not exist"):
        find_config(tmp_path / "missing.yaml")
    monkeypatch.setenv("RIGD_CONFIG", str(tmp_path / "gone.yaml"))
    with pytest.raises(ConfigError, match="RIGD_CONFIG"):
        find_config()


def test_options_override_the_rig_file_which_overrides_the_defaults(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"lidar": {"source": "pcap:x.pcap"},
                                    "capture": {"n": 7, "sweeps": 3, "out": str(tmp_path / "ds"),
                                                "min_sweep_fraction": 0.95}}))
    args = build_parser().parse_args(["capture", "--config", str(path), "--sweeps", "9", "--camera", "sim"])
    request = request_from_args(args)
    assert (request.n, request.sweeps, request.out) == (7, 9, tmp_path / "ds")  # file, option, file
    assert request.min_sweep_fraction == 0.95
    args = build_parser().parse_args(["capture", "--config", str(path), "--min-sweep-fraction", "0.9"])
    assert request_from_args(args).min_sweep_fraction == 0.9
    assert (request.lidar, request.camera) == ("pcap:x.pcap", "sim")
    assert (request.still_seconds, request.min_move, request.silence_timeout_s) == (2.0, 0.5, 5.0)  # built in
    assert request.config == path


def test_cli_errors_are_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RIGD_CONFIG", raising=False)
    monkeypatch.setattr(capture_config, "SEARCH_PATHS", ())
    assert main(["capture", "--n", "2"]) == ERROR
    assert "rigd: error: give the dataset directory with --out" in capsys.readouterr().err
    assert main(["capture", "--out", str(tmp_path / "ds"), "--lidar", "sim", "--camera", "sdk"]) == ERROR
    assert "use --camera sim" in capsys.readouterr().err
    assert main(["capture", "--out", str(tmp_path / "ds"), "--lidar", "udp:127.0.0.1:9", "--camera", "sim"]) == ERROR
    assert "--camera sim:FILE" in capsys.readouterr().err


def status(state: str, message: str, pairs: int = 1) -> CaptureStatus:
    return CaptureStatus(state, pairs, 12, 0.4, 754.2, 3, message)


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_status_lines_in_a_log_one_per_state() -> None:
    log = io.StringIO()
    printer = StatusPrinter(log)
    for s in (status("holding_still", "hold still 1.6 s"), status("holding_still", "hold still 1.1 s"),
              status("captured", "captured 2/12", 2)):
        printer(s)
    lines = log.getvalue().splitlines()
    assert len(lines) == 2
    assert "[ 1/12]" in lines[0] and "hold still 1.6 s" in lines[0] and "754 packets/s, 3 lost" in lines[0]
    assert "captured 2/12" in lines[1]


def test_status_line_on_a_terminal_is_rewritten_in_place() -> None:
    terminal = FakeTerminal()
    printer = StatusPrinter(terminal)
    printer(status("holding_still", "hold still 1.6 s"))
    printer(status("holding_still", "hold still 1.1 s"))
    printer(status("captured", "captured 2/12", 2))
    printer.finish()
    out = terminal.getvalue()
    assert out.count("\r") == 2 and out.count("\n") == 2  # same state: same line; a new state: a new line
    shown = out.split("\n")[0].split("\r")[-1]  # what the terminal shows on the first line at the end
    assert "hold still 1.1 s" in shown and shown.rstrip().endswith("3 lost")


def test_the_sdk_camera_settings_and_options(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"camera": {**PANORAMA, "sdk": {"serial": 17092345, "grab_timeout_ms": 500}}}))
    settings = load_settings(path)
    assert (settings.sdk.serial, settings.sdk.grab_timeout_ms) == (17092345, 500)
    assert load_settings(None).sdk.serial is None and load_settings(None).sdk.grab_timeout_ms == 2000
    args = build_parser().parse_args(["capture", "--config", str(path), "--out", "ds"])
    request = request_from_args(args)
    assert (request.serial, request.nominal_head) == (None, False)
    assert settings_for(request).sdk.serial == 17092345  # the rig file's camera
    args = build_parser().parse_args(["capture", "--config", str(path), "--out", "ds", "--serial", "42",
                                      "--nominal-head"])
    request = request_from_args(args)
    assert (request.serial, request.nominal_head) == (42, True)
    assert settings_for(request).sdk.serial == 42 and settings_for(request).sdk.grab_timeout_ms == 500


@pytest.mark.parametrize("sdk, match", [({"serial": "abc"}, "camera.sdk.serial"), ({"serial": 0}, "serial"),
                                        ({"grab_timeout_ms": 0}, "grab_timeout_ms"),
                                        ({"grab_timeout": 5}, "'grab_timeout'")])
def test_bad_sdk_settings_name_the_key(tmp_path: Path, sdk: dict, match: str) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"camera": {**PANORAMA, "sdk": sdk}}))
    with pytest.raises(ConfigError, match=match):
        load_settings(path)


def test_the_lidar_elevation_offset_of_the_rig_file_is_carried_into_the_datasets(tmp_path: Path) -> None:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"camera": {"model": "equirectangular", "width": 64, "height": 32},
                                    "lidar": {"model": "VLP-16", "elevation_offset_deg": -0.2,
                                              "elevation_offset_sigma_deg": 0.05}}))
    settings = load_settings(path)
    assert (settings.lidar_elevation_offset_deg, settings.lidar_elevation_sigma_deg) == (-0.2, 0.05)
    assert load_settings(None).lidar_elevation_offset_deg == 0.0
