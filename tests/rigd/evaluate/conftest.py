"""The simulated dataset that the evaluation tests share: written once for the package (no test changes it)."""

import pytest

from rigd.simulate import write_simulated_dataset


@pytest.fixture(scope="package")
def small_dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("ev") / "indoor"
    write_simulated_dataset(root, "indoor", 2, seed=5, width=512, height=256, progress=False)
    return root
