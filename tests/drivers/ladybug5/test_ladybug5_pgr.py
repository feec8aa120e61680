""".pgr streams as newer SDKs write them: the head info's data format, Bayer pattern, resolution and per-frame
header; RAW8/RAW16 and COLOR_SEP_JPEG8 decoded, other formats named as unsupported."""

from __future__ import annotations

import numpy as np
import pytest
from ladybug5_helpers import BLUE, RED, documented_channel_jpegs, documented_mosaic

from drivers.ladybug5.errors import CorruptFrameError, StreamFormatError, UnsupportedFormatError
from drivers.ladybug5.formats import STREAM_RESOLUTIONS, BayerPattern, DataFormat
from drivers.ladybug5.pgr import (
    DEFAULT_LAYOUT,
    FrameHeaderStyle,
    PgrFrameData,
    PgrStream,
    PgrWriteOptions,
    assemble_mosaic,
    write_pgr,
)
from drivers.ladybug5.pgr_layout import PgrLayout
from drivers.ladybug5.pgr_write import bayer_planes, mosaic_from_bgr
from drivers.ladybug5.replay import PgrFrameSource
from drivers.ladybug5.rig import default_ladybug5_rig
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

COLS, ROWS = 16, 12
TINY = 99  # a resolution code for 16x12 sensors, registered for these tests only


@pytest.fixture(autouse=True)
def tiny_resolution(monkeypatch):
    monkeypatch.setitem(STREAM_RESOLUTIONS, TINY, (COLS, ROWS))


def colours(frame: int) -> list[np.ndarray]:
    """Six flat BGR images, a colour per camera (exact through any demosaicing)."""
    return [np.full((ROWS, COLS, 3), (20 + 30 * c, 100 + frame, 220 - 20 * c), np.uint8) for c in range(6)]


def smooth(frame: int) -> list[np.ndarray]:
    yy, xx = np.mgrid[0:ROWS, 0:COLS]
    return [np.stack([60 + 3 * xx + c, 100 + 2 * yy + frame, 200 - xx - yy], axis=-1).astype(np.uint8)
            for c in range(6)]


def jpeg_frames(n: int = 3, pattern: BayerPattern = BayerPattern.RGGB) -> list[PgrFrameData]:
    return [PgrFrameData(100 + i, 250_000, 7 + i, [bayer_planes(im, quality=100, pattern=pattern)
                                                   for im in smooth(i)]) for i in range(n)]


def raw_frames(fmt: DataFormat, pattern: BayerPattern, n: int = 2) -> list[PgrFrameData]:
    scale = 256 if fmt is DataFormat.RAW16 else 1
    out = []
    for i in range(n):
        mosaics = [mosaic_from_bgr(im.astype(np.uint16) * scale, pattern) for im in colours(i)]
        out.append(PgrFrameData(100 + i, 500_000, 7 + i, gain_raw=(i,) * 6, raw=mosaics))
    return out


def test_head_info_fields_are_read(tmp_path):
    options = PgrWriteOptions(bayer=BayerPattern.BGGR, resolution=(2464, 2048), serial=17123456,
                              frame_header_size=512)
    write_pgr(tmp_path / "s.pgr", jpeg_frames(2, BayerPattern.BGGR), calibration=b"config", options=options)
    header = PgrStream(tmp_path / "s.pgr").header
    assert (header.serial, header.data_format, header.bayer, header.resolution) == (
        17123456, DataFormat.COLOR_SEP_JPEG8, BayerPattern.BGGR, (2464, 2048))
    assert header.frame_header_size == 512 and header.calibration == b"config"


@pytest.mark.parametrize("style", [FrameHeaderStyle.INFO, FrameHeaderStyle.OPAQUE])
def test_a_per_frame_header_is_skipped_not_read_as_damage(tmp_path, style):
    frames = jpeg_frames()
    write_pgr(tmp_path / "old.pgr", frames)
    write_pgr(tmp_path / "new.pgr", frames, options=PgrWriteOptions(frame_header_size=512, frame_header_style=style))
    old, new = PgrStream(tmp_path / "old.pgr"), PgrStream(tmp_path / "new.pgr")
    assert new.style is style and new.damaged == []
    assert [(e.sequence_id, e.device_time_s) for e in new.index] == [(e.sequence_id, e.device_time_s)
                                                                     for e in old.index]
    for a, b in zip(old.camera_images(2), new.camera_images(2), strict=True):
        np.testing.assert_array_equal(a, b)


def test_padding_after_each_frame_is_not_damage(tmp_path):
    write_pgr(tmp_path / "s.pgr", jpeg_frames(), options=PgrWriteOptions(padding_size=300))
    stream = PgrStream(tmp_path / "s.pgr")
    assert len(stream.index) == 3 and stream.damaged == []


@pytest.mark.parametrize("fmt", [DataFormat.RAW8, DataFormat.RAW16])
@pytest.mark.parametrize("pattern", list(BayerPattern))
def test_raw_streams_decode_with_the_streams_bayer_pattern(tmp_path, fmt, pattern):
    options = PgrWriteOptions(data_format=fmt, bayer=pattern, resolution=(COLS, ROWS), frame_header_size=512)
    write_pgr(tmp_path / "s.pgr", raw_frames(fmt, pattern), options=options)
    stream = PgrStream(tmp_path / "s.pgr")
    assert [e.sequence_id for e in stream.index] == [7, 8] and stream.damaged == []
    assert stream.index[1].device_time_s == pytest.approx(101.5) and stream.index[1].exposure.gain_raw == (1,) * 6
    scale = 256 if fmt is DataFormat.RAW16 else 1
    for got, want in zip(stream.camera_images(1), colours(1), strict=True):
        assert got.dtype == (np.uint16 if scale > 1 else np.uint8)
        assert np.all(got == want.astype(np.uint16) * scale)


def test_the_streams_bayer_pattern_matters(tmp_path):
    write_pgr(tmp_path / "s.pgr", jpeg_frames(1, BayerPattern.BGGR), options=PgrWriteOptions(bayer=BayerPattern.BGGR))
    right = PgrStream(tmp_path / "s.pgr").camera_images(0)[0].astype(float)
    wrong = PgrStream(tmp_path / "s.pgr", PgrLayout(bayer_pattern=BayerPattern.RGGB)).camera_images(0)[0].astype(float)
    want = smooth(0)[0].astype(float)
    assert np.abs(right - want).mean() < 3.0
    assert np.abs(wrong[..., ::-1] - want)[2:-2, 2:-2].mean() < 6.0  # red and blue swapped


@pytest.mark.parametrize("pattern", list(BayerPattern))
def test_channel_jpegs_in_the_documented_order_decode_with_blue_as_blue(tmp_path, pattern):
    # Built by hand (not by rigd's writer's mapping): channel k holds the k-th cell of the tile, row by row.
    planes = documented_channel_jpegs(pattern.value, ROWS, COLS)
    options = PgrWriteOptions(bayer=pattern, resolution=(COLS, ROWS))
    write_pgr(tmp_path / "s.pgr", [PgrFrameData(100, 0, 7, [planes] * 6)], options=options)
    stream = PgrStream(tmp_path / "s.pgr")
    mosaic = assemble_mosaic(stream.jpegs(0)[0], stream.layout, "test")
    np.testing.assert_array_equal(mosaic, documented_mosaic(pattern.value, ROWS, COLS))  # every cell in place
    image = stream.camera_images(0)[0].astype(int)
    assert np.all(image[..., 0] == BLUE) and np.all(image[..., 2] == RED)  # blue as blue, red as red


def test_a_stream_without_a_bayer_pattern_says_so(tmp_path):
    write_pgr(tmp_path / "s.pgr", jpeg_frames(1), options=PgrWriteOptions(bayer=None))
    with pytest.raises(StreamFormatError, match="no Bayer pattern.*code 4"):
        PgrStream(tmp_path / "s.pgr").camera_images(0)
    assert PgrStream(tmp_path / "s.pgr", PgrLayout(bayer_pattern=BayerPattern.RGGB)).camera_images(0)


def test_half_height_is_named_unsupported_not_corrupt(tmp_path):
    options = PgrWriteOptions(data_format=DataFormat.COLOR_SEP_HALF_HEIGHT_JPEG12)
    write_pgr(tmp_path / "s.pgr", jpeg_frames(2), options=options)
    stream = PgrStream(tmp_path / "s.pgr")
    assert len(stream.index) == 2  # the frames are found; their pixels are not decoded
    with pytest.raises(UnsupportedFormatError, match="COLOR_SEP_HALF_HEIGHT_JPEG12 is not supported.*COLOR_SEP_JPEG8"):
        stream.camera_images(0)
    rig = default_ladybug5_rig((COLS, ROWS))
    with pytest.raises(UnsupportedFormatError, match="HALF_HEIGHT"):
        PgrFrameSource(tmp_path / "s.pgr", Stitcher(rig, PanoramaSpec(32, 16)))


def test_an_unknown_format_code_is_named(tmp_path):
    write_pgr(tmp_path / "s.pgr", jpeg_frames(1), options=PgrWriteOptions(extra={DEFAULT_LAYOUT.head_data_format: 99}))
    with pytest.raises(StreamFormatError, match="unknown data format code 99"):
        PgrStream(tmp_path / "s.pgr").camera_images(0)


def test_raw_frames_whose_header_has_no_image_info_are_refused(tmp_path):
    options = PgrWriteOptions(data_format=DataFormat.RAW8, resolution=(COLS, ROWS), frame_header_size=512)
    write_pgr(tmp_path / "s.pgr", raw_frames(DataFormat.RAW8, BayerPattern.RGGB), options=options)
    raw = bytearray((tmp_path / "s.pgr").read_bytes())
    raw = raw.replace(b"\xca\xfe\xba\xbe", b"\0\0\0\0")
    (tmp_path / "bad.pgr").write_bytes(bytes(raw))
    with pytest.raises(StreamFormatError, match="no frame block|RAW frames without an image info"):
        PgrStream(tmp_path / "bad.pgr")


def test_a_raw_frame_smaller_than_its_resolution_is_corrupt(tmp_path):
    options = PgrWriteOptions(data_format=DataFormat.RAW8, resolution=(COLS, ROWS), frame_header_size=512,
                              extra={DEFAULT_LAYOUT.head_resolution: 8})  # says 1616x1232
    write_pgr(tmp_path / "s.pgr", raw_frames(DataFormat.RAW8, BayerPattern.RGGB), options=options)
    with pytest.raises(CorruptFrameError, match="six 1616x1232 sensor images need"):
        PgrStream(tmp_path / "s.pgr").camera_images(0)


def test_raw_frames_without_a_frame_header_are_refused(tmp_path):
    options = PgrWriteOptions(data_format=DataFormat.COLOR_SEP_JPEG8)
    write_pgr(tmp_path / "s.pgr", jpeg_frames(1), options=options)
    raw = bytearray((tmp_path / "s.pgr").read_bytes())
    raw[16 + DEFAULT_LAYOUT.head_data_format] = 1  # says RAW8, no frame header
    (tmp_path / "bad.pgr").write_bytes(bytes(raw))
    with pytest.raises(StreamFormatError, match="RAW frames without a per-frame header"):
        PgrStream(tmp_path / "bad.pgr")
