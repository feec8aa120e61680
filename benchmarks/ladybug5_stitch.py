"""Stitch time of the Ladybug5 adapter: 6 x 2448x2048 BGR camera images -> equirectangular panorama.

Run: .venv/bin/python benchmarks/ladybug5_stitch.py [--repeats N]
Prints the map precomputation time (once per rig file and panorama size) and the per-frame stitch time
(median and max over the repeats) for each default panorama size (target: < 0.5 s a frame), and the time
to decode one COLOR_SEP_JPEG8 frame and one COLOR_SEP_JPEG12 frame (24 JPEGs + demosaicing), which a live or
.pgr frame adds.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import imagecodecs
import numpy as np

from drivers.ladybug5.formats import BayerPattern, DataFormat
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, PgrFrameData, PgrStream, PgrWriteOptions, bayer_planes, write_pgr
from drivers.ladybug5.pgr_write import mosaic_from_bgr
from drivers.ladybug5.rig import default_ladybug5_rig
from drivers.ladybug5.stitch import DEFAULT_RADIUS_M, PANORAMA_SIZES, PanoramaSpec, Stitcher


def _median_s(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _jpeg12_planes(image: np.ndarray) -> list[bytes]:
    """Four 12-bit channel JPEGs (quality 95) of an 8-bit BGR image's RGGB mosaic, its values scaled to 12 bits."""
    mosaic = mosaic_from_bgr(image, BayerPattern.RGGB).astype(np.uint16) << 4
    return [imagecodecs.jpeg8_encode(np.ascontiguousarray(mosaic[r::2, c::2]), level=95, bitspersample=12)
            for r, c in DEFAULT_LAYOUT.slot_cells]


def _decode_time(images: list[np.ndarray], repeats: int, tmp: Path, bits: int = 8) -> float:
    """Median time to turn one frame block (as in a .pgr or an SDK JPEG buffer) into six BGR images."""
    jpegs = [bayer_planes(im, DEFAULT_LAYOUT) if bits == 8 else _jpeg12_planes(im) for im in images]
    fmt = DataFormat.COLOR_SEP_JPEG8 if bits == 8 else DataFormat.COLOR_SEP_JPEG12
    write_pgr(tmp / "bench.pgr", [PgrFrameData(0, 0, 0, jpegs)], options=PgrWriteOptions(data_format=fmt))
    stream = PgrStream(tmp / "bench.pgr")
    try:
        return _median_s(lambda: stream.camera_images(0), repeats)
    finally:
        stream.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    args = parser.parse_args()
    rig = default_ladybug5_rig()
    rng = np.random.default_rng(0)
    # Smooth content plus sensor-like noise: compresses like a real scene (pure noise would not).
    yy, xx = np.mgrid[0 : rig.cameras[0].height, 0 : rig.cameras[0].width]
    base = 128 + 60 * np.sin(xx / 37.0) * np.cos(yy / 53.0)
    images = [
        np.clip(base[..., None] + rng.normal(0, 3, (*base.shape, 3)), 0, 255).astype(np.uint8) for _ in rig.cameras
    ]
    print(f"cpus: {os.cpu_count()}, OpenCV {cv2.__version__} threads: {cv2.getNumThreads()}")
    print(f"input: 6 x {rig.cameras[0].width}x{rig.cameras[0].height} BGR uint8; sphere radius {DEFAULT_RADIUS_M} m")
    for width, height in PANORAMA_SIZES:
        start = time.perf_counter()
        stitcher = Stitcher(rig, PanoramaSpec(width, height))
        init_s = time.perf_counter() - start
        stitcher.stitch(images)  # warm-up
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            stitcher.stitch(images)
            times.append(time.perf_counter() - start)
        print(
            f"{width}x{height}: maps {init_s:.2f} s once; stitch median {statistics.median(times) * 1e3:.1f} ms, "
            f"max {max(times) * 1e3:.1f} ms over {args.repeats} frames"
        )
    for bits in (8, 12):
        with tempfile.TemporaryDirectory() as tmp:
            decode_s = _decode_time(images, max(3, args.repeats // 4), Path(tmp), bits)
        print(f"decode one COLOR_SEP_JPEG{bits} frame (24 JPEGs + demosaic): median {decode_s * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
