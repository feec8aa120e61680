"""rigd.calibration.service.params_with_sigmas: the user's ladder, checked, on every camera."""

import math

import pytest

from calib.pipeline import CalibParams
from rigd.calibration.service import params_with_sigmas
from rigd.errors import RigdError


def test_a_given_ladder_replaces_both_the_default_and_the_heads():
    params = params_with_sigmas(CalibParams(), (5.0, 2.0))
    assert params.optim.sigmas_deg == (5.0, 2.0) and params.head_sigmas_deg is None


@pytest.mark.parametrize("bad", [(), (3.0, 0.0), (3.0, -1.0), (math.nan,), (math.inf, 1.0)])
def test_a_ladder_that_is_not_positive_angles_is_refused_naming_it(bad):
    with pytest.raises(RigdError, match="sigmas must be positive angles in degrees"):
        params_with_sigmas(CalibParams(), bad)
