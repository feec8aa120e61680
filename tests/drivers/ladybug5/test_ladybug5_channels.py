"""Channel JPEGs judged as the SDK and public readers judge them: padded lengths are fine, a truncated, garbage or
empty channel loses its camera (named), a frame with five good cameras is kept. The frame blocks and stream files
here are built byte by byte in the test (the layout public readers use), not by rigd's writer."""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest

from drivers.ladybug5.channels import block_jpegs, frame_mosaics
from drivers.ladybug5.errors import CorruptFrameError
from drivers.ladybug5.formats import STREAM_RESOLUTIONS
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, PgrStream
from drivers.ladybug5.replay import PgrFrameSource
from drivers.ladybug5.rig import RigCameras, scaled_ladybug5_rig
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

COLS, ROWS = 24, 20  # a sensor's mosaic (a scaled Ladybug5 head); each channel JPEG is 12x10
TINY = 98  # a resolution code for these sensors, registered for these tests only
HEADER = 0x340 + 24 * 8  # image info and the JPEG table
GREY = 120


@pytest.fixture(autouse=True)
def tiny_resolution(monkeypatch):
    monkeypatch.setitem(STREAM_RESOLUTIONS, TINY, (COLS, ROWS))


def channel_jpeg(value: int = GREY) -> bytes:
    ok, data = cv2.imencode(".jpg", np.full((ROWS // 2, COLS // 2), value, np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 100])
    assert ok
    return data.tobytes()


def block(channels: list[list[bytes]], lengths: dict[tuple[int, int], tuple[int, int]] | None = None,
          sequence: int = 7) -> bytes:
    """A frame block: big-endian size at 0x08, 0xCAFEBABE at 0x10, seconds/µs/sequence at 0x18, the (offset, size)
    table at 0x340 (offsets from the block's start), then the JPEGs. ``lengths`` overrides table entries."""
    head, payload = bytearray(HEADER), bytearray()
    for c in range(6):
        for k in range(4):
            entry = (HEADER + len(payload), len(channels[c][k]))
            struct.pack_into(">2I", head, 0x340 + 32 * c + 8 * k, *(lengths or {}).get((c, k), entry))
            payload += channels[c][k]
    struct.pack_into(">I", head, 0x08, HEADER + len(payload))
    struct.pack_into(">I", head, 0x10, 0xCAFEBABE)
    struct.pack_into(">3I", head, 0x18, 100, 0, sequence)
    return bytes(head + payload)


def stream(path, blocks: list[bytes]) -> None:
    """A .pgr file: signature, head info (little-endian: COLOR_SEP_JPEG8 = 4, RGGB = 3), the frames."""
    info = bytearray(0xBF0)
    data_offset = 16 + len(info)
    for at, value in {0x78: 4, 0x7C: TINY, 0x80: 3, 0x88: len(blocks), 0x94: data_offset}.items():
        struct.pack_into("<I", info, at, value)
    path.write_bytes(b"PGRLADYBUGSTREAM" + bytes(info) + b"".join(blocks))


def good() -> list[list[bytes]]:
    return [[channel_jpeg() for _ in range(4)] for _ in range(6)]


def test_padded_channel_lengths_are_not_corruption():
    channels = good()
    channels[2] = [j + pad for j, pad in zip(channels[2], (bytes(64), b"\xff" * 7, b"\x5a" * 3, bytes(1)),
                                             strict=True)]
    raw = block(channels)
    # camera 5's last channel claims 40 bytes more than the block holds (the padding was never written)
    last = raw.rfind(channels[5][3])
    overrun = block(channels, {(5, 3): (last, len(channels[5][3]) + 40)})
    for data in (raw, overrun):
        cameras = frame_mosaics(block_jpegs(data, 0, len(data), DEFAULT_LAYOUT, "t"), DEFAULT_LAYOUT)
        assert cameras.faults == () and all(np.all(m == GREY) for m in cameras.arrays)


@pytest.mark.parametrize(("damage", "reason"), [
    ("truncated", "camera 1 channel 2: the JPEG decoder refuses it"),
    ("garbage", "camera 1 channel 2: no JPEG start marker (FF D8)"),
    ("unfinished", "camera 1 channel 2: no data (size 0: the camera's JPEG compression did not finish)"),
    ("too small", "camera 1 channel 2: no data (size 0: the camera's JPEG buffer was too small)"),
    ("outside", "camera 1 channel 2: offset 99999 is outside"),
])
def test_a_bad_channel_loses_its_camera_by_name(damage, reason):
    channels = good()
    lengths = {}
    if damage == "truncated":
        channels[1][2] = channels[1][2][: len(channels[1][2]) // 2]
    elif damage == "garbage":
        channels[1][2] = bytes(np.random.default_rng(1).integers(0, 256, 300, dtype=np.uint8))
    elif damage == "unfinished":
        lengths[(1, 2)] = (0, 0)
    elif damage == "too small":
        lengths[(1, 2)] = (4000, 0)
    else:
        lengths[(1, 2)] = (99999, 300)
    data = block(channels, lengths)
    cameras = frame_mosaics(block_jpegs(data, 0, len(data), DEFAULT_LAYOUT, "t"), DEFAULT_LAYOUT)
    assert cameras.missing == (1,) and len(cameras.faults) == 1 and str(cameras.faults[0]).startswith(reason)
    assert cameras.require(5, "t") is cameras
    with pytest.raises(CorruptFrameError, match=f"t: 5 of 6 cameras decode \\(6 needed\\): {reason[:20]}"):
        cameras.require(6, "t")


def test_replay_keeps_five_camera_frames_fills_the_gap_from_the_overlaps_and_counts(tmp_path):
    one_bad, two_bad = good(), good()
    one_bad[2][1] = one_bad[2][1][:40]  # truncated
    two_bad[2][1], two_bad[4][0] = b"\x00" * 50, b"\x00" * 50
    stream(tmp_path / "s.pgr", [block(good(), sequence=1), block(one_bad, sequence=2), block(two_bad, sequence=3)])
    rig = scaled_ladybug5_rig(COLS)
    stitcher = Stitcher(rig, PanoramaSpec(64, 32))
    source = PgrFrameSource(tmp_path / "s.pgr", stitcher)
    frames = list(source.frames())
    assert [f.sequence_id for f in frames] == [1, 2]
    assert (source.skipped.count, source.skipped.partial, source.skipped.channels) == (1, 1, 1)
    assert "frame 1: kept without a camera: camera 2 channel 1: the JPEG decoder refuses" in source.skipped.reasons[0]
    assert "frame 2" in source.skipped.reasons[1] and "camera 4 channel 0" in source.skipped.reasons[1]
    # Every camera sees the same grey: without camera 2 the panorama is that grey wherever another camera sees (its
    # neighbours' weights renormalised in the overlaps, not darkened), and empty where camera 2 alone saw.
    full, partial = frames[0].image.astype(int), frames[1].image.astype(int)
    assert np.all(np.abs(full[stitcher.coverage] - GREY) <= 1)
    others = np.zeros_like(stitcher.coverage)
    for i, camera in enumerate(rig.cameras):
        if i != 2:
            others |= Stitcher(RigCameras(rig.model, (camera,)), PanoramaSpec(64, 32)).coverage
    assert np.all(np.abs(partial[others] - GREY) <= 1) and np.all(partial[~others] == 0)
    assert (stitcher.coverage & ~others).any() and (stitcher.overlap & others).any()


def test_strict_reads_name_the_damage(tmp_path):
    channels = good()
    channels[0][3] = b"\xff\xd8" + bytes(30)
    stream(tmp_path / "s.pgr", [block(channels)])
    pgr = PgrStream(tmp_path / "s.pgr")
    with pytest.raises(CorruptFrameError, match="frame 0 .*5 of 6 cameras decode .*camera 0 channel 3"):
        pgr.camera_images(0)
    assert pgr.frame_images(0, min_cameras=5).missing == (0,)
