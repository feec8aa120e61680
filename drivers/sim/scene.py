"""Scenes made of axis-aligned boxes with per-face albedo, paint and recesses.

- A *box* is solid; each of its six faces has a grey albedo in [0, 1] (diffuse reflectance).
- A *paint* is a rectangle on one face that changes the albedo (and may emit light) without geometry:
  posters, road markings, window panes, ceiling lights. Later paints cover earlier ones.
- A *recess* is a rectangular pocket cut into one face, ``depth_m`` deep: recessed doors and windows,
  shelf compartments. Its back wall has its own albedo; its side walls (reveals) take the face's albedo.

Rectangles on a face are given in the face's two in-plane world axes in ascending order (a face normal
to x uses (y, z); normal to y uses (x, z); normal to z uses (x, y)), as ``(lo_a, hi_a, lo_b, hi_b)`` m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum, IntEnum

import numpy as np
from numpy.typing import NDArray

from drivers.sim.errors import SimError

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

# The two in-plane axes of a face normal to each axis.
IN_PLANE_AXES = ((1, 2), (0, 2), (0, 1))


class SceneKind(Enum):
    INDOOR = "indoor"
    OUTDOOR = "outdoor"


class Face(IntEnum):
    """Face index ``2 * axis + side``; side 0 is the face at the box minimum, 1 at the maximum."""

    X_MIN = 0
    X_MAX = 1
    Y_MIN = 2
    Y_MAX = 3
    Z_MIN = 4
    Z_MAX = 5

    @property
    def axis(self) -> int:
        return int(self) // 2

    @property
    def side(self) -> int:
        return int(self) % 2


@dataclass(frozen=True)
class Lighting:
    """Radiance model: ``L = albedo * (ambient + sun * max(0, n . sun_dir) * lit) + emission``.

    ``sun_dir_world`` (3,) unit vector towards the light. ``shadows``: cast hard shadows from it (a sun;
    indoors the light comes from many lamps, so no hard shadows). Rays that hit nothing see the sky,
    ``sky_horizon`` at the horizon blending to ``sky_zenith`` straight up. ``exposure`` scales radiance
    before the camera's response curve.
    """

    sun_dir_world: F64
    ambient: float
    sun: float
    shadows: bool
    sky_horizon: float = 1.0
    sky_zenith: float = 0.75
    exposure: float = 1.0


@dataclass(frozen=True)
class Scene:
    """A frozen scene. B boxes, P paints, R recesses; all coordinates world metres.

    ``box_min``/``box_max`` (B,3); ``face_albedo`` (B,6) indexed by :class:`Face`; ``texture_amp`` (B,)
    relative albedo variation of the surface texture; ``paint_box``/``paint_face`` (P,) int64,
    ``paint_rect`` (P,4), ``paint_albedo``/``paint_emission`` (P,); ``recess_box``/``recess_face`` (R,)
    int64, ``recess_rect`` (R,4), ``recess_depth_m``/``recess_albedo`` (R,). ``free_area`` (4,) is the
    (x_lo, x_hi, y_lo, y_hi) m region where a rig may stand, ``floor_z_m`` the height it stands on.
    """

    kind: SceneKind
    box_min: F64
    box_max: F64
    face_albedo: F64
    texture_amp: F64
    paint_box: I64
    paint_face: I64
    paint_rect: F64
    paint_albedo: F64
    paint_emission: F64
    recess_box: I64
    recess_face: I64
    recess_rect: F64
    recess_depth_m: F64
    recess_albedo: F64
    lighting: Lighting
    free_area: F64
    floor_z_m: float
    rig_height_m: tuple[float, float]

    # Derived once (ray casting uses them on every call): recess pockets as AABBs, box bounding spheres.
    recess_min: F64 = field(init=False, repr=False)
    recess_max: F64 = field(init=False, repr=False)
    box_centre: F64 = field(init=False, repr=False)
    box_radius: F64 = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lo, hi = _recess_volumes(self)
        object.__setattr__(self, "recess_min", lo)
        object.__setattr__(self, "recess_max", hi)
        object.__setattr__(self, "box_centre", (self.box_min + self.box_max) / 2.0)
        object.__setattr__(self, "box_radius", np.linalg.norm(self.box_max - self.box_min, axis=1) / 2.0)

    @property
    def n_boxes(self) -> int:
        return len(self.box_min)


def _recess_volumes(scene: Scene) -> tuple[F64, F64]:
    """The pocket of each recess as an AABB (min (R,3), max (R,3)), poking 1 mm out of its face.

    The pocket opens outwards, so a ray that enters through the opening leaves it through the back or a
    side wall: that exit is where the ray hits the recessed surface.
    """
    rows = np.arange(len(scene.recess_box))
    axis, side = scene.recess_face // 2, scene.recess_face % 2
    in_plane = np.array(IN_PLANE_AXES)[axis]
    lo, hi = np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
    for k in range(2):
        lo[rows, in_plane[:, k]] = scene.recess_rect[:, 2 * k]
        hi[rows, in_plane[:, k]] = scene.recess_rect[:, 2 * k + 1]
    plane = np.where(side == 1, scene.box_max[scene.recess_box, axis], scene.box_min[scene.recess_box, axis])
    depth = scene.recess_depth_m
    lo[rows, axis] = np.where(side == 1, plane - depth, plane - 1e-3)
    hi[rows, axis] = np.where(side == 1, plane + 1e-3, plane + depth)
    return lo, hi


@dataclass
class SceneBuilder:
    """Mutable collector used by the scene generators; :meth:`build` freezes it into a :class:`Scene`."""

    boxes: list[tuple[F64, F64, F64, float]] = field(default_factory=list)
    paints: list[tuple[int, int, tuple[float, float, float, float], float, float]] = field(default_factory=list)
    recesses: list[tuple[int, int, tuple[float, float, float, float], float, float]] = field(
        default_factory=list
    )

    def box(self, lo: tuple[float, ...] | F64, hi: tuple[float, ...] | F64,
            albedo: float | tuple[float, ...] | F64, texture: float = 0.04) -> int:
        """Add a box from corner ``lo`` to ``hi`` (m); ``albedo`` one value or six (per :class:`Face`)."""
        lo_a, hi_a = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        if lo_a.shape != (3,) or hi_a.shape != (3,) or np.any(hi_a <= lo_a):
            raise SimError(f"box needs lo < hi on every axis, got lo={lo_a} hi={hi_a}")
        faces = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (6,)).copy()
        self.boxes.append((lo_a, hi_a, np.clip(faces, 0.0, 1.0), float(texture)))
        return len(self.boxes) - 1

    def face_rect(self, box: int, face: Face) -> tuple[float, float, float, float]:
        """The full rectangle of a face of ``box`` in its in-plane axes."""
        lo, hi = self.boxes[box][0], self.boxes[box][1]
        a, c = IN_PLANE_AXES[face.axis]
        return float(lo[a]), float(hi[a]), float(lo[c]), float(hi[c])

    def paint(self, box: int, face: Face, rect: tuple[float, float, float, float], albedo: float,
              emission: float = 0.0) -> None:
        self.paints.append((box, int(face), _checked_rect(rect), float(np.clip(albedo, 0, 1)), float(emission)))

    def recess(self, box: int, face: Face, rect: tuple[float, float, float, float], depth_m: float,
               albedo: float) -> None:
        lo, hi = self.boxes[box][0], self.boxes[box][1]
        if not 0 < depth_m < hi[face.axis] - lo[face.axis]:
            raise SimError(f"recess depth {depth_m} m does not fit in box {box} along axis {face.axis}")
        self.recesses.append((box, int(face), _checked_rect(rect), float(depth_m), float(np.clip(albedo, 0, 1))))

    def build(self, kind: SceneKind, lighting: Lighting, free_area: tuple[float, float, float, float],
              floor_z_m: float, rig_height_m: tuple[float, float]) -> Scene:
        if not self.boxes:
            raise SimError("a scene needs at least one box")
        p, r = self.paints, self.recesses
        return Scene(
            kind=kind,
            box_min=np.array([b[0] for b in self.boxes]),
            box_max=np.array([b[1] for b in self.boxes]),
            face_albedo=np.array([b[2] for b in self.boxes]),
            texture_amp=np.array([b[3] for b in self.boxes]),
            paint_box=np.array([x[0] for x in p], dtype=np.int64),
            paint_face=np.array([x[1] for x in p], dtype=np.int64),
            paint_rect=np.array([x[2] for x in p], dtype=np.float64).reshape(-1, 4),
            paint_albedo=np.array([x[3] for x in p], dtype=np.float64),
            paint_emission=np.array([x[4] for x in p], dtype=np.float64),
            recess_box=np.array([x[0] for x in r], dtype=np.int64),
            recess_face=np.array([x[1] for x in r], dtype=np.int64),
            recess_rect=np.array([x[2] for x in r], dtype=np.float64).reshape(-1, 4),
            recess_depth_m=np.array([x[3] for x in r], dtype=np.float64),
            recess_albedo=np.array([x[4] for x in r], dtype=np.float64),
            lighting=lighting,
            free_area=np.asarray(free_area, dtype=np.float64),
            floor_z_m=float(floor_z_m),
            rig_height_m=rig_height_m,
        )


def _checked_rect(rect: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    a0, a1, b0, b1 = (float(x) for x in rect)
    if not (a1 > a0 and b1 > b0):
        raise SimError(f"rectangle needs lo < hi on both axes, got {rect}")
    return a0, a1, b0, b1
