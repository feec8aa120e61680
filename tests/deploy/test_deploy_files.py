"""The rig computer's files in deploy/: parse what can be parsed and check that they agree."""

from __future__ import annotations

import ipaddress
import re
import shlex
from pathlib import Path

import pytest
import yaml

from drivers.ladybug5.usb import POINT_GREY_VENDOR_ID, REQUIRED_USBFS_MEMORY_MB, USBFS_MEMORY_PATH
from rigd.dataset import CameraKind, RigConfig

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
SENSOR_ADDRESS = ipaddress.ip_address("192.168.1.201")  # the VLP-16's factory address (user manual)
VLP16_DATA_PORT = 2368


def parse_ini(path: Path) -> dict[str, dict[str, list[str]]]:
    """systemd-style INI: sections of ``Key=value`` lines; a key may repeat, so values are lists."""
    sections: dict[str, dict[str, list[str]]] = {}
    current: dict[str, list[str]] | None = None
    for number, raw in enumerate(path.read_text().splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1], {})
            continue
        assert current is not None and "=" in line, f"{path.name}:{number}: not 'Key=value' in a section"
        key, value = line.split("=", 1)
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


def non_comment_lines(path: Path) -> list[str]:
    return [
        s for s in (line.strip() for line in path.read_text().splitlines()) if s and not s.startswith("#")
    ]


@pytest.fixture(scope="module")
def unit() -> dict[str, dict[str, list[str]]]:
    return parse_ini(DEPLOY / "systemd" / "rigd.service")


def service(unit: dict[str, dict[str, list[str]]], key: str) -> str:
    values = unit["Service"][key]
    assert len(values) == 1, f"{key} given {len(values)} times"
    return values[0]


def environment(unit: dict[str, dict[str, list[str]]]) -> dict[str, str]:
    pairs = [
        item.split("=", 1) for value in unit["Service"].get("Environment", []) for item in shlex.split(value)
    ]
    return dict(pairs)


# --- systemd unit ---------------------------------------------------------------------------------------


def test_unit_runs_rigd_serve(unit: dict[str, dict[str, list[str]]]) -> None:
    argv = shlex.split(service(unit, "ExecStart"))
    assert Path(argv[0]).is_absolute() and Path(argv[0]).name == "rigd"
    assert argv[1] == "serve"
    assert unit["Install"]["WantedBy"] == ["multi-user.target"]


def test_unit_raises_the_open_file_limit(unit: dict[str, dict[str, list[str]]]) -> None:
    # systemd's default of 1024 open files let ~1,000 slow-header connections lock every client out (issue 33).
    assert int(service(unit, "LimitNOFILE")) >= 65536


def test_unit_user_data_dir_and_config(unit: dict[str, dict[str, list[str]]]) -> None:
    assert service(unit, "User") == service(unit, "Group") == "rigd"
    # StateDirectory=rigd is /var/lib/rigd, created by systemd and owned by User=.
    assert service(unit, "StateDirectory") == "rigd"
    env = environment(unit)
    assert env["RIGD_DATA_DIR"] == "/var/lib/rigd"
    assert env["RIGD_CONFIG"] == "/etc/rigd/rig.yaml"
    assert service(unit, "ConfigurationDirectory") == "rigd"


def test_unit_is_hardened_but_can_reach_the_camera(unit: dict[str, dict[str, list[str]]]) -> None:
    expected = {
        "NoNewPrivileges": "yes",
        "ProtectSystem": "strict",
        "ProtectHome": "yes",
        "PrivateTmp": "yes",
        "ProtectKernelModules": "yes",
        "RestrictNamespaces": "yes",
        "DevicePolicy": "closed",
        "CapabilityBoundingSet": "",
    }
    for key, value in expected.items():
        assert service(unit, key) == value, key
    # libusb opens /dev/bus/usb/BBB/DDD: USB device nodes must stay reachable.
    assert "PrivateDevices" not in unit["Service"]
    assert any(
        v.split()[0] == "char-usb_device" and "rw" in v.split()[1:] for v in unit["Service"]["DeviceAllow"]
    )
    families = service(unit, "RestrictAddressFamilies").split()
    assert {"AF_INET", "AF_UNIX"} <= set(families)  # HTTP and the VLP-16's UDP


def test_sysusers_creates_the_service_user(unit: dict[str, dict[str, list[str]]]) -> None:
    entries = [shlex.split(line) for line in non_comment_lines(DEPLOY / "sysusers.d" / "rigd.conf")]
    users = {e[1]: e for e in entries if e[0] == "u"}
    assert service(unit, "User") in users
    assert users["rigd"][4] == environment(unit)["RIGD_DATA_DIR"]  # home
    assert users["rigd"][5] == "/usr/sbin/nologin"


# --- camera: udev, usbfs --------------------------------------------------------------------------------

RULE_TERM = re.compile(r'(?P<key>[A-Z_]+(?:\{[^}]+\})?)\s*(?P<op>==|!=|\+=|:=|=)\s*"(?P<value>[^"]*)"')


def test_udev_rule_matches_the_ladybug5_vendor() -> None:
    rules = non_comment_lines(DEPLOY / "udev" / "60-rigd-ladybug5.rules")
    assert len(rules) == 1
    terms = {(m["key"], m["op"]): m["value"] for m in RULE_TERM.finditer(rules[0])}
    # The same vendor id the driver enumerates with (drivers/ladybug5/usb.py).
    assert int(terms[("ATTR{idVendor}", "==")], 16) == POINT_GREY_VENDOR_ID
    assert terms[("SUBSYSTEM", "==")] == "usb"
    assert terms[("MODE", "=")] == "0660"
    assert terms[("GROUP", "=")] == "rigd"


def test_usbfs_memory_is_raised_at_boot() -> None:
    modprobe = non_comment_lines(DEPLOY / "modprobe.d" / "rigd-usbfs.conf")
    assert modprobe == [f"options usbcore usbfs_memory_mb={REQUIRED_USBFS_MEMORY_MB}"]
    # tmpfiles.d "w PATH MODE USER GROUP AGE ARGUMENT": write ARGUMENT into PATH at boot.
    (line,) = non_comment_lines(DEPLOY / "tmpfiles.d" / "rigd-usbfs.conf")
    kind, path, *_, argument = line.split()
    assert kind == "w"
    assert path == str(USBFS_MEMORY_PATH)
    assert int(argument) == REQUIRED_USBFS_MEMORY_MB


# --- LiDAR: network, receive buffer ------------------------------------------------------------------------


def test_networkd_puts_the_host_next_to_the_sensor() -> None:
    network = parse_ini(DEPLOY / "network" / "10-rigd-vlp16.network")
    (address,) = network["Network"]["Address"]
    host = ipaddress.ip_interface(address)
    assert SENSOR_ADDRESS in host.network and host.ip != SENSOR_ADDRESS
    assert "Gateway" not in network["Network"]
    assert network["Match"]["Name"]


def test_netplan_alternative_says_the_same() -> None:
    netplan = yaml.safe_load((DEPLOY / "network" / "60-rigd-vlp16.yaml").read_text())["network"]
    assert netplan["version"] == 2
    ((name, port),) = netplan["ethernets"].items()
    networkd = parse_ini(DEPLOY / "network" / "10-rigd-vlp16.network")
    assert [name] == networkd["Match"]["Name"]
    assert port["addresses"] == networkd["Network"]["Address"]
    assert port["dhcp4"] is False and "gateway4" not in port and "routes" not in port


def test_receive_buffer_holds_seconds_of_packets() -> None:
    lines = non_comment_lines(DEPLOY / "sysctl.d" / "60-rigd-udp.conf")
    settings = {key.strip(): value.strip() for key, value in (line.split("=", 1) for line in lines)}
    # A packet carries 24 firing sequences of 55.296 us (user manual): 753.5 packets/s, twice that in
    # dual-return mode; even counting only the 1206-byte payloads, 10 s of dual return must fit.
    packets_per_s = 2 * 1e6 / (24 * 55.296)
    assert int(settings["net.core.rmem_max"]) >= 10 * packets_per_s * 1206


# --- /etc/rigd/rig.yaml ---------------------------------------------------------------------------------


def test_rig_yaml_is_a_valid_rig_file() -> None:
    data = yaml.safe_load((DEPLOY / "config" / "rig.yaml").read_text())
    rig = RigConfig.from_yaml(data, "deploy/config/rig.yaml")  # the dataset reader accepts it
    assert rig.camera.kind is CameraKind.EQUIRECTANGULAR
    assert (rig.camera.width, rig.camera.height) == (2048, 1024)
    assert rig.lidar_model == "VLP-16"
    assert rig.initial_guess is not None
    scheme, host, port = data["lidar"]["source"].split(":")
    assert (scheme, host, int(port)) == ("udp", "0.0.0.0", VLP16_DATA_PORT)
    capture = data["capture"]
    assert capture["n"] >= 1 and capture["still_seconds"] > 0 and capture["sweeps"] >= 1


def test_readme_installs_every_file() -> None:
    readme = (DEPLOY / "README.md").read_text()
    for path in DEPLOY.rglob("*"):
        if path.is_file() and path.name != "README.md":
            assert str(path.relative_to(DEPLOY)) in readme, f"{path.name} is not in deploy/README.md"
    assert "/etc/rigd/rig.yaml" in readme
