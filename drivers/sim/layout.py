"""Small placement helpers shared by the scene generators: wall slots and floor footprints."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.sim.scene import Face

Rect2 = tuple[float, float, float, float]  # (x_lo, x_hi, y_lo, y_hi) m


@dataclass
class Wall:
    """The inner face of a wall box: ``face`` of ``box``, spanning ``extent`` along world axis ``along``.

    ``plane`` is the face's coordinate on its normal axis, ``inward`` (+1/-1) the direction into the room.
    ``taken`` collects the (lo, hi) stretches already used along the wall.
    """

    box: int
    face: Face
    along: int
    extent: tuple[float, float]
    plane: float
    inward: int
    taken: list[tuple[float, float]] = field(default_factory=list)

    def slot(self, rng: np.random.Generator, width: float, margin: float = 0.15, tries: int = 30) -> float | None:
        """Start of a free stretch of ``width`` m along the wall (and reserve it), or None."""
        lo, hi = self.extent[0] + margin, self.extent[1] - margin - width
        if hi <= lo:
            return None
        for _ in range(tries):
            start = float(rng.uniform(lo, hi))
            if all(start + width + margin <= a or start >= b + margin for a, b in self.taken):
                self.taken.append((start, start + width))
                return start
        return None

    def footprint(self, start: float, width: float, depth: float) -> Rect2:
        """Floor rectangle of an object ``depth`` m deep standing against the wall at ``start``."""
        near, far = sorted((self.plane, self.plane + self.inward * depth))
        if self.along == 1:
            return near, far, start, start + width
        return start, start + width, near, far

    def front_face(self) -> Face:
        """The face of an object against this wall that looks into the room."""
        return self.face


@dataclass
class Floor:
    """Footprints (x_lo, x_hi, y_lo, y_hi) already standing on the floor."""

    taken: list[Rect2] = field(default_factory=list)

    def free(self, rect: Rect2, margin: float) -> bool:
        x0, x1, y0, y1 = rect
        return all(x1 + margin <= a or x0 >= b + margin or y1 + margin <= c or y0 >= d + margin
                   for a, b, c, d in self.taken)

    def take(self, rect: Rect2) -> None:
        self.taken.append(rect)


def contrasting(rng: np.random.Generator, base: float, min_diff: float = 0.2) -> float:
    """A grey in [0.05, 0.95] that differs from ``base`` by at least ``min_diff``."""
    for _ in range(20):
        value = float(rng.uniform(0.05, 0.95))
        if abs(value - base) >= min_diff:
            return value
    return 0.1 if base > 0.5 else 0.9
