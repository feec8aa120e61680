"""8-, 12- and 16-bit data converted by the format: RAW12 packed as ladybug.h lays it out, RAW16 with its 12 bits at
the top or the bottom of the word, 12-bit JPEG channels; every result uint16 with its bits at the top, so the 8-bit
view is never 'nearly black'. Buffers are packed by hand here, not by rigd."""

from __future__ import annotations

import struct

import cv2
import imagecodecs
import numpy as np
import pytest

from drivers.ladybug5.channels import block_jpegs, frame_mosaics
from drivers.ladybug5.formats import BayerPattern, DataFormat
from drivers.ladybug5.pgr import DEFAULT_LAYOUT
from drivers.ladybug5.raw import Raw16Bits, SensorGeometry, decode_raw, raw16_bits, to_uint8

COLS, ROWS = 8, 6
GEOMETRY = SensorGeometry(COLS, ROWS)


def values12(seed: int = 0) -> np.ndarray:
    """Six flat-per-camera 12-bit mosaics (flat: exact through demosaicing) with a varied low nibble."""
    return np.stack([np.full((ROWS, COLS), 0x5A3 + 0x151 * c, np.uint16) for c in range(6)])


def pack_raw12(pixels: np.ndarray) -> bytes:
    """ladybug.h's RAW12: 'Px1 (top 8) | Px2 (top 8) | Px1 (bottom 4) | Px2 (bottom 4)', written out byte by byte."""
    flat = pixels.ravel().tolist()
    out = bytearray()
    for p1, p2 in zip(flat[0::2], flat[1::2], strict=True):
        out += bytes([p1 >> 4, p2 >> 4, ((p1 & 0xF) << 4) | (p2 & 0xF)])
    return bytes(out)


def test_raw12_unpacks_by_the_headers_layout():
    pixels = values12()
    images = decode_raw(pack_raw12(pixels), DataFormat.RAW12, GEOMETRY, BayerPattern.RGGB, "t")
    for image, want in zip(images, pixels, strict=True):
        assert image.dtype == np.uint16 and np.all(image == want[0, 0] << 4)  # 12 bits at the top
        assert np.all(to_uint8(image) == want[0, 0] >> 4)  # the 8-bit view keeps the top 8 of 12 bits


def test_raw12_pixel_order_within_a_triplet():
    pixels = np.zeros((6, ROWS, COLS), np.uint16)
    pixels[:, :, 0::2], pixels[:, :, 1::2] = 0xABC, 0x123  # neighbours differ: a swap would show
    data = pack_raw12(pixels)
    assert data[:3] == bytes([0xAB, 0x12, 0xC3])
    from drivers.ladybug5.raw import unpack_raw12
    words = unpack_raw12(data, pixels.size)
    assert words[0] == 0xABC0 and words[1] == 0x1230


@pytest.mark.parametrize(("layout", "shift"), [("low12", 0), ("high", 4)])
def test_raw16_is_read_where_its_bits_are(layout, shift):
    pixels = values12() << shift  # 12-bit data in the low bits (an unpacked RAW12), or at the top
    data = pixels.astype("<u2").tobytes()
    images = decode_raw(data, DataFormat.RAW16, GEOMETRY, BayerPattern.RGGB, "t")
    for image, want in zip(images, values12(), strict=True):
        assert np.all(image == want[0, 0] << 4)
        assert np.all(to_uint8(image) == want[0, 0] >> 4)  # not 'nearly black' either way
    told = Raw16Bits.LOW12 if layout == "low12" else Raw16Bits.HIGH
    assert raw16_bits(pixels) is told


def test_raw16_full_scale_words_and_an_explicit_choice():
    words = np.array([0x0000, 0x8001, 0xFFFF], np.uint16)
    assert raw16_bits(words) is Raw16Bits.HIGH  # beyond 12 bits: 16-bit data as sent
    assert raw16_bits(np.array([0x0010, 0x0FF0], np.uint16)) is Raw16Bits.HIGH  # low nibble unused: bits at the top
    dark = np.array([3, 17, 40], np.uint16)  # could be either: the camera's setting decides
    assert raw16_bits(dark) is Raw16Bits.LOW12 and raw16_bits(dark, Raw16Bits.HIGH) is Raw16Bits.HIGH
    assert to_uint8(np.array([0xFFFF], np.uint16))[0] == 255 and to_uint8(np.array([0x0FFF], np.uint16))[0] == 255


def jpeg12_block(values: list[int], eight_bit_camera: int | None = None, cut_camera: int | None = None) -> bytes:
    """A COLOR_SEP_JPEG12 frame block: camera c's four channels flat 12-bit ``values[c]`` (libjpeg-turbo 12-bit via
    imagecodecs), laid out by hand as in test_ladybug5_channels."""
    header, payload = bytearray(0x340 + 24 * 8), bytearray()
    for c, value in enumerate(values):
        plane = np.full((ROWS // 2, COLS // 2), value, np.uint16)
        jpeg = imagecodecs.jpeg8_encode(plane, level=100, bitspersample=12)
        if c == eight_bit_camera:
            jpeg = cv2.imencode(".jpg", (plane >> 4).astype(np.uint8))[1].tobytes()
        if c == cut_camera:
            jpeg = jpeg[: len(jpeg) - 20]
        for k in range(4):
            struct.pack_into(">2I", header, 0x340 + 32 * c + 8 * k, len(header) + len(payload), len(jpeg))
            payload += jpeg
    struct.pack_into(">I", header, 0x10, 0xCAFEBABE)
    return bytes(header + payload)


def test_12_bit_jpeg_channels_decode_with_their_bits_at_the_top():
    values = [100, 700, 1500, 2222, 3000, 4095]
    data = jpeg12_block(values)
    cameras = frame_mosaics(block_jpegs(data, 0, len(data), DEFAULT_LAYOUT, "t"), DEFAULT_LAYOUT, bits=12)
    assert cameras.faults == ()
    for mosaic, value in zip(cameras.arrays, values, strict=True):
        assert mosaic is not None and mosaic.dtype == np.uint16
        assert np.abs(mosaic.astype(int) - (value << 4)).max() <= 16 * 2  # lossy 12-bit JPEG: within 2 levels
        assert np.abs(to_uint8(mosaic).astype(int) - (value >> 4)).max() <= 1


def test_12_bit_stream_channels_that_are_not_12_bit_jpegs_are_named():
    data = jpeg12_block([500] * 6, eight_bit_camera=1, cut_camera=4)
    cameras = frame_mosaics(block_jpegs(data, 0, len(data), DEFAULT_LAYOUT, "t"), DEFAULT_LAYOUT, bits=12)
    assert cameras.missing == (1, 4)
    reasons = {str(f) for f in cameras.faults}
    assert "camera 1 channel 0: a 8-bit JPEG in a 12-bit stream" in reasons
    assert "camera 4 channel 3: no JPEG end marker (FF D9): truncated" in reasons


def test_a_16_bit_replay_image_with_12_bit_data_is_not_black(tmp_path):
    from drivers.ladybug5.replay import DirectoryFrameSource
    from drivers.ladybug5.rig import scaled_ladybug5_rig
    from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

    rig = scaled_ladybug5_rig(24)
    (tmp_path / "f").mkdir()
    for i, camera in enumerate(rig.cameras):  # 12-bit values in the low bits of 16-bit PNGs
        cv2.imwrite(str(tmp_path / "f" / f"cam{i}.png"), np.full((camera.height, camera.width, 3), 2001, np.uint16))
    (tmp_path / "timestamps.csv").write_text("image,device_time_s\nf,1.0\n")
    source = DirectoryFrameSource(tmp_path, Stitcher(rig, PanoramaSpec(32, 16)))
    _, sensors = next(source.frames_with_sensors())
    assert sensors is not None and np.all(sensors.images[0] == 2001 >> 4)
