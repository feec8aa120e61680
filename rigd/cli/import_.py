"""``rigd import ford SRC OUT``: recordings of other rigs as rigd datasets (docs/dataset.md, "Importing")."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from tqdm import tqdm


def _scan_list(text: str) -> list[int]:
    """'1-10' or '1,3,5' (or both mixed) as a list of scan numbers."""
    out: list[int] = []
    try:
        for part in text.split(","):
            lo, _, hi = part.partition("-")
            out += list(range(int(lo), int(hi or lo) + 1))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"scans are numbers or ranges like 1-10,12, got {text!r}") from exc
    if not out or min(out) < 0:
        raise argparse.ArgumentTypeError(f"scans are numbers or ranges like 1-10,12, got {text!r}")
    return out


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("import", help="a recording of another rig as a rigd dataset",
                                   description="Read a recording made by another rig or tool into a rigd dataset "
                                   "(docs/dataset.md, 'Importing').")
    formats = parser.add_subparsers(dest="format", metavar="FORMAT", required=True)
    ford = formats.add_parser(
        "ford", help="the Ford Campus sample (Ladybug3 head + HDL-64E)",
        description="The Ford Campus sample of Pandey's MI calibration (camN/imageSSSS.jpg, masks/camN.png, "
        "scans/scanSSSS.pcd, head.yaml) as a head dataset, or one camera as a pinhole dataset; the reference pose "
        "is written to OUT/reference.yaml.")
    ford.add_argument("src", type=Path, metavar="SRC", help="the sample's folder (holds head.yaml)")
    ford.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder")
    ford.add_argument("--camera", default=None, metavar="NAME", help="one camera (cam0..cam4) as a pinhole dataset")
    ford.add_argument("--scans", type=_scan_list, default=None, metavar="LIST",
                      help="scans to take, e.g. 1-10 (default: every scan the folder holds)")
    ford.set_defaults(func=_ford)


def _ford(args: argparse.Namespace) -> int:
    from rigd.importers.ford import import_ford  # scipy/cv2 only when importing

    with tqdm(desc="import ford", unit="scan") as bar:
        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        n = import_ford(args.src, args.out, args.camera, args.scans, progress)
    what = f"camera {args.camera}" if args.camera else "head"
    print(f"written: {args.out} ({n} pairs, {what}; reference pose in {args.out / 'reference.yaml'})")
    return 0
