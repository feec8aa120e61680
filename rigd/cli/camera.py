"""``rigd camera``: the Ladybug5 -- USB presence and health, SDK layout probe (docs/ladybug5.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from drivers.ladybug5.errors import UsbBackendError
from drivers.ladybug5.sdk import DEFAULT_LIBRARY, probe_layout, sdk_status
from drivers.ladybug5.usb import (
    POINT_GREY_VENDOR_ID,
    UsbCamera,
    UsbMatch,
    find_cameras,
    health_warnings,
    read_usbfs_memory_mb,
    reset_camera,
)
from rigd.cli.exit_codes import OK, UNHEALTHY


def _hex_int(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not an integer (e.g. 0x1e10): {text}") from exc


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
