"""Seeded indoor scenes: an office-like room with furniture, pillars, doors, posters and ceiling lights.

The room spans x in [0, L], y in [0, W], z in [0, H] (L 6-12 m, W 5-10 m, H 2.6-3.5 m); walls, floor and
ceiling are 0.2 m slabs that overlap at the corners so the room is closed (every camera ray hits).
"""

from __future__ import annotations

import numpy as np

from drivers.sim.layout import Floor, Wall, contrasting
from drivers.sim.scene import Face, Lighting, Scene, SceneBuilder, SceneKind

SLAB_M = 0.2
RIG_CLEARANCE_M = 0.9  # furniture keeps this far from the centre of the room so the rig fits


def indoor_scene(rng: np.random.Generator) -> Scene:
    length, width, height = rng.uniform(6.0, 12.0), rng.uniform(5.0, 10.0), rng.uniform(2.6, 3.5)
    b = SceneBuilder()
    walls = _shell(b, rng, length, width, height)
    floor = Floor()
    for wall in walls:
        _skirting(b, rng, wall)
    for _ in range(rng.integers(1, 4)):
        _door(b, rng, walls[rng.integers(4)], height)
    for _ in range(rng.integers(3, 9)):
        _wall_furniture(b, rng, walls[rng.integers(4)], floor, height)
    for _ in range(rng.integers(0, 2)):
        _whiteboard(b, rng, walls[rng.integers(4)])
    for _ in range(rng.integers(2, 7)):
        _poster(b, rng, walls[rng.integers(4)], height)
    for _ in range(rng.integers(0, 3)):
        _pillar(b, rng, floor, length, width, height)
    for _ in range(rng.integers(0, 3)):
        _desk(b, rng, floor, length, width)
    _ceiling(b, rng, length, width, height)
    elevation, azimuth = np.radians(rng.uniform(55, 80)), rng.uniform(0, 2 * np.pi)
    sun_dir = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    ambient = float(rng.uniform(0.45, 0.6))
    lighting = Lighting(sun_dir_world=sun_dir, ambient=ambient, sun=1.0 - ambient, shadows=False)
    free = (0.7, length - 0.7, 0.7, width - 0.7)
    return b.build(SceneKind.INDOOR, lighting, free, floor_z_m=0.0, rig_height_m=(1.2, 1.8))


def _shell(b: SceneBuilder, rng: np.random.Generator, length: float, width: float, height: float) -> list[Wall]:
    t = SLAB_M
    wall_grey = float(rng.uniform(0.55, 0.85))
    greys = [wall_grey] * 4
    if rng.random() < 0.3:  # an accent wall
        greys[rng.integers(4)] = contrasting(rng, wall_grey)
    b.box((-t, -t, -t), (length + t, width + t, 0.0), rng.uniform(0.15, 0.45), texture=0.08)
    b.box((-t, -t, height), (length + t, width + t, height + t), rng.uniform(0.75, 0.9), texture=0.03)
    x0 = b.box((-t, -t, 0.0), (0.0, width + t, height), greys[0])
    x1 = b.box((length, -t, 0.0), (length + t, width + t, height), greys[1])
    y0 = b.box((0.0, -t, 0.0), (length, 0.0, height), greys[2])
    y1 = b.box((0.0, width, 0.0), (length, width + t, height), greys[3])
    return [
        Wall(x0, Face.X_MAX, 1, (0.0, width), 0.0, 1),
        Wall(x1, Face.X_MIN, 1, (0.0, width), length, -1),
        Wall(y0, Face.Y_MAX, 0, (0.0, length), 0.0, 1),
        Wall(y1, Face.Y_MIN, 0, (0.0, length), width, -1),
    ]


def _skirting(b: SceneBuilder, rng: np.random.Generator, wall: Wall) -> None:
    grey = float(b.boxes[wall.box][2][int(wall.face)])
    b.paint(wall.box, wall.face, (wall.extent[0], wall.extent[1], 0.0, rng.uniform(0.07, 0.12)),
            contrasting(rng, grey, 0.15))


def _door(b: SceneBuilder, rng: np.random.Generator, wall: Wall, height: float) -> None:
    door_w, door_h = rng.uniform(0.85, 1.0), min(rng.uniform(2.0, 2.15), height - 0.3)
    frame = rng.uniform(0.05, 0.08)
    start = wall.slot(rng, door_w + 2 * frame, margin=0.3)
    if start is None:
        return
    grey = float(b.boxes[wall.box][2][int(wall.face)])
    opening = (start + frame, start + frame + door_w, 0.0, door_h)
    b.paint(wall.box, wall.face, (start, start + door_w + 2 * frame, 0.0, door_h + frame), contrasting(rng, grey, 0.15))
    leaf = contrasting(rng, grey, 0.2)
    if rng.random() < 0.7:
        b.recess(wall.box, wall.face, opening, rng.uniform(0.04, 0.12), leaf)
    else:  # a flush door: paint only
        b.paint(wall.box, wall.face, opening, leaf)


def _wall_furniture(b: SceneBuilder, rng: np.random.Generator, wall: Wall, floor: Floor, height: float) -> None:
    shelf = rng.random() < 0.4
    w = rng.uniform(0.8, 1.6) if shelf else rng.uniform(0.4, 1.2)
    depth = rng.uniform(0.3, 0.4) if shelf else rng.uniform(0.4, 0.6)
    top = min(rng.uniform(1.2, 2.2) if shelf else rng.uniform(0.75, 2.0), height - 0.3)
    start = wall.slot(rng, w)
    if start is None:
        return
    x0, x1, y0, y1 = wall.footprint(start, w, depth)
    floor.take((x0, x1, y0, y1))
    grey = contrasting(rng, float(b.boxes[wall.box][2][int(wall.face)]), 0.15)
    box = b.box((x0, y0, 0.0), (x1, y1, top), grey, texture=0.03)
    front = wall.front_face()
    if shelf:
        _shelf_compartments(b, rng, box, front, start, w, top, depth, grey)
    else:
        _cabinet_front(b, box, front, start, w, top)


def _shelf_compartments(b: SceneBuilder, rng: np.random.Generator, box: int, front: Face, start: float,
                        w: float, top: float, depth: float, grey: float) -> None:
    board = 0.02
    cols = max(1, int(w // 0.8))
    rows = max(1, int((top - 0.1) // 0.38))
    col_w = (w - board * (cols + 1)) / cols
    row_h = (top - 0.1 - board * (rows + 1)) / rows
    inside = grey * rng.uniform(0.3, 0.7)  # the back panel, darker than the carcass
    for c in range(cols):
        for r in range(rows):
            a0 = start + board + c * (col_w + board)
            z0 = 0.1 + board + r * (row_h + board)
            b.recess(box, front, (a0, a0 + col_w, z0, z0 + row_h), depth - board, inside)


def _cabinet_front(b: SceneBuilder, box: int, front: Face, start: float, w: float, top: float) -> None:
    if w > 0.7:  # two doors: a dark gap down the middle
        mid = start + w / 2
        b.paint(box, front, (mid - 0.005, mid + 0.005, 0.02, top - 0.02), 0.05)
        handles = [mid - 0.06, mid + 0.04]
    else:
        handles = [start + w - 0.08]
    z = min(1.0, top - 0.2)
    for h in handles:
        b.paint(box, front, (h, h + 0.02, z - 0.08, z + 0.08), 0.08)


def _whiteboard(b: SceneBuilder, rng: np.random.Generator, wall: Wall) -> None:
    w = rng.uniform(1.2, 2.4)
    start = wall.slot(rng, w)
    if start is None:
        return
    x0, x1, y0, y1 = wall.footprint(start, w, 0.02)
    z0 = rng.uniform(0.85, 1.0)
    b.box((x0, y0, z0), (x1, y1, z0 + rng.uniform(0.9, 1.2)), 0.92, texture=0.01)


def _poster(b: SceneBuilder, rng: np.random.Generator, wall: Wall, height: float) -> None:
    w, h = rng.uniform(0.4, 1.2), rng.uniform(0.5, 1.0)
    start = wall.slot(rng, w, margin=0.2)
    if start is None:
        return
    z0 = min(rng.uniform(1.0, 1.5), height - h - 0.2)
    grey = float(b.boxes[wall.box][2][int(wall.face)])
    outer = contrasting(rng, grey)
    b.paint(wall.box, wall.face, (start, start + w, z0, z0 + h), outer)
    if rng.random() < 0.6:  # picture content: an inner block
        m = rng.uniform(0.05, 0.15)
        b.paint(wall.box, wall.face, (start + m, start + w - m, z0 + m, z0 + h - 2 * m), contrasting(rng, outer))


def _pillar(b: SceneBuilder, rng: np.random.Generator, floor: Floor, length: float, width: float,
            height: float) -> None:
    side = rng.uniform(0.4, 0.8)
    for _ in range(20):
        x, y = rng.uniform(1.2, length - 1.2 - side), rng.uniform(1.2, width - 1.2 - side)
        rect = (x, x + side, y, y + side)
        if floor.free(rect, RIG_CLEARANCE_M):
            floor.take(rect)
            b.box((x, y, 0.0), (x + side, y + side, height), rng.uniform(0.5, 0.85))
            return


def _desk(b: SceneBuilder, rng: np.random.Generator, floor: Floor, length: float, width: float) -> None:
    size = (rng.uniform(1.2, 1.8), rng.uniform(0.6, 0.8))
    sx, sy = size if rng.random() < 0.5 else size[::-1]
    for _ in range(20):
        x, y = rng.uniform(0.3, length - 0.3 - sx), rng.uniform(0.3, width - 0.3 - sy)
        rect = (x, x + sx, y, y + sy)
        if floor.free(rect, RIG_CLEARANCE_M):
            floor.take(rect)
            _desk_boxes(b, rng, rect)
            return


def _desk_boxes(b: SceneBuilder, rng: np.random.Generator, rect: tuple[float, float, float, float]) -> None:
    x0, x1, y0, y1 = rect
    top_z, t = rng.uniform(0.72, 0.76), 0.03
    grey = rng.uniform(0.3, 0.85)
    legs = rng.uniform(0.2, 0.6)
    b.box((x0, y0, top_z - t), (x1, y1, top_z), grey, texture=0.03)
    if x1 - x0 >= y1 - y0:  # side panels at the short ends
        b.box((x0, y0, 0.0), (x0 + t, y1, top_z - t), legs)
        b.box((x1 - t, y0, 0.0), (x1, y1, top_z - t), legs)
    else:
        b.box((x0, y0, 0.0), (x1, y0 + t, top_z - t), legs)
        b.box((x0, y1 - t, 0.0), (x1, y1, top_z - t), legs)
    if rng.random() < 0.6:  # a monitor on a stand
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        b.box((cx - 0.03, cy - 0.03, top_z), (cx + 0.03, cy + 0.03, top_z + 0.12), 0.15)
        half = (0.28, 0.03) if x1 - x0 >= y1 - y0 else (0.03, 0.28)
        b.box((cx - half[0], cy - half[1], top_z + 0.12), (cx + half[0], cy + half[1], top_z + 0.45), 0.06)


def _ceiling(b: SceneBuilder, rng: np.random.Generator, length: float, width: float, height: float) -> None:
    ceiling = 1
    grey = float(b.boxes[ceiling][2][int(Face.Z_MIN)])
    if rng.random() < 0.5:  # suspended ceiling: a 0.6 m tile grid
        line = grey - rng.uniform(0.1, 0.2)
        for x in np.arange(0.6, length, 0.6):
            b.paint(ceiling, Face.Z_MIN, (x - 0.012, x + 0.012, 0.0, width), line)
        for y in np.arange(0.6, width, 0.6):
            b.paint(ceiling, Face.Z_MIN, (0.0, length, y - 0.012, y + 0.012), line)
    if rng.random() < 0.3:  # a beam across the room
        x = rng.uniform(1.5, length - 1.5)
        b.box((x - 0.15, 0.0, height - rng.uniform(0.3, 0.45)), (x + 0.15, width, height), grey)
    pitch = rng.uniform(1.8, 2.4)
    lx, ly = (0.6, 0.6) if rng.random() < 0.5 else (1.2, 0.3)
    emission = rng.uniform(1.2, 2.0)
    for cx in np.arange(pitch / 2 + rng.uniform(0, 0.5), length - 0.5, pitch):
        for cy in np.arange(pitch / 2 + rng.uniform(0, 0.5), width - 0.5, pitch):
            b.paint(ceiling, Face.Z_MIN, (cx - lx / 2, cx + lx / 2, cy - ly / 2, cy + ly / 2), 0.9, emission)
