"""Named points of the store's writes (before and after each commit, around a job's folder) where a test can
stop the process, to show that a restart finds every change whole or not at all (fault injection).

Production code never installs a hook: :func:`at` is then one global lookup.
"""

from __future__ import annotations

from collections.abc import Callable

_hook: Callable[[str], None] | None = None


def at(point: str) -> None:
    """Reached ``point`` (``"versions.add:commit"``, ...): the installed hook, if any, may raise or end the process."""
    if _hook is not None:
        _hook(point)


def install(hook: Callable[[str], None] | None) -> None:
    """Call ``hook(point)`` at every point from now on (None: no more)."""
    global _hook
    _hook = hook
