"""The real data in tests/data/: every file a README lists is there, unchanged; a missing one fails loudly."""

from __future__ import annotations

import hashlib
import re

import pytest

from tests.testdata import DATA, data_file

# A README table row: | `name` | bytes | `sha256` | ...
ROW = re.compile(r"^\| `([^`]+)` \| ([\d,]+) \| `([0-9a-f]{64})` \|", re.MULTILINE)


def listed_files() -> list[tuple[str, int, str]]:
    rows = []
    for readme in sorted(DATA.glob("*/README.md")):
        folder = readme.parent.relative_to(DATA)
        for name, size, sha in ROW.findall(readme.read_text()):
            rows.append((str(folder / name), int(size.replace(",", "")), sha))
    return rows


def test_the_readmes_list_every_data_file() -> None:
    listed = {name for name, _, _ in listed_files()}
    present = {str(p.relative_to(DATA)) for p in DATA.rglob("*") if p.is_file() and p.name != "README.md"}
    assert listed == present
    assert len(listed) >= 10  # both folders' tables were parsed


@pytest.mark.parametrize(("name", "size", "sha256"), listed_files())
def test_data_file_is_the_one_documented(name: str, size: int, sha256: str) -> None:
    data = data_file(name).read_bytes()
    assert len(data) == size
    assert hashlib.sha256(data).hexdigest() == sha256


def test_a_missing_data_file_raises_naming_it() -> None:
    with pytest.raises(FileNotFoundError, match=r"tests/data/vlp16/absent\.pcap is missing"):
        data_file("vlp16/absent.pcap")


def test_the_data_stays_small() -> None:
    total = sum(p.stat().st_size for p in DATA.rglob("*") if p.is_file())
    assert total < 8_000_000
