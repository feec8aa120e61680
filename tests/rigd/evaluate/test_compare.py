"""``rigd evaluate compare``: reports, table, plot, method names; research methods run there, not in rigd calibrate."""

from dataclasses import replace

import pytest
import yaml

import calib.methods
from calib.methods import Method
from rigd.cli import main
from rigd.cli.exit_codes import USAGE
from rigd.errors import RigdError
from rigd.evaluate.compare import parse_methods

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def quick_photometric(monkeypatch):
    """The photometric methods with a small budget (the test checks the plumbing, not the optimum); --workers 1
    runs in this process, so the patch reaches the runs."""
    for method, spec in calib.methods.METHODS.items():
        if spec.photo is not None:
            quick = replace(spec.photo, max_points=3000, max_evals=120, restarts=0)
            monkeypatch.setitem(calib.methods.METHODS, method, replace(spec, photo=quick))


def test_parse_methods():
    assert parse_methods("gmm, nid,gom,nid") == (Method.GMM, Method.NID, Method.GOM)
    with pytest.raises(RigdError, match="unknown method 'sift'"):
        parse_methods("gmm,sift")


def test_compare_writes_one_table_one_plot_and_every_method(small_dataset, tmp_path, capsys, quick_photometric):
    out = tmp_path / "cmp"
    code = main(["evaluate", "compare", str(small_dataset), "--methods", "nid,gom", "--trials", "2", "--subsets",
                 "1", "--size", "1", "--rot-deg", "1", "--trans-m", "0.02", "--workers", "1", "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0
    report = yaml.safe_load((out / "compare.yaml").read_text())
    assert set(report["methods"]) == {"nid", "gom"}
    assert report["settings"]["subsets"] == 1 and report["settings"]["trials"] == 2
    for row in report["methods"].values():
        assert row["convergence"]["runs"] == 2 and row["precision"]["runs"] == 1
        assert len(row["errors_vs_reference"]) == 2
    table = (out / "compare.md").read_text()
    assert table.count("\n| nid |") == 1 and table.count("\n| gom |") == 1 and table in printed
    assert (out / "compare.png").read_bytes().startswith(PNG_MAGIC)


def test_compare_on_as_few_pairs_as_a_subset_runs_no_precision_and_says_so(small_dataset, tmp_path, capsys,
                                                                          quick_photometric):
    out = tmp_path / "cmp1"
    code = main(["evaluate", "compare", str(small_dataset), "--methods", "nid", "--trials", "1", "--size", "2",
                 "--rot-deg", "1", "--trans-m", "0.02", "--workers", "1", "--out", str(out)])
    capsys.readouterr()
    assert code == 0
    row = yaml.safe_load((out / "compare.yaml").read_text())["methods"]["nid"]
    assert row["precision"] is None and row["time_per_run_s"]["precision"] is None
    assert row["time_per_run_s"]["convergence"] > 0
    nid_line = next(ln for ln in (out / "compare.md").read_text().splitlines() if ln.startswith("| nid |"))
    assert "nan" not in nid_line and "| — / " in nid_line


def test_calibrate_refuses_a_research_method_by_name(small_dataset, tmp_path, capsys):
    with pytest.raises(SystemExit) as refused:
        main(["calibrate", str(small_dataset), "--method", "nid", "--out", str(tmp_path / "out")])
    assert refused.value.code == USAGE and "invalid choice: 'nid'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
