"""The bag importer's message decoders on messages built with rosbags' types: image encodings, PointCloud2
layouts (from real VLP-16 returns), CameraInfo models."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from drivers.vlp16 import decode_packets
from rigd.dataset.records import CameraKind
from rigd.importers.bag import BagError
from rigd.importers.bag.clouds import pointcloud2_sweep, rings_from_elevation
from rigd.importers.bag.images import decode_compressed, decode_image
from rigd.importers.bag.intrinsics import camera_from_info
from tests.rigd.importers.bag.bags import legacy_turns

T = get_typestore(Stores.ROS2_HUMBLE).types
HEADER = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=5, nanosec=0), frame_id="f")
RNG = np.random.default_rng(3)
BGR = RNG.integers(0, 256, (6, 8, 3), dtype=np.uint8)


def _image(encoding: str, pixels: np.ndarray, pad: int = 0, bigendian: int = 0) -> object:
    height, width = pixels.shape[:2]
    rows = pixels.reshape(height, -1).view(np.uint8)
    padded = np.concatenate([rows, np.zeros((height, pad), np.uint8)], axis=1)
    return T["sensor_msgs/msg/Image"](header=HEADER, height=height, width=width, encoding=encoding,
                                      is_bigendian=bigendian, step=padded.shape[1], data=padded.ravel())


def test_raw_encodings() -> None:
    assert np.array_equal(decode_image(_image("bgr8", BGR, pad=5), where="x"), BGR)
    assert np.array_equal(decode_image(_image("rgb8", BGR[..., ::-1].copy()), where="x"), BGR)
    grey = BGR[..., 0].copy()
    assert np.array_equal(decode_image(_image("mono8", grey, pad=3), where="x"), grey)
    wide = (grey.astype(np.uint16) * 200).astype(">u2")
    scaled = decode_image(_image("mono16", wide, bigendian=1), where="x")
    assert scaled.dtype == np.uint8 and scaled.max() == 255 and np.array_equal(np.argsort(scaled, None, "stable"),
                                                                                np.argsort(grey, None, "stable"))


def test_bayer_mosaic_keeps_the_colours() -> None:
    flat = np.zeros((16, 16, 3), np.uint8)
    flat[:] = (30, 120, 220)  # B, G, R
    mosaic = np.empty((16, 16), np.uint8)  # RGGB: R at (even, even), B at (odd, odd)
    mosaic[0::2, 0::2], mosaic[1::2, 1::2] = 220, 30
    mosaic[0::2, 1::2] = mosaic[1::2, 0::2] = 120
    out = decode_image(_image("bayer_rggb8", mosaic), where="x")
    assert np.allclose(out[4:-4, 4:-4].reshape(-1, 3).mean(axis=0), flat[0, 0], atol=2)


def test_unknown_encoding_is_named() -> None:
    with pytest.raises(BagError, match="'yuv422'.*mono8"):
        decode_image(_image("yuv422", BGR[..., :2].copy()), where="/cam at 5 s")
    short = _image("bgr8", BGR)
    short.data = short.data[:-10]
    with pytest.raises(BagError, match="does not hold"):
        decode_image(short, where="x")


def test_compressed_png_and_jpeg() -> None:
    for ext, fmt in ((".png", "png"), (".jpg", "rgb8; jpeg compressed bgr8")):
        ok, data = cv2.imencode(ext, BGR)
        assert ok
        out = decode_compressed(T["sensor_msgs/msg/CompressedImage"](header=HEADER, format=fmt, data=data.ravel()),
                                where="x")
        assert out.shape == BGR.shape
        if ext == ".png":
            assert np.array_equal(out, BGR)
    with pytest.raises(BagError, match="compressed image format 'tiff'"):
        decode_compressed(T["sensor_msgs/msg/CompressedImage"](header=HEADER, format="tiff", data=data.ravel()),
                          where="x")


def _cloud(points: np.ndarray, fields: list[tuple[str, int, str]], padding: int) -> object:
    """A PointCloud2 of ``points`` (structured) with the named fields at their offsets, each point padded."""
    Field = T["sensor_msgs/msg/PointField"]
    codes = {"f4": 7, "f8": 8, "u1": 2, "u2": 4}
    step = max(off + np.dtype(code).itemsize for _, off, code in fields) + padding
    dtype = np.dtype({"names": [n for n, _, _ in fields], "formats": ["<" + c for _, _, c in fields],
                      "offsets": [o for _, o, _ in fields], "itemsize": step})
    records = np.zeros(len(points), dtype)
    for name, _, _ in fields:
        records[name] = points[name]
    return T["sensor_msgs/msg/PointCloud2"](
        header=HEADER, height=1, width=len(points), fields=[Field(name=n, offset=o, datatype=codes[c], count=1)
                                                            for n, o, c in fields],
        is_bigendian=False, point_step=step, row_step=step * len(points), data=records.view(np.uint8).ravel(),
        is_dense=True)


def test_pointcloud2_of_real_returns() -> None:
    decoded = decode_packets(legacy_turns()[0], None, 5.0 + np.arange(len(legacy_turns()[0])) * 1e-3).points
    rel = np.zeros(len(decoded), [("x", "f4"), ("y", "f4"), ("z", "f4"), ("intensity", "u1"), ("ring", "u2"),
                                  ("time", "f4")])
    for name in ("x", "y", "z", "intensity", "ring"):
        rel[name] = decoded[name]
    rel["time"] = decoded["time"] - 5.0
    fields = [("x", 0, "f4"), ("y", 4, "f4"), ("z", 8, "f4"), ("intensity", 16, "u1"), ("ring", 18, "u2"),
              ("time", 20, "f4")]
    sweep = pointcloud2_sweep(_cloud(rel, fields, padding=6), stamp_s=5.0, where="x")
    xyz = np.stack([decoded["x"], decoded["y"], decoded["z"]], axis=1)
    assert np.allclose(sweep.points_lidar, xyz) and np.array_equal(sweep.ring, decoded["ring"])
    assert sweep.t_start_s == pytest.approx(decoded["time"].min(), abs=1e-6)
    assert sweep.t_end_s == pytest.approx(decoded["time"].max(), abs=1e-6)
    assert np.mean(rings_from_elevation(xyz) == decoded["ring"]) > 0.99
    without = pointcloud2_sweep(_cloud(rel, fields[:3], padding=0), stamp_s=5.0, where="x")
    assert without.t_start_s == without.t_end_s == 5.0 and np.mean(without.ring == decoded["ring"]) > 0.99
    with pytest.raises(BagError, match="without field"):
        pointcloud2_sweep(_cloud(rel, [("x", 0, "f4"), ("y", 4, "f4")], padding=0), stamp_s=5.0, where="x")


def _info(model: str, d: list[float]) -> object:
    Roi = T["sensor_msgs/msg/RegionOfInterest"]
    K = [500.0, 0, 320, 0, 510.0, 240, 0, 0, 1]
    return T["sensor_msgs/msg/CameraInfo"](header=HEADER, height=480, width=640, distortion_model=model,
                                           d=np.array(d), k=np.array(K), r=np.eye(3).ravel(), p=np.zeros(12),
                                           binning_x=0, binning_y=0, roi=Roi(x_offset=0, y_offset=0, height=0,
                                                                             width=0, do_rectify=False))


def test_camera_info_models() -> None:
    pinhole = camera_from_info(_info("plumb_bob", [0.1, -0.2, 0.001, 0.002, 0.03]), where="x")
    assert pinhole.kind is CameraKind.PINHOLE and pinhole.D is not None and pinhole.D[4] == 0.03
    assert pinhole.K is not None and pinhole.K[1, 1] == 510.0 and (pinhole.width, pinhole.height) == (640, 480)
    fisheye = camera_from_info(_info("equidistant", [0.1, 0.01, 0.001, 0.0001]), where="x")
    assert fisheye.kind is CameraKind.FISHEYE
    with pytest.raises(BagError, match="unknown distortion model 'kannala'"):
        camera_from_info(_info("kannala", []), where="x")
