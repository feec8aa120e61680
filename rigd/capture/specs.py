"""Sensor source strings: ``--lidar udp[:HOST:PORT[:POSITION_PORT]] | pcap:FILE | sim[:FILE]`` and
``--camera sdk | replay:DIR | sim[:FILE]``."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from pathlib import Path

from drivers.vlp16 import DATA_PORT, POSITION_PORT
from rigd.capture.errors import SourceSpecError

LIDAR_FORMS = "udp[:HOST:PORT[:POSITION_PORT]] | pcap:FILE | sim[:FILE]"
CAMERA_FORMS = "sdk | replay:DIR | sim[:FILE]"


class LidarKind(Enum):
    UDP = "udp"
    PCAP = "pcap"
    SIM = "sim"


class CameraKind(Enum):
    SDK = "sdk"
    REPLAY = "replay"
    SIM = "sim"


@dataclass(frozen=True)
class LidarSpec:
    """Where VLP-16 packets come from: a UDP bind address and ports, a capture file, or the simulated rig
    (``path``: its sim rig file, None for the default rig)."""

    kind: LidarKind
    host: str = "0.0.0.0"
    data_port: int = DATA_PORT
    position_port: int = POSITION_PORT
    path: Path | None = None

    def __str__(self) -> str:
        if self.kind is LidarKind.UDP:
            return f"udp:{self.host}:{self.data_port}:{self.position_port}"
        kind: str = self.kind.value
        return kind + (f":{self.path}" if self.path else "")


@dataclass(frozen=True)
class CameraSpec:
    """Where panoramas come from: FLIR's SDK, a replay directory, or the simulated rig (``path``: its sim rig
    file, None for the rig simulated in this process)."""

    kind: CameraKind
    path: Path | None = None

    def __str__(self) -> str:
        return self.kind.value + (f":{self.path}" if self.path else "")


def _port(text: str, what: str, spec: str) -> int:
    try:
        port = int(text)
    except ValueError as exc:
        raise SourceSpecError(f"--lidar {spec!r}: {what} must be a number, got {text!r}") from exc
    if not 0 < port < 65536:
        raise SourceSpecError(f"--lidar {spec!r}: {what} must be 1..65535, got {port}")
    return port


def _kind_and_rest(text: str, kinds: type[Enum], option: str, forms: str) -> tuple[Enum, str | None]:
    head, sep, rest = text.partition(":")
    try:
        kind = kinds(head)
    except ValueError as exc:
        raise SourceSpecError(f"{option} {text!r}: unknown source {head!r}; use {forms}") from exc
    return kind, (rest if sep else None)


def parse_lidar(text: str) -> LidarSpec:
    kind, rest = _kind_and_rest(text, LidarKind, "--lidar", LIDAR_FORMS)
    if kind is LidarKind.UDP:
        if rest is None:
            return LidarSpec(LidarKind.UDP)
        parts = rest.split(":")
        if len(parts) not in (2, 3) or not parts[0]:
            raise SourceSpecError(f"--lidar {text!r}: expected udp:HOST:PORT or udp:HOST:PORT:POSITION_PORT")
        position = _port(parts[2], "POSITION_PORT", text) if len(parts) == 3 else POSITION_PORT
        return LidarSpec(LidarKind.UDP, parts[0], _port(parts[1], "PORT", text), position)
    if kind is LidarKind.PCAP:
        if not rest:
            raise SourceSpecError(f"--lidar {text!r}: expected pcap:FILE")
        return LidarSpec(LidarKind.PCAP, path=Path(rest))
    return LidarSpec(LidarKind.SIM, path=Path(rest) if rest else None)


def parse_camera(text: str) -> CameraSpec:
    kind, rest = _kind_and_rest(text, CameraKind, "--camera", CAMERA_FORMS)
    if kind is CameraKind.SDK:
        if rest is not None:
            raise SourceSpecError(f"--camera {text!r}: 'sdk' takes no argument (its settings are in the rig file)")
        return CameraSpec(CameraKind.SDK)
    if kind is CameraKind.REPLAY:
        if not rest:
            raise SourceSpecError(f"--camera {text!r}: expected replay:DIR")
        return CameraSpec(CameraKind.REPLAY, Path(rest))
    return CameraSpec(CameraKind.SIM, Path(rest) if rest else None)
