"""Seeded outdoor scenes: a street along x with kerbs, pavements, buildings, poles and parked cars.

The rig stands on the road near the origin. Buildings line both sides 10-30 m away, with a few farther
blocks behind and across the street ends; above them is the sky (no LiDAR return, bright in the image).
A low sun casts hard shadows.
"""

from __future__ import annotations

import numpy as np

from drivers.sim.layout import contrasting
from drivers.sim.scene import Face, Lighting, Scene, SceneBuilder, SceneKind
from drivers.sim.vegetation import street_trees

GROUND_HALF_M = 150.0
FREE_X_M = 10.0  # the rig stands within +-FREE_X_M of the origin along the street


def outdoor_scene(rng: np.random.Generator, trees_rng: np.random.Generator | None = None) -> Scene:
    """A street from ``rng``; with ``trees_rng``, rows of street trees on both pavements too (drawn from that
    generator alone and added last, so the rest of the scene is the same with or without them)."""
    b = SceneBuilder()
    ground_grey = float(rng.uniform(0.2, 0.35))
    ground = b.box((-GROUND_HALF_M, -GROUND_HALF_M, -0.5), (GROUND_HALF_M, GROUND_HALF_M, 0.0), ground_grey,
                   texture=0.12)
    road_half = float(rng.uniform(3.0, 5.0))
    _road(b, rng, ground, road_half)
    kerb_h = float(rng.uniform(0.12, 0.16))
    pavement = float(rng.uniform(2.0, 4.0))
    for side in (-1, 1):
        _kerb_and_pavement(b, rng, side, road_half, kerb_h, pavement)
        edge = road_half + 0.15 + pavement
        _street_furniture(b, rng, side, road_half, kerb_h)
        _buildings(b, rng, side, edge)
        _cars(b, rng, side, road_half)
    _background(b, rng)
    if trees_rng is not None:
        for side in (-1, 1):
            y = road_half + 0.15 + pavement * float(trees_rng.uniform(0.3, 0.7))
            street_trees(b, trees_rng, side, y, kerb_h - 0.01)
    elevation, azimuth = np.radians(rng.uniform(20, 65)), rng.uniform(0, 2 * np.pi)
    sun_dir = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    lighting = Lighting(sun_dir_world=sun_dir, ambient=float(rng.uniform(0.25, 0.35)), sun=0.75, shadows=True,
                        sky_horizon=1.0, sky_zenith=float(rng.uniform(0.65, 0.85)))
    free = (-FREE_X_M, FREE_X_M, -road_half + 1.0, road_half - 1.0)
    return b.build(SceneKind.OUTDOOR, lighting, free, floor_z_m=0.0, rig_height_m=(1.6, 2.2))


def _road(b: SceneBuilder, rng: np.random.Generator, ground: int, half: float) -> None:
    g = GROUND_HALF_M
    top = Face.Z_MAX
    b.paint(ground, top, (-g, g, -half, half), rng.uniform(0.08, 0.16))
    marking = rng.uniform(0.7, 0.85)
    dash, gap = rng.uniform(2.5, 3.5), rng.uniform(4.0, 8.0)
    for x in np.arange(-g + rng.uniform(0, gap), g - dash, dash + gap):
        b.paint(ground, top, (x, x + dash, -0.06, 0.06), marking)
    if rng.random() < 0.6:  # solid edge lines
        for s in (-1, 1):
            y = s * (half - 0.3)
            b.paint(ground, top, (-g, g, y - 0.06, y + 0.06), marking)
    if rng.random() < 0.5:  # a zebra crossing
        x0 = rng.uniform(-25, 25)
        for y in np.arange(-half + 0.3, half - 0.5, 1.0):
            b.paint(ground, top, (x0, x0 + 3.0, y, y + 0.5), marking)


def _kerb_and_pavement(b: SceneBuilder, rng: np.random.Generator, side: int, road_half: float, kerb_h: float,
                       pavement: float) -> None:
    g = GROUND_HALF_M
    k0, k1 = sorted((side * road_half, side * (road_half + 0.15)))
    b.box((-g, k0, 0.0), (g, k1, kerb_h), rng.uniform(0.5, 0.7), texture=0.06)
    p0, p1 = sorted((side * (road_half + 0.15), side * (road_half + 0.15 + pavement)))
    b.box((-g, p0, 0.0), (g, p1, kerb_h - 0.01), rng.uniform(0.35, 0.55), texture=0.1)


def _street_furniture(b: SceneBuilder, rng: np.random.Generator, side: int, road_half: float,
                      kerb_h: float) -> None:
    y = side * (road_half + 0.6)
    spacing = rng.uniform(15, 30)
    for x in np.arange(-60 + rng.uniform(0, spacing), 60, spacing):  # street lights
        w = rng.uniform(0.15, 0.25)
        h = rng.uniform(5.0, 9.0)
        grey = rng.uniform(0.3, 0.6)
        b.box((x - w / 2, y - w / 2, kerb_h), (x + w / 2, y + w / 2, h), grey)
        arm_end = y - side * 1.5
        a0, a1 = sorted((y, arm_end))
        b.box((x - 0.05, a0, h - 0.1), (x + 0.05, a1, h), grey)
        l0, l1 = sorted((arm_end, arm_end + side * 0.5))
        b.box((x - 0.15, l0, h - 0.25), (x + 0.15, l1, h - 0.1), 0.7)
    for _ in range(rng.integers(0, 3)):  # sign posts
        x = rng.uniform(-40, 40)
        b.box((x - 0.04, y - 0.04, kerb_h), (x + 0.04, y + 0.04, 2.6), 0.5)
        b.box((x - 0.3, y - 0.02, 2.0), (x + 0.3, y + 0.02, 2.6), rng.uniform(0.7, 0.9), texture=0.01)
    for _ in range(rng.integers(0, 6)):  # bollards along the kerb
        x = rng.uniform(-30, 30)
        b.box((x - 0.08, y - 0.08, kerb_h), (x + 0.08, y + 0.08, 1.0), rng.uniform(0.2, 0.7))


def _buildings(b: SceneBuilder, rng: np.random.Generator, side: int, edge: float) -> None:
    x = float(rng.uniform(-90, -60))
    while x < 80:
        width = float(rng.uniform(10, 35))
        front = abs(edge) + float(rng.uniform(1.0, 12.0))
        front = min(max(front, 10.0), 30.0)
        depth = float(rng.uniform(10, 20))
        height = float(rng.uniform(6, 30))
        y0, y1 = sorted((side * front, side * (front + depth)))
        _building(b, rng, (x, x + width, y0, y1), height, front_face=Face.Y_MIN if side > 0 else Face.Y_MAX)
        x += width + float(rng.uniform(3, 15))


def _building(b: SceneBuilder, rng: np.random.Generator, rect: tuple[float, float, float, float], height: float,
              front_face: Face) -> None:
    x0, x1, y0, y1 = rect
    grey = float(rng.uniform(0.3, 0.85))
    box = b.box((x0, y0, 0.0), (x1, y1, height), grey, texture=0.05)
    recessed = rng.random() < 0.4
    glass = float(rng.uniform(0.05, 0.25)) if rng.random() < 0.8 else float(rng.uniform(0.6, 0.8))
    storey = float(rng.uniform(3.0, 3.6))
    win_w, win_h = float(rng.uniform(1.0, 2.0)), float(rng.uniform(1.2, 1.8))
    pitch = win_w + float(rng.uniform(1.0, 2.5))
    depth = float(rng.uniform(0.15, 0.3))
    for face in (front_face, Face.X_MIN, Face.X_MAX):
        a0, a1, _, _ = b.face_rect(box, face)
        n = int((a1 - a0 - 1.0) // pitch)
        if n < 1:
            continue
        margin = (a1 - a0 - n * pitch + (pitch - win_w)) / 2
        for floor_z in np.arange(storey, height - storey + 0.5, storey):
            z0 = floor_z + 0.9
            for i in range(n):
                w0 = a0 + margin + i * pitch
                rect_w = (w0, w0 + win_w, z0, z0 + win_h)
                if recessed:
                    b.recess(box, face, rect_w, depth, glass)
                else:
                    b.paint(box, face, rect_w, glass)
        if face is front_face:  # an entrance at street level
            a_mid = float(rng.uniform(a0 + 2.0, a1 - 4.0)) if a1 - a0 > 6.0 else a0 + 1.0
            b.recess(box, face, (a_mid, a_mid + float(rng.uniform(1.2, 2.4)), 0.0, 2.4), 0.4,
                     contrasting(rng, grey))


def _cars(b: SceneBuilder, rng: np.random.Generator, side: int, road_half: float) -> None:
    taken: list[tuple[float, float]] = []
    for _ in range(rng.integers(1, 5)):
        length = float(rng.uniform(4.2, 4.8))
        x = float(rng.uniform(-40, 40))
        if any(x < b1 + 1.0 and x + length > a0 - 1.0 for a0, b1 in taken):
            continue
        taken.append((x, x + length))
        width = float(rng.uniform(1.7, 1.85))
        y_out = side * (road_half - 0.3)
        y0, y1 = sorted((y_out, y_out - side * width))
        _car(b, rng, (x, x + length, y0, y1))


def _car(b: SceneBuilder, rng: np.random.Generator, rect: tuple[float, float, float, float]) -> None:
    x0, x1, y0, y1 = rect
    paint = float(rng.uniform(0.1, 0.85))
    for wx in (x0 + 0.5, x1 - 1.1):  # wheels, 0.6 m across
        for wy0, wy1 in ((y0 + 0.05, y0 + 0.27), (y1 - 0.27, y1 - 0.05)):
            b.box((wx, wy0, 0.0), (wx + 0.6, wy1, 0.6), 0.06, texture=0.0)
    b.box((x0, y0, 0.3), (x1, y1, 1.0), paint, texture=0.01)
    length = x1 - x0
    c0 = x0 + length * float(rng.uniform(0.25, 0.35))
    c1 = c0 + length * float(rng.uniform(0.45, 0.55))
    top = 1.0 + float(rng.uniform(0.4, 0.5))
    cabin = b.box((c0, y0 + 0.08, 1.0), (c1, y1 - 0.08, top), paint, texture=0.01)
    window = 0.07
    for face in (Face.Y_MIN, Face.Y_MAX):
        b.paint(cabin, face, (c0 + 0.1, c1 - 0.1, 1.05, top - 0.05), window)
    for face in (Face.X_MIN, Face.X_MAX):
        b.paint(cabin, face, (y0 + 0.15, y1 - 0.15, 1.05, top - 0.05), window)


def _background(b: SceneBuilder, rng: np.random.Generator) -> None:
    """Blocks 40-90 m away: behind the street-side buildings and across both ends of the street."""
    for _ in range(rng.integers(3, 7)):
        distance = float(rng.uniform(40, 90))
        angle = float(rng.uniform(0, 2 * np.pi))
        cx, cy = distance * np.cos(angle), distance * np.sin(angle)
        half = float(rng.uniform(8, 20))
        b.box((cx - half, cy - half, 0.0), (cx + half, cy + half, float(rng.uniform(10, 40))),
              rng.uniform(0.3, 0.8), texture=0.05)
