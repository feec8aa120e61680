"""pcap/pcapng capture files (container via dpkt): reading UDP datagram batches, and writing captures.

Reading is chunked (files of any size stream through). Plain Ethernet/IPv4/UDP frames, which is what a
VLP-16 sends, are parsed for a whole chunk at once with numpy; any other frame (VLAN tag, IPv6, IP
options, cooked or raw link types) goes through dpkt's frame classes one by one.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from operator import itemgetter
from pathlib import Path
from typing import Any, BinaryIO

import dpkt
import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.datagrams import DatagramBatch, PositionDatagram, fault_entry
from drivers.vlp16.errors import CaptureFileError
from drivers.vlp16.layout import DATA_PACKET_SIZE, DATA_PORT, POSITION_PACKET_SIZE, POSITION_PORT
from drivers.vlp16.validate import PacketFault

_PCAP_MAGICS = {0xA1B2C3D4, 0xD4C3B2A1, 0xA1B23C4D, 0x4D3CB2A1, 0xA1B2CD34, 0x34CDB2A1}
_PCAPNG_MAGIC = 0x0A0D0D0A
_ETH_IP_UDP = 14 + 20 + 8  # header bytes of a plain Ethernet/IPv4/UDP frame
_LINK_DECODERS = {
    dpkt.pcap.DLT_EN10MB: dpkt.ethernet.Ethernet,
    dpkt.pcap.DLT_LINUX_SLL: dpkt.sll.SLL,
    276: dpkt.sll2.SLL2,  # LINKTYPE_LINUX_SLL2
    dpkt.pcap.DLT_NULL: dpkt.loopback.Loopback,
    dpkt.pcap.DLT_LOOP: dpkt.loopback.Loopback,
}
_RAW_IP_LINKTYPES = {dpkt.pcap.DLT_RAW, 12, 14, 228, 229}  # raw IP, IPv4, IPv6


@dataclass(frozen=True)
class Ports:
    """Destination UDP ports of data and position packets."""

    data: int = DATA_PORT
    position: int = POSITION_PORT


class _ShortReads:
    """A capture file that remembers the first read it could not fill, as (bytes asked, bytes got).

    dpkt's pcap reader takes a record's length (``incl_len``) on trust: a corrupt one (0xFFFFFFF0) makes it read
    the rest of the file as one frame, and every packet in it would be lost without a word."""

    def __init__(self, fh: BinaryIO) -> None:
        self.fh = fh
        self.short: tuple[int, int] | None = None

    def read(self, n: int = -1) -> bytes:
        data = self.fh.read(n)
        if 0 < n and len(data) < n and self.short is None and data:
            self.short = (n, len(data))
        return data

    def __getattr__(self, name: str) -> Any:
        return getattr(self.fh, name)


@contextmanager
def _open_reader(path: Path) -> Iterator[tuple[Iterable[tuple[float, bytes]], int, _ShortReads]]:
    """Yield (record iterator, link type, the file read); CaptureFileError if the file is not pcap/pcapng."""
    path = Path(path)
    try:
        fh = _ShortReads(path.open("rb"))
    except OSError as exc:
        raise CaptureFileError(f"{path}: cannot open capture ({exc.strerror})") from exc
    with fh.fh:
        head = fh.read(4)
        magic_le = struct.unpack("<I", head)[0] if len(head) == 4 else None
        fh.seek(0)
        try:
            if magic_le in _PCAP_MAGICS:
                reader: dpkt.pcap.Reader | dpkt.pcapng.Reader = dpkt.pcap.Reader(fh)
            elif magic_le == _PCAPNG_MAGIC:
                reader = dpkt.pcapng.Reader(fh)
            else:
                raise CaptureFileError(
                    f"{path}: not a pcap or pcapng file (starts with {head.hex() or 'nothing'})"
                )
        except (ValueError, dpkt.UnpackError, struct.error) as exc:
            raise CaptureFileError(f"{path}: corrupt pcap/pcapng header ({exc})") from exc
        linktype = reader.datalink()
        if linktype not in _LINK_DECODERS and linktype not in _RAW_IP_LINKTYPES:
            raise CaptureFileError(
                f"{path}: unsupported link type {linktype} (Ethernet, Linux cooked, "
                "loopback and raw IP are supported)"
            )
        yield reader, linktype, fh


def _u16(rows: NDArray[np.uint8], offset: int) -> NDArray[np.int64]:
    return (rows[:, offset].astype(np.int64) << 8) | rows[:, offset + 1]


def _plain_udp(rows: NDArray[np.uint8]) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64]]:
    """For (n,L) Ethernet frames: which are plain unfragmented IPv4/UDP, their dst port and payload size.

    The IP total length is not checked: pre-2015 VLP-16 firmware writes 1234 in position packets too.
    """
    length = rows.shape[1]
    udp_len = _u16(rows, 38)
    plain = (
        (_u16(rows, 12) == 0x0800)
        & (rows[:, 14] == 0x45)
        & (rows[:, 23] == 17)
        & ((rows[:, 20] & 0x3F) == 0)
        & (rows[:, 21] == 0)  # no "more fragments", offset 0
        & (udp_len >= 8)
        & (udp_len - 8 <= length - _ETH_IP_UDP)
    )
    return plain, _u16(rows, 36), udp_len - 8


class _ChunkRouter:
    """Collects the datagrams of one chunk of records, routed by port and size."""

    def __init__(self, ports: Ports) -> None:
        self.ports = ports
        self.data_rows: list[NDArray[np.uint8]] = []
        self.data_records: list[NDArray[np.int64]] = []
        self.positions: list[tuple[int, bytes]] = []
        self.bad_size: list[int] = []
        self.truncated: list[int] = []
        self.frame_errors: list[int] = []
        self.other = 0
        self.fragments = 0

    def add_rows(
        self,
        records: NDArray[np.int64],
        rows: NDArray[np.uint8],
        dport: NDArray[np.int64],
        size: NDArray[np.int64],
    ) -> None:
        """Route plain frames given as rows; the UDP payload starts at byte 42."""
        data = (dport == self.ports.data) & (size == DATA_PACKET_SIZE)
        position = (dport == self.ports.position) & (size == POSITION_PACKET_SIZE)
        ours = (dport == self.ports.data) | (dport == self.ports.position)
        if data.any():
            self.data_rows.append(rows[data, _ETH_IP_UDP : _ETH_IP_UDP + DATA_PACKET_SIZE])
            self.data_records.append(records[data])
        for i in np.flatnonzero(position):
            self.positions.append(
                (int(records[i]), rows[i, _ETH_IP_UDP : _ETH_IP_UDP + POSITION_PACKET_SIZE].tobytes())
            )
        self.bad_size.extend(records[ours & ~data & ~position].tolist())
        self.other += int(np.count_nonzero(~ours))

    def add_datagram(self, record: int, dport: int, payload: bytes) -> None:
        if dport == self.ports.data and len(payload) == DATA_PACKET_SIZE:
            self.data_rows.append(np.frombuffer(payload, np.uint8)[None])
            self.data_records.append(np.array([record]))
        elif dport == self.ports.position and len(payload) == POSITION_PACKET_SIZE:
            self.positions.append((record, payload))
        elif dport in (self.ports.data, self.ports.position):
            self.bad_size.append(record)
        else:
            self.other += 1

    def batch(self, first_record: int, host_s: NDArray[np.float64]) -> DatagramBatch:
        """The chunk's datagrams in record order (fast and slow paths each kept their own order)."""
        records = np.concatenate(self.data_records) if self.data_records else np.empty(0, np.int64)
        data = np.concatenate(self.data_rows) if self.data_rows else np.empty((0, DATA_PACKET_SIZE), np.uint8)
        if np.any(np.diff(records) < 0):
            order = np.argsort(records, kind="stable")
            records, data = records[order], data[order]
        positions = tuple(
            PositionDatagram(payload, float(host_s[r - first_record]), r)
            for r, payload in sorted(self.positions, key=itemgetter(0))
        )
        faults = (
            fault_entry(PacketFault.SIZE, np.array(self.bad_size, np.int64))
            + fault_entry(PacketFault.TRUNCATED, np.array(self.truncated, np.int64))
            + fault_entry(PacketFault.FRAME, np.array(self.frame_errors, np.int64))
        )
        return DatagramBatch(
            data, host_s[records - first_record], records, positions, faults, self.other, self.fragments
        )


def _parse_one(router: _ChunkRouter, record: int, frame: bytes, linktype: int) -> None:
    """Slow path: one frame through dpkt's classes."""
    try:
        if linktype in _RAW_IP_LINKTYPES:
            packet = dpkt.ip6.IP6(frame) if frame[:1] and frame[0] >> 4 == 6 else dpkt.ip.IP(frame)
        else:
            packet = _LINK_DECODERS[linktype](frame)
    except (dpkt.UnpackError, struct.error, IndexError):
        router.frame_errors.append(record)
        return
    ip = packet if isinstance(packet, dpkt.ip.IP | dpkt.ip6.IP6) else getattr(packet, "data", None)
    if not isinstance(ip, dpkt.ip.IP | dpkt.ip6.IP6):
        router.other += 1
        return
    if isinstance(ip, dpkt.ip.IP) and (ip.mf or ip.offset):
        # Counted apart from "other": a fragment may hold part of a data packet, and it is not reassembled.
        router.fragments += 1
        return
    udp = ip.data
    if not isinstance(udp, dpkt.udp.UDP):
        if (
            isinstance(udp, bytes)
            and (ip.p if isinstance(ip, dpkt.ip.IP) else ip.nxt) == dpkt.ip.IP_PROTO_UDP
        ):
            router.truncated.append(record)  # dpkt leaves a cut-short UDP header as bytes
        else:
            router.other += 1
        return
    payload = bytes(udp.data)
    if len(payload) < udp.ulen - 8:
        router.truncated.append(record)
    else:
        router.add_datagram(record, udp.dport, payload[: udp.ulen - 8])


def _route_chunk(
    frames: list[bytes], host_s: NDArray[np.float64], first_record: int, linktype: int, ports: Ports
) -> DatagramBatch:
    router = _ChunkRouter(ports)
    records = first_record + np.arange(len(frames), dtype=np.int64)
    lengths = np.fromiter(map(len, frames), dtype=np.int64, count=len(frames))
    slow = np.ones(len(frames), dtype=bool)
    if linktype == dpkt.pcap.DLT_EN10MB:
        for length in np.unique(lengths[lengths >= _ETH_IP_UDP]):
            group = np.flatnonzero(lengths == length)
            picked = itemgetter(*group)(frames) if len(group) > 1 else (frames[group[0]],)
            rows = np.frombuffer(b"".join(picked), dtype=np.uint8).reshape(len(group), int(length))
            plain, dport, size = _plain_udp(rows)
            router.add_rows(records[group[plain]], rows[plain], dport[plain], size[plain])
            slow[group[plain]] = False
    for i in np.flatnonzero(slow):
        _parse_one(router, int(records[i]), frames[i], linktype)
    return router.batch(first_record, host_s)


@dataclass
class CaptureSummary:
    """Filled while reading: ``records`` read and whether the file ended inside a record."""

    records: int = 0
    truncated_tail: bool = False
    unread: str = ""  # what of the file was not read, when a record was cut short (the file's end, or its length)


def read_batches(
    path: Path, ports: Ports | None = None, chunk_records: int = 4096, summary: CaptureSummary | None = None
) -> Iterator[DatagramBatch]:
    """Yield the UDP datagrams of a pcap/pcapng file in chunks; raises CaptureFileError if unreadable.

    Datagram indices are 0-based record numbers in the file. A file that ends inside a record yields
    what came before it and one TRUNCATED fault.
    """
    summary = summary if summary is not None else CaptureSummary()
    ports = ports or Ports()
    with _open_reader(path) as (reader, linktype, source):
        iterator = iter(reader)
        while True:
            frames: list[bytes] = []
            stamps: list[float] = []
            try:
                for stamp, frame in iterator:
                    if source.short is not None:  # the record claims more than the file holds: it is not one
                        summary.truncated_tail = True
                        asked, got = source.short
                        summary.unread = (f"record {summary.records + len(frames)} claims {asked} bytes, the file "
                                          f"holds {got} more: they were not read")
                        break
                    stamps.append(float(stamp))
                    frames.append(frame)
                    if len(frames) == chunk_records:
                        break
            except (dpkt.UnpackError, ValueError, struct.error):
                summary.truncated_tail = True
            first = summary.records
            summary.records += len(frames)
            if frames:
                yield _route_chunk(frames, np.asarray(stamps, dtype=np.float64), first, linktype, ports)
            if summary.truncated_tail:
                yield DatagramBatch(faults=((PacketFault.TRUNCATED, 1, summary.records),))
                return
            if len(frames) < chunk_records:
                return


def udp_frame(
    payload: bytes,
    dport: int,
    source: tuple[str, int] = ("192.168.1.201", DATA_PORT),
    destination: str = "255.255.255.255",
) -> bytes:
    """An Ethernet/IPv4/UDP frame as the sensor sends it (Velodyne MAC prefix 60:76:88, broadcast)."""
    udp = dpkt.udp.UDP(sport=source[1], dport=dport, data=payload)
    udp.ulen = len(udp)
    ip = dpkt.ip.IP(
        src=socket.inet_aton(source[0]),
        dst=socket.inet_aton(destination),
        p=dpkt.ip.IP_PROTO_UDP,
        ttl=64,
        data=udp,
    )
    ip.len = len(ip)
    return bytes(
        dpkt.ethernet.Ethernet(
            src=b"\x60\x76\x88\x00\x00\x01", dst=b"\xff" * 6, type=dpkt.ethernet.ETH_TYPE_IP, data=ip
        )
    )


def write_pcap(path: Path, datagrams: Iterable[tuple[float, int, bytes]]) -> int:
    """Write (time s, destination port, payload) datagrams as a classic pcap file; returns the count."""
    count = 0
    try:
        with Path(path).open("wb") as fh:
            writer = dpkt.pcap.Writer(fh, snaplen=65535, linktype=dpkt.pcap.DLT_EN10MB)
            for time_s, dport, payload in datagrams:
                writer.writepkt(udp_frame(payload, dport), ts=time_s)
                count += 1
    except OSError as exc:
        raise CaptureFileError(f"{path}: cannot write capture ({exc.strerror})") from exc
    return count


def read_datagrams(path: Path, ports: Ports | None = None) -> Iterator[tuple[float, int, bytes]]:
    """(host time s, destination port, payload) of the data and position datagrams of a capture, in file
    order: the input :func:`drivers.vlp16.sender.send_datagrams` replays. Wrong-size ones are skipped."""
    ports = ports or Ports()
    for batch in read_batches(path, ports):
        merged = [
            (int(i), float(t), ports.data, row.tobytes())
            for i, t, row in zip(batch.data_index, batch.data_host_s, batch.data, strict=True)
        ]
        merged += [(p.number, p.host_s, ports.position, p.payload) for p in batch.positions]
        for _, time_s, port, payload in sorted(merged, key=itemgetter(0)):
            yield time_s, port, payload
