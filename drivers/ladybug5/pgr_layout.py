"""Where things are in a Ladybug stream file (.pgr): the head info, the frame header, the frame block.

The head info follows the field order of the SDK's ``LadybugStreamHeadInfo`` (ladybugstream.h, 2017): after
the 16-byte signature, little-endian u32s: stream version 0x00, head serial 0x0C, padding size 0x74, data
format 0x78, resolution 0x7C, Bayer (stippled) format 0x80, configuration size 0x84, image count 0x88, first
image offset 0x94, per-frame header size 0xA0; the structure is 0xBF0 bytes and the camera's configuration
(its factory calibration, in the SDK's own format) follows it. Frame blocks are big-endian (see
:class:`PgrLayout`); their layout is from open-source readers of earlier Ladybug models, checked on every frame.

A camera's four JPEGs are its Bayer channels, one per cell of the 2x2 tile, in row order of the frame's stippled
format (:data:`BAYER_CELLS`): a BGGR frame's channel 0 is blue and channel 3 red, an RGGB frame's channel 0 red
and channel 3 blue. Public code agrees: a Ladybug5 driver's colour offset per stippled format, a Ladybug2 stream
reader (a BGGR head: channel 0 blue, 3 red) and a Ladybug3 log player's interleaving of the four channels.
"""

from __future__ import annotations

import mmap
import struct
from dataclasses import dataclass
from enum import Enum

from drivers.ladybug5.formats import BayerPattern
from drivers.ladybug5.raw import Raw16Bits

SIGNATURE = b"PGRLADYBUGSTREAM"
FINGERPRINT = 0xCAFEBABE
NUM_CAMERAS = 6
JPEGS_PER_CAMERA = 4
JPEG_SOI = b"\xff\xd8"
JPEG_EOI = b"\xff\xd9"
# (row, col) in the 2x2 Bayer tile of channel JPEG k: row order, k = 2 row + col (module docstring)
BAYER_CELLS: tuple[tuple[int, int], ...] = ((0, 0), (0, 1), (1, 0), (1, 1))


class FrameHeaderStyle(Enum):
    """What precedes each frame's data in a stream whose head info gives a frame header size (0xA0)."""

    NONE = "none"  # no frame header (size 0, older streams): the frame is the fingerprinted block itself
    INFO = "info"  # the header starts with the image info (size, fingerprint, times), the data follows it
    OPAQUE = "opaque"  # rigd cannot read the header; the JPEG block after it carries the image info


@dataclass(frozen=True)
class PgrLayout:
    """Byte offsets of a .pgr file. Head info: little-endian u32 after the signature. Image info (at the start
    of a JPEG frame block, or of an INFO frame header): big-endian u32 relative to its start. The JPEG entry
    (offset, size) of camera c, slot k is at ``jpeg_table + c * 32 + k * 8``; slot k holds the Bayer cell
    ``slot_cells[k]`` (row, col) of the mosaic (:data:`BAYER_CELLS`; reader and writer both take it from here).
    Decoding choices: ``bayer_pattern`` overrides the stream's own (None: the head info's); ``raw16_bits`` says where
    RAW16 words hold their data (:class:`drivers.ladybug5.raw.Raw16Bits`)."""

    head_version: int = 0x00
    head_serial: int = 0x0C
    head_padding_size: int = 0x74
    head_data_format: int = 0x78
    head_resolution: int = 0x7C
    head_bayer: int = 0x80
    head_config_size: int = 0x84
    head_frame_count: int = 0x88
    head_data_offset: int = 0x94
    head_frame_header_size: int = 0xA0
    head_info_size: int = 0xBF0  # the calibration follows the head info
    frame_size: int = 0x08
    fingerprint: int = 0x10
    seconds: int = 0x18
    microseconds: int = 0x1C
    sequence_id: int = 0x20
    gain: int = 0x28  # 6 x u32 registers
    shutter: int = 0x58  # 6 x u32 registers
    jpeg_table: int = 0x340
    bayer_pattern: BayerPattern | None = None
    slot_cells: tuple[tuple[int, int], ...] = BAYER_CELLS
    raw16_bits: Raw16Bits = Raw16Bits.AUTO

    @property
    def frame_header_size(self) -> int:
        """Bytes of a JPEG frame block's header (image info and the JPEG table)."""
        return self.jpeg_table + NUM_CAMERAS * JPEGS_PER_CAMERA * 8

    @property
    def info_size(self) -> int:
        """Bytes of the image info: up to and including the shutter registers."""
        return self.shutter + NUM_CAMERAS * 4


DEFAULT_LAYOUT = PgrLayout()


def u32be(buf: bytes | bytearray | mmap.mmap, at: int) -> int:
    return int(struct.unpack_from(">I", buf, at)[0])


def u32le(buf: bytes | bytearray | mmap.mmap, at: int) -> int:
    return int(struct.unpack_from("<I", buf, at)[0])
