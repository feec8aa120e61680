"""What the service says of its own files: a dataset by its id, not by a path on the server.

Errors from the dataset layer and the calibration name the file they could not use, by its path under the data
directory (``/var/lib/rigd/datasets/pin1/pairs/0003/cloud.pcd: ...``): right for ``rigd calibrate`` in a
shell, where the path is what the user typed, but on the page and in the API's answers the operator knows the
dataset by its id and cannot act on a server's path. The paths are said as ``dataset pin1's
pairs/0003/cloud.pcd`` where the errors are shown (job records, error responses); the job log keeps them whole.
"""

from __future__ import annotations

import re
from pathlib import Path

from rigd.store.datasets import DATASET_ID_PATTERN

_ID = DATASET_ID_PATTERN.strip("^$")
_FILE = r"(?:/([^\s:;,()'\"]+))?"  # a path inside the dataset, to the next blank or punctuation


def _said(match: re.Match[str]) -> str:
    dataset, inside = match.group(1), match.group(2)
    return f"dataset {dataset}'s {inside}" if inside else f"dataset {dataset}"


def public_text(text: str, datasets_root: Path) -> str:
    """``text`` with every path into ``datasets_root`` (as given and resolved) said by the dataset's id, and a
    ``dataset X: dataset X`` that leaves said once."""
    roots = {str(datasets_root).rstrip("/"), str(datasets_root.resolve()).rstrip("/")}
    for root in sorted(roots, key=len, reverse=True):  # the longer first: one may hold the other
        text = re.sub(re.escape(root) + "/(" + _ID + ")" + _FILE, _said, text)
    return re.sub(r"\bdataset (" + _ID + r"): dataset \1\b", r"dataset \1", text)
