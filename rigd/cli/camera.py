"""``rigd camera``: the Ladybug5 -- USB presence and health, SDK layout probe, the factory head calibration, another
panorama's orientation against rigd's (docs/ladybug5.md)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from drivers.ladybug5.errors import HeadCalibrationError, StreamFormatError, UsbBackendError
from drivers.ladybug5.head import HeadCalibration
from drivers.ladybug5.head_file import load_head, save_head
from drivers.ladybug5.pano_check import panorama_alignment
from drivers.ladybug5.pgr import PgrStream
from drivers.ladybug5.raw import to_uint8
from drivers.ladybug5.replay import PARTIAL_FRAME_CAMERAS
from drivers.ladybug5.sdk import (
    DEFAULT_LIBRARY,
    LadybugLibrary,
    SdkLayout,
    probe_layout,
    read_camera_head,
    sdk_status,
)
from drivers.ladybug5.sdk_head import DEFAULT_MAP_STEP_PX, LensSource, head_from_config_file, head_from_pgr
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.ladybug5.usb import (
    POINT_GREY_VENDOR_ID,
    UsbCamera,
    UsbMatch,
    find_cameras,
    health_warnings,
    read_usbfs_memory_mb,
    reset_camera,
)
from rigd.capture.config import DEFAULT_LAYOUT_FILE
from rigd.cli.exit_codes import OK, UNHEALTHY
from rigd.outdir import claim_output_files


def _hex_int(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not an integer (e.g. 0x1e10): {text}") from exc


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not WIDTHxHEIGHT in px (e.g. 2448x2048): {text}") from exc
    if width <= 0 or height <= 0:
        raise argparse.ArgumentTypeError(f"the size must be positive: {text}")
    return width, height


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("camera", help="Ladybug5 camera: presence, USB health, SDK setup")
    sub = parser.add_subparsers(dest="camera_command", metavar="ACTION", required=True)

    info = sub.add_parser(
        "info",
        help="list Ladybug cameras on USB with serial, port, link speed; check usbfs memory and the SDK",
        description="Enumerates USB through pyusb (no FLIR SDK needed). Exit 0 when one or more cameras "
        "are found and healthy, 1 otherwise.",
    )
    info.add_argument("--vendor-id", type=_hex_int, default=POINT_GREY_VENDOR_ID, help="default 0x1e10")
    info.add_argument("--product-id", type=_hex_int, action="append", default=[], help="Ladybug product id (repeat)")
    info.add_argument(
        "--product-match", action="append", default=None, help="substring of the USB product string (default ladybug)"
    )
    info.add_argument("--serial", default=None, help="only this camera serial")
    info.add_argument("--reset", action="store_true", help="USB-reset the (single) matching camera first")
    info.add_argument("--sdk-library", default=DEFAULT_LIBRARY, help=f"Ladybug SDK library (default {DEFAULT_LIBRARY})")
    info.set_defaults(func=run_info)

    layout = sub.add_parser(
        "sdk-layout",
        help="measure the installed Ladybug SDK's struct layout and enum values for the ctypes binding",
        description="Compiles drivers/ladybug5/layout_probe.c against INCLUDE/ladybug.h and writes its YAML.",
    )
    layout.add_argument("--include", type=Path, required=True, help="directory holding the SDK's ladybug.h")
    layout.add_argument("--out", type=Path, required=True, help="YAML file to write")
    layout.add_argument("--compiler", default="c++", help="C or C++ compiler (default c++)")
    layout.set_defaults(func=run_sdk_layout)
    _register_export_head(sub)
    _register_check_panorama(sub)


def _register_export_head(sub: Any) -> None:
    export = sub.add_parser(
        "export-head",
        help="read the factory head calibration through the Ladybug SDK and write it (head dataset format)",
        description="After ladybugLoadConfig the SDK holds the head's factory calibration: each sensor's focal "
        "length, image centre, pose in the head and rectification. This reads it from the camera (default), a "
        ".pgr stream's embedded configuration (--pgr) or a configuration file (--calibration), fits an OpenCV "
        "lens model to the rectification and writes OUT (the head dataset format's camera section, usable as "
        "camera.sdk.rig_file) and the sampled rectification maps beside it. On a rig without OpenGL the lens is "
        "fitted to the SDK's 3D map of the raw pixels instead (no maps then). Exit 0, or 1 when a sensor's lens "
        "fit is poor (written anyway). Needs FLIR's SDK and the layout of `rigd camera sdk-layout`.",
    )
    export.add_argument("--out", type=Path, required=True, help="head file to write (YAML)")
    export.add_argument("--overwrite", action="store_true", help="replace --out (and its maps) if they exist")
    export.add_argument("--maps", type=Path, default=None, help="rectification maps file (default OUT.maps.npz)")
    source = export.add_mutually_exclusive_group()
    source.add_argument("--serial", type=int, default=None, help="the camera's serial (default: the only camera)")
    source.add_argument("--pgr", type=Path, default=None, help="a .pgr stream: its embedded configuration")
    source.add_argument("--calibration", type=Path, default=None, help="a configuration file (.cal)")
    export.add_argument("--size", type=_size, default=None, metavar="WxH",
                        help="sensor size in px (default: a grabbed frame's, or the stream's resolution)")
    export.add_argument("--step", type=_positive, default=DEFAULT_MAP_STEP_PX, metavar="PX",
                        help=f"rectification sampled every PX px (default {DEFAULT_MAP_STEP_PX})")
    export.add_argument("--lens-from", type=LensSource, choices=list(LensSource), default=LensSource.AUTO,
                        metavar="{" + ",".join(s.value for s in LensSource) + "}",
                        help="the lens from the SDK's rectification (may need OpenGL), from its 3D map of the raw "
                        "pixels (no rendering context), or auto: the rectification, else the 3D map (default)")
    export.add_argument("--layout", type=Path, default=DEFAULT_LAYOUT_FILE,
                        help=f"SDK layout file from rigd camera sdk-layout (default {DEFAULT_LAYOUT_FILE})")
    export.add_argument("--sdk-library", default=DEFAULT_LIBRARY,
                        help=f"Ladybug SDK library (default {DEFAULT_LIBRARY})")
    export.set_defaults(func=run_export_head)


def _register_check_panorama(sub: Any) -> None:
    check = sub.add_parser(
        "check-panorama",
        help="measure how another panorama of a frame (FLIR's renderer or export) is oriented against rigd's",
        description="Compares PANORAMA with rigd's panorama of the same frame: --reference (a panorama rigd wrote), "
        "or stitched here from a .pgr frame (--pgr, --frame) with a head file (--head). Prints the turn about "
        "the vertical, whether it is mirrored or upside down, and the edges' agreement. Exit 0 when it is in rigd's "
        "convention (docs/conventions.md), 1 otherwise.",
    )
    check.add_argument("panorama", type=Path, help="the other panorama (2:1 image)")
    ref = check.add_mutually_exclusive_group(required=True)
    ref.add_argument("--reference", type=Path, help="rigd's panorama of the same frame (2:1 image)")
    ref.add_argument("--pgr", type=Path, help="a .pgr stream: rigd stitches --frame with --head")
    check.add_argument("--frame", type=int, default=0, help="the .pgr frame's index (default 0)")
    check.add_argument("--head", type=Path, help="head file or rig camera file the .pgr frame is stitched with")
    check.set_defaults(func=run_check_panorama)


def _image(path: Path) -> Any:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise StreamFormatError(f"{path}: missing, unreadable or not an image")
    return image


def _rigd_panorama(args: argparse.Namespace, size: tuple[int, int]) -> Any:
    """rigd's panorama of the frame: the given one, or the .pgr frame stitched with the head at ``size``."""
    if args.reference is not None:
        return _image(args.reference)
    if args.head is None:
        raise StreamFormatError("--pgr needs the head its frames are stitched with (--head)")
    stream = PgrStream(args.pgr)
    try:
        if not 0 <= args.frame < len(stream.index):
            raise StreamFormatError(f"{args.pgr}: no frame {args.frame} (it holds {len(stream.index)})")
        images = stream.frame_images(args.frame, PARTIAL_FRAME_CAMERAS).arrays
    finally:
        stream.close()
    stitcher = Stitcher(load_head(args.head).to_rig(), PanoramaSpec(*size))
    return stitcher.stitch([None if im is None else to_uint8(im) for im in images])


def run_check_panorama(args: argparse.Namespace) -> int:
    panorama = _image(args.panorama)
    found = panorama_alignment(panorama, _rigd_panorama(args, (panorama.shape[1], panorama.shape[0])))
    turns = [f"turned {found.yaw_deg:+.2f} deg (rigd's azimuth at its centre column)"]
    turns += ["mirrored (azimuth runs the other way)"] * found.mirrored
    turns += ["upside down"] * found.upside_down
    print(f"{args.panorama}: {', '.join(turns)}; edges agree {found.score:.2f} (the next best orientation "
          f"{found.runner_up:.2f})")
    print("in rigd's convention" if found.same_convention else "NOT in rigd's convention (docs/conventions.md)")
    return OK if found.same_convention else UNHEALTHY


def _match(args: argparse.Namespace) -> UsbMatch:
    substrings = tuple(args.product_match) if args.product_match else UsbMatch().product_substrings
    return UsbMatch(args.vendor_id, tuple(args.product_id), substrings, args.serial)


def run_info(args: argparse.Namespace) -> int:
    match = _match(args)
    if args.reset:
        camera = reset_camera(match)
        print(f"reset camera {camera.serial or '?'} at {camera.location}")
    try:
        cameras, unidentified = find_cameras(match)
    except UsbBackendError as exc:  # report it and still show the kernel and SDK checks
        print(f"USB: {exc}")
        cameras, unidentified = [], []
    else:
        _print_cameras(cameras, unidentified, match)
    usbfs = read_usbfs_memory_mb()
    print(f"usbfs memory limit: {f'{usbfs} MB' if usbfs is not None else 'unknown'}")
    print(f"Ladybug SDK: {sdk_status(args.sdk_library)}")
    print("power: the Ladybug5+ needs 12-24 V on its GPIO connector; only the SDK can report it (at start)")
    warnings = health_warnings(cameras, usbfs)
    for warning in warnings:
        print(f"warning: {warning}")
    return OK if cameras and not warnings else UNHEALTHY


def _print_cameras(cameras: list[UsbCamera], unidentified: list[UsbCamera], match: UsbMatch) -> None:
    for cam in cameras:
        print(
            f"Ladybug {cam.product or '?'} serial {cam.serial or '?'} at {cam.location} "
            f"(id {cam.vendor_id:04x}:{cam.product_id:04x}), link {cam.speed.label}"
        )
    if not cameras:
        print(f"no Ladybug camera found on USB (vendor 0x{match.vendor_id:04x}, product {_describe_match(match)})")
    for dev in unidentified:
        print(
            f"device {dev.vendor_id:04x}:{dev.product_id:04x} at {dev.location}: strings unreadable "
            "(no permission on the USB node?); may be a Ladybug -- pass --product-id to match it"
        )


def _describe_match(match: UsbMatch) -> str:
    ids = [f"0x{p:04x}" for p in match.product_ids]
    names = [repr(s) for s in match.product_substrings]
    serial = f", serial {match.serial}" if match.serial else ""
    return " or ".join(ids + [f"string containing {n}" for n in names]) + serial


def run_sdk_layout(args: argparse.Namespace) -> int:
    layout = probe_layout(args.include, args.compiler, args.out)
    print(f"wrote {args.out}: LadybugImage is {layout.image_size} bytes; {len(layout.errors)} error codes")
    return 0


def _read_head(args: argparse.Namespace) -> HeadCalibration:
    lib = LadybugLibrary(SdkLayout.load(args.layout), args.sdk_library)
    if args.pgr is not None:
        stream = PgrStream(args.pgr)
        try:
            return head_from_pgr(lib, stream, args.size, args.step, args.lens_from)
        finally:
            stream.close()
    if args.calibration is not None:
        if args.size is None:
            raise HeadCalibrationError(f"{args.calibration}: a configuration file does not say the sensor size: "
                                       "give it (--size 2448x2048, Ladybug5+: 2464x2048)")
        return head_from_config_file(lib, args.calibration, args.size, step_px=args.step, lens=args.lens_from)
    return read_camera_head(lib, args.serial, args.size, args.step, args.lens_from)


def run_export_head(args: argparse.Namespace) -> int:
    # refused before the camera is read: a head file (and its maps) written by another run stays unless told
    claim_output_files([args.out, args.maps or args.out.with_suffix(".maps.npz")], overwrite=args.overwrite)
    head = _read_head(args)
    save_head(head, args.out, args.maps)
    print(f"wrote {args.out}: {head.summary()}")
    for s in head.sensors:
        rpy = np.degrees(s.extrinsics[:3])
        pinhole = (f"raw f {s.lens.K[0, 0]:.2f} px, centre ({s.lens.K[0, 2]:.2f}, {s.lens.K[1, 2]:.2f})"
                   if math.isnan(s.focal_px) else
                   f"f {s.focal_px:.2f} px, centre ({s.centre_px[0]:.2f}, {s.centre_px[1]:.2f})")
        print(f"  {s.name}: {s.width}x{s.height} px, {pinhole}, Euler ZYX [{rpy[0]:.3f} {rpy[1]:.3f} {rpy[2]:.3f}] "
              f"deg, at [{s.extrinsics[3]:.4f} {s.extrinsics[4]:.4f} {s.extrinsics[5]:.4f}] m; lens fit rms "
              f"{s.lens.rms_px:.3f} px, max {s.lens.max_px:.3f} px")
    poor = head.poor_sensors()
    if poor:
        print(f"warning: the OpenCV lens model does not hold the SDK's rectification for {', '.join(poor)}: use the "
              "rectification maps for those sensors (docs/ladybug5.md)")
        return UNHEALTHY
    return OK
