"""Velodyne VLP-16 driver: decode -> sweep assembly -> sources (pcap replay, live UDP), plus an encoder.

Typical use::

    from drivers.vlp16 import PcapReplay, Vlp16Config
    for sweep in PcapReplay("capture.pcap", Vlp16Config()):
        sweep.points["x"], sweep.start.device, sweep.missing_packets

See docs/vlp16.md for the packet layout, time handling and the comparison with velodyne-decoder.
"""

from drivers.vlp16.calibration import LaserCalibration, load_calibration
from drivers.vlp16.clock import ClockStep, StepKind, TimePair, TimeSource
from drivers.vlp16.datagrams import DatagramBatch, PositionDatagram
from drivers.vlp16.decode import POINT_DTYPE, Decoded, decode_packets
from drivers.vlp16.encode import EncodedPackets, encode_data_packets, encode_position_packet, gprmc_sentence
from drivers.vlp16.layout import (
    DATA_PACKET_SIZE,
    DATA_PORT,
    LEGACY_PRODUCT_ID,
    POSITION_PACKET_SIZE,
    POSITION_PORT,
    VLP16_PRODUCT_ID,
    PpsStatus,
    ReturnMode,
    ReturnType,
)
from drivers.vlp16.pcap import CaptureSummary, Ports, read_batches, write_pcap
from drivers.vlp16.position import PositionPacket, parse_position_packet
from drivers.vlp16.receiver import UdpReceiver
from drivers.vlp16.replay import PcapReplay, read_sweeps
from drivers.vlp16.sender import send_datagrams
from drivers.vlp16.sweep import StreamStats, Sweep, SweepAssembler, Vlp16Config
from drivers.vlp16.validate import PacketCheck, PacketFault, check_packets

__all__ = [
    "DATA_PACKET_SIZE",
    "DATA_PORT",
    "LEGACY_PRODUCT_ID",
    "POINT_DTYPE",
    "POSITION_PACKET_SIZE",
    "POSITION_PORT",
    "VLP16_PRODUCT_ID",
    "CaptureSummary",
    "ClockStep",
    "DatagramBatch",
    "Decoded",
    "EncodedPackets",
    "LaserCalibration",
    "PacketCheck",
    "PacketFault",
    "PcapReplay",
    "Ports",
    "PositionDatagram",
    "PositionPacket",
    "PpsStatus",
    "ReturnMode",
    "ReturnType",
    "StepKind",
    "StreamStats",
    "Sweep",
    "SweepAssembler",
    "TimePair",
    "TimeSource",
    "UdpReceiver",
    "Vlp16Config",
    "check_packets",
    "decode_packets",
    "encode_data_packets",
    "encode_position_packet",
    "gprmc_sentence",
    "load_calibration",
    "parse_position_packet",
    "read_batches",
    "read_sweeps",
    "send_datagrams",
    "write_pcap",
]
