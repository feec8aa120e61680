"""A kernel compiled at its first call: once, whichever threads call it first, with its helpers compiled in place."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from numba.core.registry import CPUDispatcher

from calib.compiled import Kernel


def _half_py(x: float) -> float:
    return 0.5 * x


def _quarter_py(x: float) -> float:
    return _half(_half(x))  # the helper by its global name, as calib.pixel_grid's kernel calls its own


_half = _half_py
quarter = Kernel(_quarter_py, helpers=("_half",))


def test_threads_that_call_a_kernel_first_together_share_one_compiled_form() -> None:
    assert quarter._compiled is None  # nothing compiled at import
    with ThreadPoolExecutor(4) as threads:
        values = list(threads.map(quarter, [float(k) for k in range(16)]))
    assert values == [k / 4.0 for k in range(16)]
    # Compiled once: a second compile would have wrapped the already compiled helper again, and numba refuses that.
    assert isinstance(quarter._compiled, CPUDispatcher)
    assert isinstance(_half, CPUDispatcher) and _half.py_func is _half_py
