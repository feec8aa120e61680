"""Building and steering the fake libladybug (fake_sdk/): a shared library compiled here with the system C
compiler from a header with the real SDK's struct layouts, and its layout probed like a real SDK's."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.ladybug5.sdk import LadybugLibrary, SdkLayout, probe_layout

FAKE = Path(__file__).resolve().parent / "fake_sdk"
COMPILER = shutil.which("gcc") or shutil.which("cc")
COLS, ROWS = 16, 12  # the fake's useful sensor image
BORDER = (1, 2, 3, 1)  # top, bottom, left, right: odd on purpose (the Bayer phase shifts)
FOCAL, K1, K2 = 10.0, -0.05, 0.01


def build(out: Path, shift: int = 0) -> tuple[Path, SdkLayout]:
    """The fake library and its probed layout; ``shift`` moves every enum value (RIGD_FAKE_SHIFT)."""
    lib = out / "libfakeladybug.so"
    define = [f"-DRIGD_FAKE_SHIFT={shift}"]
    assert COMPILER is not None
    subprocess.run([COMPILER, "-shared", "-fPIC", *define, "-o", str(lib), "-I", str(FAKE),
                    str(FAKE / "fake_ladybug.c"), "-lm"], check=True)
    include = out / "include"
    shutil.copytree(FAKE, include)
    header = include / "ladybug.h"
    header.write_text(header.read_text().replace("#define RIGD_FAKE_SHIFT 0", f"#define RIGD_FAKE_SHIFT {shift}"))
    return lib, probe_layout(include, compiler=COMPILER, out=out / "layout.yaml")


@dataclass
class Fake:
    """A private copy of the fake (its globals start fresh), the binding over it and a handle to steer it."""

    library: LadybugLibrary
    handle: ctypes.CDLL
    path: Path

    def g(self, name: str) -> ctypes.c_int:
        return ctypes.c_int.in_dll(self.handle, name)

    def set(self, **values: int) -> None:
        for name, value in values.items():
            self.g(f"fake_{name}").value = value

    def set_double(self, **values: float) -> None:
        for name, value in values.items():
            ctypes.c_double.in_dll(self.handle, f"fake_{name}").value = value

    def call_log(self) -> str:
        """The configuration, geometry and renderer calls so far, a letter each, in order (fake_ladybug.c)."""
        return (ctypes.c_char * 256).in_dll(self.handle, "fake_render_log").value.decode()

    def lens(self, camera: int, cols: int = COLS, rows: int = ROWS) -> tuple[np.ndarray, np.ndarray]:
        """The fake's true raw-image K (3,3) and D (5,) of ``camera`` (fake_ladybug.c) with ``cols`` x ``rows``
        px sensors (fake_cols, fake_rows)."""
        focal = ctypes.c_double.in_dll(self.handle, "fake_focal").value
        k1 = ctypes.c_double.in_dll(self.handle, "fake_k1").value
        k2 = ctypes.c_double.in_dll(self.handle, "fake_k2").value
        cx, cy = (cols - 1) / 2 + 0.3 * camera, (rows - 1) / 2 - 0.2 * camera
        return np.array([[focal, 0, cx], [0, focal, cy], [0, 0, 1]]), np.array([k1, k2, 0, 0, 0])


def private_copy(built: tuple[Path, SdkLayout], tmp: Path) -> Fake:
    lib_path = tmp / "libfakeladybug.so"
    shutil.copy(built[0], lib_path)
    library = LadybugLibrary(built[1], lib_path)
    return Fake(library, ctypes.CDLL(str(lib_path)), lib_path)  # same path: dlopen returns the same instance
