"""The page's one vocabulary: angles in °, lengths in cm (times in ms where they are offsets between clocks),
methods by their names, and the words of reports stored by earlier releases said as the page says them now.

The reports' and the capture's own texts (the verdict's reasons, a check's reasons, the capture's stage) are
written for the terminal as well, where ``deg`` and ``mm`` are what a keyboard types; the page shows them in its
units. Only forms named here are rewritten, so a text worded otherwise is shown as it is.
"""

from __future__ import annotations

import re

from calib.methods import METHODS, Method
from calib.uncertainty import AXES

ROTATION_AXES = AXES[:3]

# An axis's sigma against its tolerance, as verdicts were worded before they said "known to ±...".
_OLD_REASON = re.compile(r"^(roll|pitch|yaw|x|y|z): ([\d.]+) sigma = ([\d.e+-]+) > tolerance ([\d.e+-]+)")
# A check's drift said with its test statistic: the length against the threshold is what the operator acts on.
_T2 = re.compile(r"; real: T² [\d.e+-]+ > [\d.e+-]+")
_DEG = re.compile(r"(\d) ?deg\b")
_MM = re.compile(r"(\d+(?:\.\d+)?) mm\b")
_SIGMA = re.compile(r"(\d) sigma\b")
# An axis with a signed value and no unit ("solution 1 ended roll -1.14, y -6.46 away"): its unit added.
_AXIS_VALUE = re.compile(r"\b(roll|pitch|yaw|x|y|z) ([+-]\d+(?:\.\d+)?(?:e[+-]?\d+)?)(?![\d.°]| ?(?:cm|deg|°|mm|m)\b)")


def unit(axis: str) -> str:
    """° for roll, pitch and yaw; " cm" for x, y and z."""
    return "°" if axis in ROTATION_AXES else " cm"


def _known_to(match: re.Match[str]) -> str:
    axis, known, needed = match.group(1), float(match.group(3)), float(match.group(4))
    return f"{axis} known to ±{known:.2f}{unit(axis)} (needs ±{needed:.2f}{unit(axis)})"


def _cm(match: re.Match[str]) -> str:
    text = match.group(1)
    decimals = len(text.partition(".")[2]) + 1
    return f"{float(text) / 10.0:.{decimals}f} cm"


def page_words(text: str) -> str:
    """``text`` in the page's units and words (module docstring)."""
    text = _OLD_REASON.sub(_known_to, text)
    text = _T2.sub("", text)
    text = _DEG.sub(r"\1°", text)
    text = _MM.sub(_cm, text)
    text = _AXIS_VALUE.sub(lambda m: f"{m.group(1)} {m.group(2)}{unit(m.group(1))}", text)
    return _SIGMA.sub(r"\1 σ", text)


def method_name(name: str) -> str:
    """A method's name in words (``gmm``: GMM edge alignment); one this release does not know, as stored."""
    try:
        return METHODS[Method(name)].label
    except ValueError:
        return name
