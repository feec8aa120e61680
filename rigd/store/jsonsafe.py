"""Values made fit for JSON: the API's responses and the database's JSON columns have no NaN or dates."""

from __future__ import annotations

import datetime as dt
import math
from typing import Any


def json_safe(value: Any) -> Any:
    """``value`` with non-finite floats as None, dates as ISO text, tuples as lists, other objects as text."""
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, dt.date | dt.datetime | dt.time):
        return value.isoformat()
    return str(value)
