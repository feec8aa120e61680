"""Values made fit for JSON: the API's responses and the database's JSON columns have no NaN, dates or lone
surrogates."""

from __future__ import annotations

import datetime as dt
import math
from typing import Any


def unicode_safe(text: str) -> str:
    """``text`` with lone surrogates (``"\\ud800"``: valid in JSON, not encodable as UTF-8) spelled out as
    ``\\ud800``; other text unchanged."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return text


def json_safe(value: Any) -> Any:
    """``value`` with non-finite floats as None, dates as ISO text, tuples as lists, other objects as text,
    and text made encodable as UTF-8 (:func:`unicode_safe`)."""
    if isinstance(value, str):
        return unicode_safe(value)
    if isinstance(value, bool | int) or value is None:
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {unicode_safe(str(k)): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, dt.date | dt.datetime | dt.time):
        return value.isoformat()
    return unicode_safe(str(value))
