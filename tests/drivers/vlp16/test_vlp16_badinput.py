"""Bad input is counted and reported, never raised past the driver, and the good packets around it decode."""

from __future__ import annotations

import re
import struct
from pathlib import Path

import dpkt
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from vlp16_helpers import SMALL_PCAP, assemble, batch_of, synthetic_firings

from drivers.vlp16 import (
    DatagramBatch,
    LaserCalibration,
    PacketFault,
    PcapReplay,
    PositionDatagram,
    PpsStatus,
    ReturnMode,
    Vlp16Config,
    decode_packets,
    encode_data_packets,
    encode_position_packet,
    load_calibration,
    read_sweeps,
    write_pcap,
)
from drivers.vlp16.errors import CalibrationFileError, CaptureFileError, EncodeError
from drivers.vlp16.pcap import udp_frame


def all_points(path: Path, config: Vlp16Config | None = None) -> tuple[np.ndarray, object]:
    sweeps, stats = read_sweeps(path, config)
    return np.concatenate([s.points for s in sweeps]) if sweeps else np.empty(0), stats


def clean_packets(count: int = 80):
    f = synthetic_firings(count * 24)
    return encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 1_700_000_000.0)


def test_truncated_last_record_is_reported_and_the_rest_decodes(tmp_path: Path) -> None:
    data = SMALL_PCAP.read_bytes()
    full, _ = all_points(SMALL_PCAP)
    for cut, where in (
        (len(data) - 500, "inside the frame"),
        (len(data) - 1248 - 8, "inside the record header"),
    ):
        path = tmp_path / f"cut{cut}.pcap"
        path.write_bytes(data[:cut])
        points, stats = all_points(path)
        assert stats.faults == {PacketFault.TRUNCATED: 1}, where
        assert stats.first_fault[PacketFault.TRUNCATED] == 83, where
        assert stats.data_packets == 83
        assert np.array_equal(points, full[: len(points)]) and 0 < len(full) - len(points) <= 384


def test_a_record_claiming_more_than_the_file_holds_is_reported(tmp_path: Path) -> None:
    """incl_len 0xFFFFFFF0 in the second record: dpkt would read the rest of the file as one frame, and the 83
    packets in it were lost while the summary said "bad packets: 0"."""
    data = bytearray(SMALL_PCAP.read_bytes())
    second = 24 + 16 + struct.unpack_from("<I", data, 24 + 8)[0]  # the file header, the first record
    struct.pack_into("<I", data, second + 8, 0xFFFFFFF0)
    path = tmp_path / "corrupt.pcap"
    path.write_bytes(bytes(data))
    replay = PcapReplay(path)
    list(replay)
    assert replay.stats.faults == {PacketFault.TRUNCATED: 1} and replay.stats.first_fault[PacketFault.TRUNCATED] == 1
    assert replay.stats.data_packets == 1
    assert re.fullmatch(r"record 1 claims 4294967280 bytes, the file holds \d+ more: they were not read",
                        replay.summary.unread)


@pytest.mark.parametrize(
    "content",
    [b"", b"hello, not a capture at all\n", b"\xd4\xc3\xb2\xa1\x02"],
    ids=["empty", "text", "short header"],
)
def test_not_a_capture_raises_a_clear_error(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "bad.pcap"
    path.write_bytes(content)
    with pytest.raises(CaptureFileError, match="bad.pcap"):
        list(PcapReplay(path))


def test_missing_file_and_unsupported_link_type(tmp_path: Path) -> None:
    with pytest.raises(CaptureFileError, match="cannot open"):
        list(PcapReplay(tmp_path / "nope.pcap"))
    path = tmp_path / "tokenring.pcap"
    with path.open("wb") as fh:
        dpkt.pcap.Writer(fh, linktype=6).writepkt(b"\0" * 60, ts=0.0)
    with pytest.raises(CaptureFileError, match="link type 6"):
        list(PcapReplay(path))


def test_header_only_capture_gives_no_sweeps(tmp_path: Path) -> None:
    path = tmp_path / "empty.pcap"
    write_pcap(path, [])
    points, stats = all_points(path)
    assert len(points) == 0 and stats.data_packets == 0 and stats.bad_packets == 0


def corrupt(payload: np.ndarray, offset: int, value: int) -> bytes:
    out = payload.copy()
    out[offset] = value
    return out.tobytes()


def test_bad_packets_and_garbage_datagrams_are_counted_and_good_ones_decode(tmp_path: Path) -> None:
    packets = clean_packets()
    p, t = packets.payloads, packets.time_s
    rng = np.random.default_rng(3)
    bad = {  # record index in the written file -> datagram
        10: (2368, p[10].tobytes()[:1000]),  # short
        11: (2368, p[11].tobytes() + b"\0"),  # long
        20: (2368, corrupt(p[20], 100, 0x00)),  # block 1 flag
        30: (2368, corrupt(p[30], 3, 0x95)),  # block 0 azimuth 0x95xx > 36000
        40: (2368, corrupt(p[40], 1204, 0x40)),  # return mode
        50: (2368, corrupt(p[50], 1205, 0x28)),  # product id
        60: (2368, rng.integers(0, 256, 1206, dtype=np.uint8).tobytes()),  # garbage of the right size
        61: (8308, rng.integers(0, 256, 77, dtype=np.uint8).tobytes()),  # short position packet
        62: (9999, b"other traffic"),
    }
    datagrams = [bad.get(i, (2368, p[i].tobytes())) for i in range(len(p))]
    datagrams += [(2368, p[i].tobytes()) for i in (20, 30, 40, 50, 60)]  # resend the damaged ones, late
    path = tmp_path / "mixed.pcap"
    write_pcap(
        path, [(float(t[min(i, len(t) - 1)]), port, payload) for i, (port, payload) in enumerate(datagrams)]
    )
    points, stats = all_points(path)
    assert stats.faults[PacketFault.SIZE] == 3 and stats.first_fault[PacketFault.SIZE] == 10
    assert stats.faults[PacketFault.FLAG] == 2  # the damaged flag and (almost surely) the garbage
    assert stats.first_fault[PacketFault.FLAG] == 20
    for fault, index in (
        (PacketFault.AZIMUTH, 30),
        (PacketFault.RETURN_MODE, 40),
        (PacketFault.PRODUCT_ID, 50),
    ):
        assert stats.faults[fault] == 1 and stats.first_fault[fault] == index
    assert stats.other_datagrams == 1
    # Packets 10, 11, 61, 62 were replaced by bad ones and never resent: their points are missing.
    lost = [10, 11, 61, 62]
    expected = decode_packets(np.delete(p, lost, axis=0)).points
    assert len(points) == len(expected)
    assert stats.missing_packets == len(lost)


HOUR_US = 3_600_000_000  # the device counts microseconds past the hour, 0 .. HOUR_US - 1


def test_a_timestamp_past_the_hour_is_counted_and_dropped() -> None:
    """A stamp >= 3.6e9 us used to be unwrapped modulo the hour: one such packet made a phantom sweep 98 s on."""
    f = synthetic_firings(80 * 24)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 1_699_999_300.0)  # 100 s past the hour
    p = packets.payloads.copy()
    stamp = struct.unpack_from("<I", p[40].tobytes(), 1200)[0]
    for index, bad in ((40, stamp + 98_000_000 + HOUR_US), (50, HOUR_US)):
        p[index, 1200:1204] = np.frombuffer(struct.pack("<I", bad), np.uint8)
    sweeps, assembler = assemble([batch_of(p, packets.time_s)])
    stats = assembler.stats()
    assert stats.faults == {PacketFault.TIMESTAMP: 2} and stats.first_fault == {PacketFault.TIMESTAMP: 40}
    assert sweeps[-1].end.device - sweeps[0].start.device < 0.2  # 80 packets: 0.1 s, no sweep 98 s later
    expected = decode_packets(np.delete(packets.payloads, [40, 50], axis=0)).points
    assert sum(len(s.points) for s in sweeps) == len(expected)


def test_a_position_packet_stamped_past_the_hour_is_counted() -> None:
    good = encode_position_packet(5_000_000, PpsStatus.LOCKED, "")
    bad = bytearray(good)
    bad[198:202] = struct.pack("<I", HOUR_US + 5_000_000)
    positions = (PositionDatagram(good, 0.0, 0), PositionDatagram(bytes(bad), 0.0, 7))
    _, assembler = assemble([DatagramBatch(positions=positions)])
    stats = assembler.stats()
    assert stats.position_packets == 1
    assert stats.faults == {PacketFault.POSITION: 1} and stats.first_fault == {PacketFault.POSITION: 7}


def test_frames_that_are_not_udp_or_are_cut_short(tmp_path: Path) -> None:
    packets = clean_packets(30)
    frames = [udp_frame(p.tobytes(), 2368) for p in packets.payloads]
    arp = bytes(dpkt.ethernet.Ethernet(type=dpkt.ethernet.ETH_TYPE_ARP, data=b"\0" * 28))
    cut = frames[5][:300]  # snap-length style: record shorter than the frame
    runt = b"\x01\x02\x03"
    path = tmp_path / "frames.pcap"
    with path.open("wb") as fh:
        writer = dpkt.pcap.Writer(fh, snaplen=65535)
        for i, frame in enumerate(frames):
            writer.writepkt(cut if i == 5 else frame, ts=float(packets.time_s[i]))
        for extra in (arp, runt):
            writer.writepkt(extra, ts=float(packets.time_s[-1]))
    points, stats = all_points(path)
    assert stats.faults == {PacketFault.TRUNCATED: 1, PacketFault.FRAME: 1}
    assert stats.first_fault == {PacketFault.TRUNCATED: 5, PacketFault.FRAME: 31}
    assert stats.other_datagrams == 1 and stats.data_packets == 29


def fragmented(payload: bytes, dport: int, split: int) -> list[bytes]:
    """The Ethernet frames of ``payload`` sent to ``dport`` as one IPv4 datagram in fragments of ``split`` bytes."""
    frame = dpkt.ethernet.Ethernet(udp_frame(payload, dport))
    datagram = bytes(frame.data.data)  # UDP header and payload, what the fragments carry
    frames = []
    for offset in range(0, len(datagram), split):
        ip = dpkt.ip.IP(
            src=frame.data.src,
            dst=frame.data.dst,
            p=dpkt.ip.IP_PROTO_UDP,
            id=7,
            ttl=64,
            data=datagram[offset : offset + split],
        )
        ip.mf, ip.offset = int(offset + split < len(datagram)), offset
        ip.len = len(ip)
        frames.append(bytes(dpkt.ethernet.Ethernet(src=frame.src, dst=frame.dst, type=frame.type, data=ip)))
    return frames


def test_ipv4_fragments_are_counted_apart_from_other_traffic(tmp_path: Path) -> None:
    packets = clean_packets(30)
    frames = [udp_frame(p.tobytes(), 2368) for p in packets.payloads]
    pieces = fragmented(packets.payloads[10].tobytes(), 2368, 600)  # 1214 bytes of UDP: 3 fragments
    frames[10:11] = pieces
    frames.append(udp_frame(b"other traffic", 9999))
    path = tmp_path / "fragments.pcap"
    with path.open("wb") as fh:
        writer = dpkt.pcap.Writer(fh, snaplen=65535)
        for i, frame in enumerate(frames):
            writer.writepkt(frame, ts=float(packets.time_s[min(i, 29)]))
    points, stats = all_points(path)
    assert len(pieces) == 3 and stats.ipv4_fragments == 3
    assert stats.other_datagrams == 1 and stats.bad_packets == 0 and stats.data_packets == 29
    assert stats.notes == ("3 IPv4 fragments skipped (fragmented datagrams are not reassembled)",)
    assert len(points) == len(decode_packets(np.delete(packets.payloads, 10, axis=0)).points)
    assert all_points(SMALL_PCAP)[1].notes == ()


def test_pcapng_vlan_and_cooked_captures_read_like_plain_pcap(tmp_path: Path) -> None:
    packets = clean_packets(60)
    plain = tmp_path / "plain.pcap"
    write_pcap(
        plain, [(float(t), 2368, p.tobytes()) for t, p in zip(packets.time_s, packets.payloads, strict=True)]
    )
    expected, _ = all_points(plain)
    frames = [dpkt.ethernet.Ethernet(udp_frame(p.tobytes(), 2368)) for p in packets.payloads]
    ng = tmp_path / "capture.pcapng"
    with ng.open("wb") as fh:
        writer = dpkt.pcapng.Writer(fh)
        for t, frame in zip(packets.time_s, frames, strict=True):
            writer.writepkt(bytes(frame), ts=float(t))
    vlan = tmp_path / "vlan.pcap"
    with vlan.open("wb") as fh:
        writer = dpkt.pcap.Writer(fh, snaplen=65535)
        for t, frame in zip(packets.time_s, frames, strict=True):
            tagged = bytes(frame)[:12] + struct.pack(">HH", 0x8100, 7) + bytes(frame)[12:]
            writer.writepkt(tagged, ts=float(t))
    cooked = tmp_path / "sll.pcap"
    with cooked.open("wb") as fh:
        writer = dpkt.pcap.Writer(fh, snaplen=65535, linktype=dpkt.pcap.DLT_LINUX_SLL)
        for t, frame in zip(packets.time_s, frames, strict=True):
            writer.writepkt(bytes(dpkt.sll.SLL(ethtype=0x0800, data=frame.data)), ts=float(t))
    for path in (ng, vlan, cooked):
        points, stats = all_points(path)
        assert stats.bad_packets == 0 and stats.data_packets == 60, path.name
        assert np.array_equal(points, expected), path.name


@settings(max_examples=25, deadline=None)
@given(st.lists(st.binary(min_size=1206, max_size=1206), min_size=1, max_size=6), st.booleans())
def test_random_datagrams_never_raise(blobs: list[bytes], any_product: bool) -> None:
    payloads = np.frombuffer(b"".join(blobs), np.uint8).reshape(len(blobs), 1206)
    config = Vlp16Config(product_ids=None if any_product else frozenset({0x22}))
    sweeps, assembler = assemble([batch_of(payloads, np.arange(len(blobs), dtype=float))], config)
    stats = assembler.stats()
    assert stats.data_packets + stats.bad_packets == len(blobs)
    assert sum(s.packet_count for s in sweeps) >= stats.data_packets


def test_malformed_calibration_files(tmp_path: Path) -> None:
    nominal = LaserCalibration()
    good = "lasers:\n" + "".join(
        f"  - {{laser_id: {i}, vert_correction: {float(np.radians(e))!r}}}\n"
        for i, e in enumerate(nominal.elevation_deg)
    )
    (tmp_path / "good.yaml").write_text(good)
    assert np.allclose(load_calibration(tmp_path / "good.yaml").elevation_deg, nominal.elevation_deg)
    cases = {
        "missing.yaml": None,
        "notyaml.yaml": "lasers: [unclosed",
        "short.yaml": "lasers:\n  - {laser_id: 0, vert_correction: 0.1}\n",
        "rot.yaml": good.replace("laser_id: 3,", "laser_id: 3, rot_correction: 0.01,"),
        "dup.yaml": good.replace("laser_id: 3,", "laser_id: 4,"),
        "range.yaml": good.replace("laser_id: 3,", "laser_id: 16,"),
        "resolution.yaml": "distance_resolution: 0.001\n" + good,
    }
    for name, text in cases.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        with pytest.raises(CalibrationFileError, match=name):
            load_calibration(tmp_path / name)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("vert_correction", ".nan", r"laser 3: vert_correction must be a finite number, got nan$"),
        ("vert_correction", "-.inf", r"laser 3: vert_correction must be a finite number, got -inf$"),
        ("vert_correction", "null", r"laser 3: vert_correction must be a finite number, got None$"),
        ("vert_offset_correction", ".nan", r"laser 3: vert_offset_correction must be a finite number, got nan$"),
        ("rot_correction", ".nan", r"laser 3: rot_correction must be a finite number, got nan$"),
        ("laser_id", ".nan", r"laser_id must be an integer 0\.\.15$"),
        ("laser_id", "2.5", r"laser_id must be an integer 0\.\.15$"),
    ],
)
def test_a_non_finite_calibration_number_names_the_laser_and_field(
    tmp_path: Path, field: str, value: str, message: str
) -> None:
    """A NaN vert_correction used to be reported as "laser ids must be 0..15, each once"."""
    entries = [
        {"laser_id": str(i), "vert_correction": repr(float(np.radians(e))), "vert_offset_correction": "0.0"}
        for i, e in enumerate(LaserCalibration().elevation_deg)
    ]
    entries[3][field] = value
    text = "lasers:\n" + "".join("  - {" + ", ".join(f"{k}: {v}" for k, v in e.items()) + "}\n" for e in entries)
    path = tmp_path / "VLP16db.yaml"
    path.write_text(text)
    with pytest.raises(CalibrationFileError, match=f"^{re.escape(str(path))}: .*{message}"):
        load_calibration(path)


def test_a_nan_distance_resolution_and_a_repeated_laser_are_named(tmp_path: Path) -> None:
    good = "lasers:\n" + "".join(f"  - {{laser_id: {i}, vert_correction: 0.0}}\n" for i in range(16))
    path = tmp_path / "VLP16db.yaml"
    path.write_text("distance_resolution: .nan\n" + good)
    with pytest.raises(CalibrationFileError, match=r"distance_resolution nan is not the VLP-16's 0\.002 m"):
        load_calibration(path)
    path.write_text(good.replace("laser_id: 4,", "laser_id: 3,"))
    with pytest.raises(CalibrationFileError, match=r"laser 3 is listed twice"):
        load_calibration(path)


def test_encoder_rejects_bad_arrays() -> None:
    f = synthetic_firings(24)
    with pytest.raises(EncodeError, match="ranges_m"):
        encode_data_packets(f.ranges_m[:, :8], f.reflectivity, f.azimuth_deg, 0.0)
    with pytest.raises(EncodeError, match="reflectivity"):
        encode_data_packets(f.ranges_m, f.reflectivity.astype(int) + 300, f.azimuth_deg, 0.0)
    with pytest.raises(EncodeError, match="azimuth"):
        encode_data_packets(f.ranges_m, f.reflectivity, np.full(24, np.nan), 0.0)
    ranges = f.ranges_m.copy()
    ranges[0, :4] = [np.inf, -1.0, 200.0, np.nan]  # returns a VLP-16 cannot report become "no return"
    decoded = decode_packets(
        encode_data_packets(ranges, f.reflectivity, f.azimuth_deg, 0.0, ReturnMode.LAST).payloads
    ).points
    assert len(decoded) == np.count_nonzero(np.isfinite(ranges) & (ranges > 0) & (ranges < 131))


def test_empty_batches_are_harmless() -> None:
    sweeps, assembler = assemble([DatagramBatch(), DatagramBatch(other=3)])
    assert sweeps == [] and assembler.stats().other_datagrams == 3
