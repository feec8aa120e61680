"""Option values that start with '-': negative numbers, number lists and exponents reach the option."""

from __future__ import annotations

import pytest

from rigd.cli import build_parser, main
from rigd.cli.exit_codes import ERROR, USAGE

NEGATIVE_INIT = "-3.5,2,-2.5,0.1,0,0"
FAR_AWAY = "-3.5,2,-2.5,1000,0,0"  # the LiDAR 1 km off: the calibration refuses it, after parsing it


@pytest.mark.parametrize("form", ["separate", "equals"])
def test_calibrate_accepts_an_initial_guess_with_a_negative_first_angle(form: str, tmp_path, capsys) -> None:
    init = ["--init", FAR_AWAY] if form == "separate" else [f"--init={FAR_AWAY}"]
    args = build_parser().parse_args(["calibrate", str(tmp_path), *init])
    assert args.init == FAR_AWAY
    # Through the whole command: the value gets to the calibration, which names the dataset as missing.
    assert main(["calibrate", str(tmp_path / "absent"), *init]) == ERROR
    err = capsys.readouterr().err
    assert "expected one argument" not in err and "absent" in err


@pytest.mark.parametrize(
    ("argv", "option", "value"),
    [
        (["calibrate", "D"], "--init", NEGATIVE_INIT),
        (["calibrate", "D"], "--sigmas-deg", "-1,2"),
        (["calibrate", "D"], "--lever-arm-m", "-0.1,0.05,-0.2"),
        (["calibrate", "D"], "--rotation-prior-deg", "-3,15,-55,2"),
        (["calibrate", "D"], "--tolerance", "-0.2,2"),
        (["evaluate", "convergence", "D"], "--tolerance", "-0.2,2"),
        (["evaluate", "convergence", "D"], "--init", NEGATIVE_INIT),
        (["evaluate", "precision", "D"], "--init", NEGATIVE_INIT),
        (["evaluate", "convergence", "D"], "--sigmas-deg", "-.5,1"),
        (["lidar", "info", "F"], "--cut-azimuth", "-1e-3"),
        (["lidar", "export", "F", "--out", "O"], "--cut-azimuth", "-90.5"),
        (["capture"], "--min-move", "-1e-3"),
        (["capture"], "--still-seconds", "-2e0"),
        (["capture"], "--silence-timeout", "-5"),
        (["capture"], "--n", "-3"),
        (["capture"], "--sweeps", "-1"),
        (["simulate", "O"], "--seed", "-1"),
        (["demo"], "--seed", "-7"),
        (["serve"], "--port", "-1"),
    ],
)
def test_negative_values_reach_every_option_that_takes_numbers(argv, option, value) -> None:
    for tokens in ([option, value], [f"{option}={value}"]):
        args = build_parser().parse_args([*argv, *tokens])
        parsed = getattr(args, option.lstrip("-").replace("-", "_"))
        assert parsed == value or parsed == float(value), (tokens, parsed)


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["simulate", "O"], "--noise-m"),
        (["simulate", "O"], "--pairs"),
        (["evaluate", "convergence", "D"], "--rot-deg"),
        (["evaluate", "convergence", "D"], "--trans-m"),
        (["evaluate", "precision", "D"], "--size"),
        (["lidar", "info", "F"], "--data-port"),
    ],
)
def test_options_that_refuse_negatives_say_so_about_the_value(argv, option, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args([*argv, option, "-2.5e-1"])
    assert exit_info.value.code == USAGE
    err = capsys.readouterr().err
    assert f"argument {option}: " in err and "-2.5e-1" in err  # the type refused the value itself
    assert "expected one argument" not in err


def test_a_real_option_after_a_value_is_still_an_option() -> None:
    args = build_parser().parse_args(["calibrate", "D", "--init", NEGATIVE_INIT, "--json"])
    assert args.init == NEGATIVE_INIT and args.json
