"""``rigd dataset thin`` (rigd/dataset/thin.py): a real 64-ring cloud (tests/data/pinhole_sample/ours_3) reduced
to the rings nearest a 2° grid, and fewer points along each ring, in a dataset that keeps everything else."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from rigd.cli import main
from rigd.cli.exit_codes import USAGE
from rigd.dataset import read_pcd
from rigd.dataset.pcd import Cloud, write_pcd
from rigd.dataset.thin import ThinOptions, _azimuth_kept, choose_rings, ring_elevations_deg, thin_cloud
from rigd.errors import DatasetError, OutputError
from tests.testdata import PINHOLE_FRAME

GROUND_TRUTH = "T_camera_lidar: {rpy_deg: [-90.0, 0.0, -90.0], xyz_m: [0.0, -0.3, -0.5]}\n"


@pytest.fixture(scope="module")
def source(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A one-pair pinhole dataset of the real frame (image, 64-ring cloud, meta)."""
    root = tmp_path_factory.mktemp("thin") / "src"
    pair = root / "pairs" / "0003"
    pair.mkdir(parents=True)
    shutil.copyfile(PINHOLE_FRAME / "image.jpg", pair / "image.jpg")
    shutil.copyfile(PINHOLE_FRAME / "cloud.pcd", pair / "cloud.pcd")
    (pair / "meta.yaml").write_text(yaml.safe_dump({"source": "test"}))
    (root / "rig.yaml").write_text(yaml.safe_dump({
        "camera": {"model": "pinhole", "width": 1920, "height": 1200,
                   "K": [[2000.0, 0.0, 960.0], [0.0, 2000.0, 600.0], [0.0, 0.0, 1.0]]},
        "lidar": {"model": "64-ring"}}))
    (root / "ground_truth.yaml").write_text(GROUND_TRUTH)
    return root


def test_the_rings_nearest_the_grid_are_kept_and_the_rest_of_the_dataset_is_the_same(source: Path,
                                                                                      tmp_path: Path) -> None:
    cloud = read_pcd(source / "pairs" / "0003" / "cloud.pcd")
    elevations = ring_elevations_deg(cloud)
    assert len(elevations) > 40  # a dense LiDAR: rings well under 1 deg apart
    out = tmp_path / "thin"
    assert main(["dataset", "thin", str(source), str(out), "--ring-spacing-deg", "2", "--phase-deg", "0.5"]) == 0

    thinned = read_pcd(out / "pairs" / "0003" / "cloud.pcd")
    meta = yaml.safe_load((out / "pairs" / "0003" / "meta.yaml").read_text())
    kept = meta["thinned"]["source_rings"]
    assert meta["source"] == "test" and meta["thinned"]["points"] == len(thinned)
    assert meta["thinned"]["points_source"] == len(cloud)
    # Each kept ring is the one nearest its grid value (within a degree), no grid value within the source's
    # range is left without one, and the rings are renumbered lowest first.
    grid = np.asarray(meta["thinned"]["grid_deg"])
    assert np.allclose(np.mod(grid - 0.5, 2.0), 0.0)
    for source_ring, value in zip(kept, grid, strict=True):
        nearest = min(elevations, key=lambda r: abs(elevations[r] - value))
        assert source_ring == nearest and abs(elevations[source_ring] - value) <= 1.0
    every_grid_value = np.arange(-89.5, 90.0, 2.0)
    for value in sorted(set(every_grid_value.tolist()) - set(grid.tolist())):  # left out: no ring within 1 deg
        assert all(abs(e - value) > 1.0 for e in elevations.values()), value
    assert len(kept) >= 10  # this LiDAR's rings are dense mid-field, 4-6 deg apart at its top and bottom
    assert sorted(np.unique(thinned.ring).tolist()) == list(range(len(kept)))
    for new, source_ring in enumerate(kept):
        original = cloud.points_lidar[cloud.ring == source_ring]
        assert np.allclose(thinned.points_lidar[thinned.ring == new], original, atol=1e-6)  # every point, in order
    assert np.all(np.diff([ring_elevations_deg(thinned)[r] for r in range(len(kept))]) > 0)
    # Everything else is the source's: the image's bytes, the reference, the rig (its LiDAR noted).
    assert (out / "pairs" / "0003" / "image.jpg").read_bytes() == (source / "pairs/0003/image.jpg").read_bytes()
    assert (out / "ground_truth.yaml").read_text() == GROUND_TRUTH
    rig = yaml.safe_load((out / "rig.yaml").read_text())
    assert rig["camera"]["K"][0][0] == 2000.0 and rig["lidar"]["model"].startswith("64-ring (")


def test_an_azimuth_step_leaves_points_at_least_that_far_apart_along_each_ring(source: Path) -> None:
    cloud = read_pcd(source / "pairs" / "0003" / "cloud.pcd")
    choice = choose_rings(ring_elevations_deg(cloud), ThinOptions(2.0))
    every = thin_cloud(cloud, choice)
    sparse = thin_cloud(cloud, choice, azimuth_step_deg=0.4)
    assert 0 < len(sparse) < len(every)
    azimuth = lambda xyz: np.mod(np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])), 360.0)  # noqa: E731
    for ring in range(len(choice.source_rings)):
        kept = np.sort(azimuth(sparse.points_lidar[sparse.ring == ring]))
        assert np.diff(np.concatenate([kept, kept[:1] + 360.0])).min() >= 0.4 - 1e-9
        # ... and every point dropped lies within 0.4 deg of one kept: thinned, not emptied
        dense = azimuth(every.points_lidar[every.ring == ring])
        gap = np.abs(dense[:, None] - kept[None, :])
        assert np.minimum(gap, 360.0 - gap).min(axis=1).max() < 0.4


def test_bad_input_is_named_and_nothing_is_written(source: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(OutputError, match="holds 1 entries already"):
        _thin(source, out)
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    inside = source / "pairs" / "9999"
    with pytest.raises(OutputError, match="it is inside the input"):  # it would change the source it reads
        _thin(source, inside)
    assert not inside.exists() and [p.name for p in tmp_path.iterdir() if p.name.endswith(".partial")] == []

    no_rings = tmp_path / "norings"
    shutil.copytree(source, no_rings)
    pcd = no_rings / "pairs" / "0003" / "cloud.pcd"
    write_pcd(pcd, Cloud(read_pcd(pcd).points_lidar))
    with pytest.raises(DatasetError, match="0003/cloud.pcd: no ring field"):
        _thin(no_rings, tmp_path / "new")
    assert not (tmp_path / "new").exists()
    with pytest.raises(DatasetError, match="ring spacing"):
        ThinOptions(0.0)
    with pytest.raises(SystemExit) as exit_info:  # argparse names the option
        main(["dataset", "thin", str(source), str(tmp_path / "x"), "--ring-spacing-deg", "-1"])
    assert exit_info.value.code == USAGE and not (tmp_path / "x").exists()


def _thin(src: Path, out: Path, options: ThinOptions | None = None) -> None:
    from rigd.dataset.thin import thin_dataset

    thin_dataset(src, out, options or ThinOptions(2.0))


def test_an_azimuth_step_below_the_angles_resolution_ends_and_is_refused() -> None:
    # At 359 deg a step of 1e-14 is lost to rounding (359 + 1e-14 == 359): the walk round the ring must still
    # move on (it stayed on one point, writing gigabytes), and the options refuse such a step by name.
    azimuth = np.array([359.0, 1.0, 359.5, 359.5])
    assert 359.0 + 1e-14 == 359.0 and _azimuth_kept(azimuth, 1e-14).tolist() == [0, 1, 2, 3]
    with pytest.raises(DatasetError, match="finer than any LiDAR resolves"):
        ThinOptions(2.0, azimuth_step_deg=1e-14)


def test_rings_picked_per_pair_follow_each_pairs_own_elevations(source: Path, tmp_path: Path) -> None:
    """Two pairs, the second's cloud 0.4 deg higher: picked by the dataset's medians both keep the same lasers;
    picked per pair each keeps the rings nearest the grid by its own elevations."""
    from calib.elevation import raise_elevation

    two = tmp_path / "two"
    shutil.copytree(source, two)
    shutil.copytree(two / "pairs" / "0003", two / "pairs" / "0004")
    cloud = read_pcd(two / "pairs" / "0004" / "cloud.pcd")
    raised = Cloud(raise_elevation(cloud.points_lidar, 0.4), cloud.intensity, cloud.ring)
    write_pcd(two / "pairs" / "0004" / "cloud.pcd", raised)
    kept = {}
    for by in ("dataset", "pair"):
        assert main(["dataset", "thin", str(two), str(tmp_path / by), "--rings-by", by]) == 0
        kept[by] = [yaml.safe_load((tmp_path / by / "pairs" / p / "meta.yaml").read_text())["thinned"]
                    for p in ("0003", "0004")]
    assert kept["dataset"][0]["source_rings"] == kept["dataset"][1]["source_rings"]
    for meta, c in zip(kept["pair"], (cloud, raised), strict=True):
        assert meta["rings_by"] == "pair"
        assert meta["source_rings"] == list(choose_rings(ring_elevations_deg(c), ThinOptions(2.0)).source_rings)
    assert kept["pair"][0]["source_rings"] != kept["pair"][1]["source_rings"]
