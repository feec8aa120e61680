"""``rigd lidar info FILE`` and ``rigd lidar export FILE --out DIR``: VLP-16 captures (docs/vlp16.md)."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from drivers.vlp16 import (
    LEGACY_PRODUCT_ID,
    VLP16_PRODUCT_ID,
    LaserCalibration,
    PacketFault,
    PcapReplay,
    Ports,
    StreamStats,
    Sweep,
    TimeSource,
    Vlp16Config,
    load_calibration,
)
from rigd.dataset import Cloud, write_pcd
from rigd.errors import RigdError


def _port(text: str) -> int:
    value = int(text)
    if not 0 < value < 65536:
        raise argparse.ArgumentTypeError(f"must be a UDP port 1..65535, got {text}")
    return value


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE", help="pcap or pcapng capture of a VLP-16")
    parser.add_argument(
        "--any-product",
        action="store_true",
        help="decode packets whatever their product-id byte says (pre-2015 firmware writes "
        f"0x{LEGACY_PRODUCT_ID:02x})",
    )
    parser.add_argument(
        "--cut-azimuth",
        type=float,
        default=0.0,
        metavar="DEG",
        help="azimuth where sweeps start, degrees clockwise from x (default 0)",
    )
    geometry = parser.add_mutually_exclusive_group()
    geometry.add_argument(
        "--calibration",
        type=Path,
        metavar="YAML",
        help="ROS VLP16db.yaml-style file with vert_correction / vert_offset_correction (default: the VLP-16 "
        "manual's geometry, with its per-laser vertical offsets)",
    )
    geometry.add_argument(
        "--nominal-geometry",
        action="store_true",
        help="nominal elevations without the manual's vertical offsets (rigd's earlier default; up to 11.2 mm "
        "lower or higher in z)",
    )
    parser.add_argument("--data-port", type=_port, default=Ports().data, help="data packet UDP port (2368)")
    parser.add_argument(
        "--position-port", type=_port, default=Ports().position, help="position packet UDP port (8308)"
    )


def register(subparsers: Any) -> None:
    lidar = subparsers.add_parser(
        "lidar",
        help="inspect and export VLP-16 captures (pcap/pcapng)",
        description="Decode Velodyne VLP-16 captures into sweeps (docs/vlp16.md).",
    )
    commands = lidar.add_subparsers(dest="lidar_command", metavar="ACTION", required=True)
    info = commands.add_parser(
        "info",
        help="packets, return mode, product id, rpm, sweeps, duration, PPS",
        description="Summarise a VLP-16 capture.",
    )
    _add_common(info)
    info.set_defaults(func=run_info)
    export = commands.add_parser(
        "export",
        help="write one PCD file per sweep",
        description="Write sweep_NNNN.pcd (x y z intensity ring, LiDAR frame) per sweep.",
    )
    _add_common(export)
    export.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="output directory: new or empty (written beside it, then renamed into place)")
    export.add_argument("--overwrite", action="store_true",
                        help="replace --out DIR as a whole when it holds anything (an earlier export's sweeps)")
    export.add_argument(
        "--complete-only", action="store_true", help="skip the partial first and last sweep of the capture"
    )
    export.set_defaults(func=run_export)


def _calibration(args: argparse.Namespace) -> LaserCalibration:
    """A calibration file if given, else the nominal geometry if asked for, else the manual's."""
    if args.calibration:
        return load_calibration(args.calibration)
    return LaserCalibration.nominal() if args.nominal_geometry else LaserCalibration()


def _replay(args: argparse.Namespace) -> PcapReplay:
    calibration = _calibration(args)
    config = Vlp16Config(
        calibration=calibration,
        cut_azimuth_deg=args.cut_azimuth,
        product_ids=None if args.any_product else frozenset({VLP16_PRODUCT_ID}),
    )
    return PcapReplay(args.file, config, Ports(args.data_port, args.position_port))


def _product_hint(stats: StreamStats) -> str:
    if PacketFault.PRODUCT_ID not in stats.faults:
        return ""
    ids = ", ".join(f"0x{p:02x}" for p in sorted(stats.product_ids - {VLP16_PRODUCT_ID}))
    return (
        f"\n  {stats.faults[PacketFault.PRODUCT_ID]} packets have product id {ids}, "
        f"not 0x{VLP16_PRODUCT_ID:02x}; "
        f"0x{LEGACY_PRODUCT_ID:02x} is what pre-2015 VLP-16 firmware writes. Rerun with --any-product "
        "to decode them as VLP-16."
    )


def _summary_lines(replay: PcapReplay, sweeps: list[Sweep]) -> list[str]:
    stats = replay.stats
    modes = ", ".join(m.name.lower() for m in sorted(stats.return_modes)) or "none decoded"
    products = ", ".join(f"0x{p:02x}" for p in sorted(stats.product_ids)) or "none"
    complete = [s for s in sweeps if s.complete]
    rpm = float(np.median([s.rpm for s in (complete or sweeps)])) if sweeps else float("nan")
    duration = sweeps[-1].end.device - sweeps[0].start.device if sweeps else 0.0
    pps = stats.pps.name.lower() if stats.pps is not None else "no position packets"
    if stats.time_source is TimeSource.GPS:
        clock = "GPS (PPS locked): device time is UTC"
    elif np.isfinite(stats.clock_offset_s):
        clock = f"host clock (no GPS lock); host time - device time = {stats.clock_offset_s:+.6f} s"
    else:
        clock = "unknown (no data packets decoded)"
    lines = [
        f"file:            {replay.path}",
        f"records:         {replay.summary.records} ({stats.data_packets} data packets, "
        f"{stats.position_packets} position packets, {stats.other_datagrams} other)",
        f"bad packets:     {stats.bad_packets}",
        *(
            f"  {fault.value}: {stats.faults[fault]} (first at record {stats.first_fault[fault]})"
            for fault in PacketFault
            if fault in stats.faults
        ),
        *(f"  {note}" for note in (*stats.notes, *([replay.summary.unread] if replay.summary.unread else []))),
        f"return mode:     {modes}",
        f"product id:      {products}",
        f"rpm:             {rpm:.1f}" if sweeps else "rpm:             n/a",
        f"sweeps:          {len(sweeps)} ({len(complete)} complete)",
        f"duration:        {duration:.3f} s",
        f"missing packets: {stats.missing_packets}",
        f"PPS:             {pps}",
        f"time:            {clock}",
    ]
    return lines


def run_info(args: argparse.Namespace) -> int:
    replay = _replay(args)
    # Only the metadata is kept: memory stays flat on long captures.
    sweeps = [replace(sweep, points=sweep.points[:0]) for sweep in replay]
    print("\n".join(_summary_lines(replay, sweeps)) + _product_hint(replay.stats))
    return 0


def sweep_cloud(sweep: Sweep) -> Cloud:
    """The project's Cloud record of a sweep: points_lidar (N,3) float64 m, intensity, ring (0 = lowest)."""
    points = sweep.points
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
    return Cloud(xyz, points["intensity"].astype(np.float32), points["ring"].astype(np.int16))


def run_export(args: argparse.Namespace) -> int:
    from rigd.outdir import claim_output_dir, write_error

    replay = _replay(args)
    written = 0
    with claim_output_dir(args.out, inputs=[args.file], overwrite=args.overwrite) as folder:
        for sweep in tqdm(replay, desc="sweeps", unit=" sweeps", disable=not sys.stderr.isatty()):
            if args.complete_only and not sweep.complete:
                continue
            path = folder / f"sweep_{sweep.index:04d}.pcd"
            try:
                write_pcd(path, sweep_cloud(sweep))
            except OSError as exc:
                raise write_error(args.out / path.name, exc) from exc
            written += 1
        if written == 0:  # nothing is put in place
            raise RigdError(f"{args.file}: no sweeps to export{_product_hint(replay.stats)}")
    print(f"wrote {written} sweeps to {args.out}")
    return 0
