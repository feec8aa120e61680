"""The argument parser class of every rigd command and subcommand: option values may be negative numbers."""

from __future__ import annotations

import argparse
import re
import sys
from typing import Any, NoReturn

from rigd.cli.exit_codes import USAGE

# argparse reads a token that starts with '-' as an option unless it looks like a negative number, and up to
# Python 3.12 "looks like" is '^-\d+$|^-\d*\.\d+$': '--init -3.5,2,-2.5,0.1,0,0' (a list) and
# '--min-move -1e-3' (an exponent) then fail with "expected one argument". No rigd option is spelt with a
# digit after its dash, so any '-' followed by a digit (or '.' and a digit) is a value, as Python 3.13 decides.
NEGATIVE_VALUE = re.compile(r"^-\.?\d")


class RigdArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` that takes '-3.5,2,...' and '-1e-3' as option values, and exits with
    ``USAGE`` (64) on a wrong command line: argparse's own 2 is ``rigd check``'s "unknown".

    ``add_subparsers`` makes its parsers of the same class, so every subcommand inherits this.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse keeps the test in this attribute (CPython 3.11-3.14); tests/rigd/test_cli_args.py fails if
        # a future argparse stops reading it.
        self._negative_number_matcher = NEGATIVE_VALUE

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(USAGE, f"{self.prog}: error: {message}\n")
