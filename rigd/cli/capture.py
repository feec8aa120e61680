"""``rigd capture``: take still, synchronised pairs at a dozen places, one pair whenever the rig stops."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any, TextIO

from rigd.capture import CaptureRequest, CaptureStatus, run_capture
from rigd.capture.config import find_config, load_settings
from rigd.capture.errors import ConfigError
from rigd.capture.specs import CAMERA_FORMS, LIDAR_FORMS
from rigd.cli.exit_codes import OK, SIGNALLED

LOG_PERIOD_S = 5.0  # without a terminal, a state that lasts is reported again this often


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "capture",
        help="capture still camera/LiDAR pairs: stop the rig at a place, it takes a pair; move on",
        description="Waits until the rig stands still (LiDAR motion estimate, confirmed by the camera), takes the "
        "camera frame and fuses the LiDAR sweeps of that still period into one pair, then waits for the rig to "
        "move to a new place. Rerunning the same command continues the dataset. Defaults come from the rig "
        "file (--config, $RIGD_CONFIG, ./rig.yaml, /etc/rigd/rig.yaml; docs/configuration.md). Ctrl-C stops "
        "between pairs. See docs/capture.md.",
    )
    parser.add_argument("--n", type=int, default=None, help="pairs the dataset should have (default 12)")
    parser.add_argument("--out", type=Path, default=None, help="dataset directory (new, or one to continue)")
    parser.add_argument("--lidar", default=None, help=f"{LIDAR_FORMS} (default udp = 0.0.0.0:2368)")
    parser.add_argument("--camera", default=None, help=f"{CAMERA_FORMS} (default sdk)")
    parser.add_argument("--still-seconds", type=float, default=None,
                        help="the rig must stand still this long before a pair is taken (default 2.0)")
    parser.add_argument("--sweeps", type=int, default=None, help="LiDAR sweeps fused per pair (default 5)")
    parser.add_argument("--min-move", type=float, default=None,
                        help="range change in m (90th percentile over directions) from the last pair's scan "
                        "that makes a new place (default 0.5)")
    parser.add_argument("--silence-timeout", type=float, default=None,
                        help="seconds without usable data from a sensor before giving up (default 5)")
    parser.add_argument("--min-sweep-fraction", type=float, default=None,
                        help="every fused LiDAR sweep holds at least this fraction of a turn's packets; sustained "
                        "loss below it ends the capture after the silence timeout (default 0.99)")
    parser.add_argument("--config", type=Path, default=None, help="rig file (default: see above)")
    parser.add_argument("--serial", type=int, default=None,
                        help="--camera sdk: the Ladybug5's head serial number (default: camera.sdk.serial in the rig "
                        "file, else the only camera on the bus)")
    parser.add_argument("--nominal-head", action="store_true",
                        help="--camera sdk: accept rigd's nominal head (NOT a calibration of the camera): used "
                        "instead of reading the camera's factory head when the rig file names no head file, and "
                        "allowed as camera.sdk.rig_file (default: refused; see `rigd camera export-head`)")
    parser.set_defaults(func=run)


def request_from_args(args: argparse.Namespace) -> CaptureRequest:
    """Options given on the command line, else the rig file's, else the built-in defaults."""
    config = find_config(args.config)
    settings = load_settings(config)
    defaults = settings.capture
    out = args.out if args.out is not None else defaults.out
    if out is None:
        raise ConfigError("give the dataset directory with --out (or capture.out in the rig file)")

    def pick(value: Any, default: Any) -> Any:
        return default if value is None else value

    return CaptureRequest(
        out=out,
        n=pick(args.n, defaults.n),
        lidar=pick(args.lidar, settings.lidar_source),
        camera=pick(args.camera, settings.camera_source),
        still_seconds=pick(args.still_seconds, defaults.still_seconds),
        sweeps=pick(args.sweeps, defaults.sweeps),
        min_move=pick(args.min_move, defaults.min_move),
        silence_timeout_s=pick(args.silence_timeout, defaults.silence_timeout_s),
        config=config,
        min_sweep_fraction=pick(args.min_sweep_fraction, defaults.min_sweep_fraction),
        serial=args.serial,
        nominal_head=args.nominal_head,
    )


class StatusPrinter:
    """One line per state on ``stream``: rewritten in place on a terminal; repeated every 5 s otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.started = time.monotonic()
        self.key: tuple[str, int] | None = None
        self.last_line = -float("inf")
        self.width = 0

    def __call__(self, status: CaptureStatus) -> None:
        now = time.monotonic()
        key = (status.state, status.pairs_done)
        text = (f"[{status.pairs_done:>2}/{status.pairs_wanted}] {now - self.started:6.1f} s  {status.message:<40} "
                f"{status.packet_rate_hz:4.0f} packets/s, {status.packets_lost} lost")
        if self.tty:
            if self.key is not None and key != self.key:
                self.stream.write("\n" + text)
            else:  # rewrite the line, blanking what a longer previous text left
                self.stream.write("\r" + text.ljust(self.width))
            self.width = len(text)
        elif key != self.key or now - self.last_line >= LOG_PERIOD_S:
            self.stream.write(text + "\n")
            self.last_line = now
        self.key = key
        self.stream.flush()

    def finish(self) -> None:
        if self.tty and self.key is not None:
            self.stream.write("\n")
            self.stream.flush()


class StopOnSignal:
    """SIGINT/SIGTERM set ``event`` (capture stops between pairs); a second Ctrl-C interrupts at once."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopOnSignal:
        for signum in (signal.SIGINT, signal.SIGTERM):
            self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.signum = signum
        self.event.set()
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nrigd capture: stopping (between pairs; Ctrl-C again to abort at once)", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    request = request_from_args(args)
    printer = StatusPrinter(sys.stderr)
    with StopOnSignal() as stopper:
        try:
            summary = run_capture(request, printer, stopper.event)
        finally:
            printer.finish()
    done = len(summary.pairs)
    if summary.seconds_per_pair:
        times = " ".join(f"{s:.1f}" for s in summary.seconds_per_pair)
        mean = sum(summary.seconds_per_pair) / done
        print(f"captured {done} pair(s) into {summary.out}; seconds per pair: {times} (mean {mean:.1f})")
    if stopper.signum is not None and printer.key is not None and printer.key[0] == "stopped":
        return SIGNALLED + stopper.signum
    return OK
