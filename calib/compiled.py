"""calib's compiled loops: numba compiles each (or loads it from its cache) on its first call, not at import.

Importing numba costs a process about 55 MB and half a second. The capture daemon, the service and the commands
that never evaluate a cost (`rigd capture`, `serve`, `lidar`, `import`) import calib for its records and options
only, so they never pay it; a calibration pays it at its first edge map, as before at its start.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

_FIRST_CALL = threading.Lock()  # the edges' threads may call a kernel for the first time together


class Kernel:
    """``function`` as ``numba.njit(cache=True, **options)`` compiles it, compiled on the first call.

    ``helpers``: names, in the function's module, of the plain functions it calls; numba finds a kernel's callees
    among its module's globals when it compiles it, so each is replaced there by its compiled form (inlined)
    first. Called from Python they give the same values either way."""

    def __init__(self, function: Callable[..., Any], *, helpers: tuple[str, ...] = (), **options: Any) -> None:
        self.function = function
        self._helpers = helpers
        self._options = options
        self._compiled: Callable[..., Any] | None = None

    def __call__(self, *args: Any) -> Any:
        return (self._compiled or self._compile())(*args)

    def _compile(self) -> Callable[..., Any]:
        with _FIRST_CALL:
            if self._compiled is None:
                import numba  # here: the module's docstring

                module = self.function.__globals__
                for name in self._helpers:
                    module[name] = numba.njit(cache=True, inline="always")(module[name])
                self._compiled = numba.njit(cache=True, **self._options)(self.function)
            return self._compiled
