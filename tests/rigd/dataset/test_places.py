"""rigd.dataset.places: pairs whose clouds' static background coincides are one place; a step or a turn of the
rig is a new place; people moving between the pairs are not."""

import numpy as np

from rigd.dataset.pcd import Cloud
from rigd.dataset.places import find_places, range_image

RINGS_DEG = np.arange(-15.0, 16.0, 2.0)  # a VLP-16's rings


def room(at_xy=(0.0, 0.0), yaw_deg=0.0, person_deg=None) -> Cloud:
    """A VLP-16 sweep in a 12 x 8 x 3 m room from a rig at ``at_xy`` (m, 1 m above the floor) turned ``yaw_deg``,
    optionally with a person (a 0.5 m post) 2 m away at azimuth ``person_deg``."""
    azimuth = np.radians(np.arange(0.0, 360.0, 0.2))
    az, el = np.meshgrid(azimuth, np.radians(RINGS_DEG))
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).reshape(-1, 3)
    ring = np.repeat(np.arange(len(RINGS_DEG), dtype=np.int16), len(azimuth))
    yaw = np.radians(yaw_deg)
    world = d @ np.array([[np.cos(yaw), np.sin(yaw), 0], [-np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    origin = np.array([at_xy[0], at_xy[1], 1.0])
    bounds = np.array([[-6.0, 6.0], [-4.0, 4.0], [0.0, 3.0]])
    with np.errstate(divide="ignore"):
        t = np.where(world > 0, (bounds[:, 1] - origin) / world, (bounds[:, 0] - origin) / world)
    r = np.min(np.where(t > 0, t, np.inf), axis=1)
    if person_deg is not None:
        near = np.abs((np.degrees(np.arctan2(d[:, 1], d[:, 0])) - person_deg + 180) % 360 - 180) < 7.0
        r = np.where(near & (np.abs(d[:, 2]) < 0.4), np.minimum(r, 2.0), r)
    return Cloud(d * r[:, None], None, ring)


def test_people_moving_keep_one_place_and_a_step_or_a_turn_makes_a_new_one():
    clouds = [room(), room(person_deg=30.0), room(person_deg=-60.0), room((1.0, 0.0)), room(yaw_deg=10.0),
              room(person_deg=100.0)]
    assert find_places([range_image(c) for c in clouds]) == (0, 0, 0, 1, 2, 0)


def test_without_rings_the_elevation_rows_compare_the_same():
    plain = [Cloud(c.points_lidar) for c in (room(), room(person_deg=45.0), room((0.0, 1.5)))]
    assert find_places([range_image(c) for c in plain]) == (0, 0, 1)
