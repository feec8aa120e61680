"""Position (GPS) packets: device timestamp, PPS status and the NMEA $GPRMC sentence (UTC date and time)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import reduce

from drivers.vlp16.layout import (
    HOUR_US,
    POSITION_NMEA_OFFSET,
    POSITION_PACKET_SIZE,
    POSITION_PPS_OFFSET,
    POSITION_TIMESTAMP_OFFSET,
    PpsStatus,
)


@dataclass(frozen=True)
class PositionPacket:
    """``timestamp_us`` past the hour (device clock), PPS status, the sentence, its UTC time s (or None)."""

    timestamp_us: int
    pps: PpsStatus
    nmea: str
    utc_s: float | None


def parse_position_packet(payload: bytes) -> PositionPacket | None:
    """Parse a 512-byte position packet; None if its size, PPS byte or timestamp (>= an hour) is invalid (the
    caller counts it)."""
    if len(payload) != POSITION_PACKET_SIZE or payload[POSITION_PPS_OFFSET] > PpsStatus.ERROR:
        return None
    (timestamp_us,) = struct.unpack_from("<I", payload, POSITION_TIMESTAMP_OFFSET)
    if timestamp_us >= HOUR_US:  # the clock would take it modulo the hour and anchor to the wrong time
        return None
    raw = payload[POSITION_NMEA_OFFSET:].split(b"\0", 1)[0]
    nmea = raw.decode("ascii", errors="replace").strip()
    return PositionPacket(timestamp_us, PpsStatus(payload[POSITION_PPS_OFFSET]), nmea, rmc_utc_s(nmea))


def rmc_utc_s(sentence: str) -> float | None:
    """UTC s since the epoch of a valid ('A') $GPRMC/$GNRMC sentence with a correct checksum, else None."""
    body, _, checksum = sentence.lstrip("$").partition("*")
    if checksum and checksum[:2].upper() != f"{reduce(lambda a, c: a ^ ord(c), body, 0):02X}":
        return None
    fields = body.split(",")
    if len(fields) < 10 or not fields[0].endswith("RMC") or fields[2] != "A":
        return None
    clock, date = fields[1], fields[9]
    try:
        stamp = datetime(
            2000 + int(date[4:6]),
            int(date[2:4]),
            int(date[0:2]),
            int(clock[0:2]),
            int(clock[2:4]),
            int(clock[4:6]),
            tzinfo=UTC,
        )
        fraction = float("0" + clock[6:]) if len(clock) > 6 else 0.0
    except ValueError:
        return None
    return stamp.timestamp() + fraction
