"""Ray casting against a :class:`~drivers.sim.scene.Scene`: numpy over rays, a Python loop over boxes.

Rays are first sorted into coherent bundles (similar direction, nearby origin) and cast in chunks; each
chunk only tests the boxes whose bounding sphere lies inside the chunk's cone, nearest first, and stops
when every ray of the chunk already has a hit nearer than the next box can be.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.sim.errors import SimError
from drivers.sim.scene import IN_PLANE_AXES, Scene
from drivers.sim.texture import value_noise

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

CHUNK_RAYS = 4096
_T_MIN_M = 1e-9  # a ray starting on a surface does not hit that surface
_IN_PLANE = np.array(IN_PLANE_AXES)
_PAINT_BLOCK = 1 << 22  # rays x paints tested at once when resolving paint


@dataclass(frozen=True)
class Hits:
    """First hits of N rays (world frame).

    ``depth_m`` (N,) float64 distance along the unit ray, inf where nothing was hit; ``albedo`` (N,) in
    [0, 1] including paint and texture (0 where no hit); ``normal`` (N,3) unit surface normal facing the ray
    origin (0 where no hit); ``emission`` (N,) emitted radiance of lamps (0 elsewhere).
    """

    depth_m: F64
    albedo: F64
    normal: F64
    emission: F64

    @property
    def hit(self) -> NDArray[np.bool_]:
        return np.isfinite(self.depth_m)


@dataclass(frozen=True)
class _Raw:
    """What the box loop finds per ray: distance, box, axis of the face hit, recess (-1 for none)."""

    t: F64
    box: I64
    axis: I64
    recess: I64


def cast(scene: Scene, origins: F64, directions: F64, chunk_rays: int = CHUNK_RAYS) -> Hits:
    """First hits of rays from ``origins`` (N,3) or (3,) m along ``directions`` (N,3) (normalised here)."""
    d = np.asarray(directions, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise SimError(f"directions must be (N,3), got shape {d.shape}")
    o = np.broadcast_to(np.asarray(origins, dtype=np.float64), d.shape)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    if np.any(~np.isfinite(norm)) or np.any(norm == 0) or not np.all(np.isfinite(o)):
        raise SimError("ray origins must be finite and directions finite and non-zero")
    d = d / norm
    raw = _cast_raw(scene, o, d, chunk_rays)
    return _resolve_surfaces(scene, o, d, raw)


def _cast_raw(scene: Scene, o: F64, d: F64, chunk_rays: int) -> _Raw:
    n = len(d)
    t = np.full(n, np.inf)
    box, axis, recess = np.full(n, -1, np.int64), np.zeros(n, np.int64), np.full(n, -1, np.int64)
    if n == 0:  # e.g. no shadow rays to trace in a chunk: nothing to order or cast
        return _Raw(t, box, axis, recess)
    # No exact zeros: 1/d must be finite-signed so the slab test never computes 0 * inf.
    d_safe = np.where(np.abs(d) < 1e-12, np.where(d < 0, -1e-12, 1e-12), d)
    order = _coherent_order(o, d)
    shared_origin = bool(np.all(o == o[0]))
    recesses_of = {int(b): np.flatnonzero(scene.recess_box == b) for b in np.unique(scene.recess_box)}
    for start in range(0, n, chunk_rays):
        idx = order[start : start + chunk_rays]
        o_chunk = o[0] if shared_origin else o[idx]
        res = _cast_chunk(scene, o_chunk, d_safe[idx], recesses_of)
        t[idx], box[idx], axis[idx], recess[idx] = res.t, res.box, res.axis, res.recess
    return _Raw(t, box, axis, recess)


def _coherent_order(o: F64, d: F64) -> I64:
    """Ray order grouping similar directions (cells of a 24^3 grid on the unit cube) within 2 m origin cells."""
    cell = np.minimum(((d + 1.0) * 12.0).astype(np.int64), 23)
    key = (cell[:, 0] * 24 + cell[:, 1]) * 24 + cell[:, 2]
    span = np.ptp(o, axis=0)
    if np.any(span > 0):
        vox = np.floor((o - o.min(axis=0)) / 2.0).astype(np.int64)
        dims = vox.max(axis=0) + 1
        key = key + 24**3 * ((vox[:, 0] * dims[1] + vox[:, 1]) * dims[2] + vox[:, 2])
    if key.max() < 2**16:  # numpy sorts 16-bit keys by radix sort: much faster than a comparison sort
        key = key.astype(np.uint16)
    return np.argsort(key, kind="stable")


def _candidate_boxes(scene: Scene, o: F64, d: F64) -> tuple[I64, F64]:
    """Boxes whose bounding sphere may meet a ray of the chunk, nearest first, with a lower bound on t.

    ``o`` is (3,) for a shared origin or (n,3); ``d`` (n,3) unit directions.
    """
    oc = o if o.ndim == 1 else o.mean(axis=0)
    ro = 0.0 if o.ndim == 1 else float(np.sqrt(np.max(np.sum((o - oc) ** 2, axis=1))))
    v = scene.box_centre - oc
    dist = np.linalg.norm(v, axis=1)
    rad = scene.box_radius + ro
    near = np.maximum(dist - rad, 0.0)
    axis_dir = d.mean(axis=0)
    length = float(np.linalg.norm(axis_dir))
    if length < 0.5:  # a wide bundle: a cone would not cull anything
        keep = np.ones(len(dist), dtype=bool)
    else:
        axis_dir /= length
        half = float(np.arccos(np.clip(np.min(np.einsum("ij,j->i", d, axis_dir)), -1.0, 1.0)))
        with np.errstate(invalid="ignore", divide="ignore"):
            angle = np.arccos(np.clip((v @ axis_dir) / dist, -1.0, 1.0))
            reach = np.arcsin(np.clip(rad / dist, 0.0, 1.0))
        keep = (dist <= rad) | (angle <= half + reach + 1e-9)
    boxes = np.flatnonzero(keep)
    by_distance = np.argsort(near[boxes], kind="stable")
    return boxes[by_distance], near[boxes][by_distance]


def _cast_chunk(scene: Scene, o: F64, d: F64, recesses_of: dict[int, I64]) -> _Raw:
    """Box loop for one bundle: ``o`` (3,) shared origin or (n,3), ``d`` (n,3) without zero components;
    ``recesses_of`` maps a box to its recess indices.

    The slab test works on per-axis contiguous rows (3,n): numpy reductions over a length-3 axis are slow.
    """
    n = len(d)
    t_best = np.full(n, np.inf)
    box, axis, recess = np.full(n, -1, np.int64), np.zeros(n, np.int64), np.full(n, -1, np.int64)
    inv = np.ascontiguousarray((1.0 / d).T)
    o_rows = o[:, None] if o.ndim == 1 else np.ascontiguousarray(o.T)
    boxes, near = _candidate_boxes(scene, o, d)
    for b, near_b in zip(boxes, near, strict=True):
        if near_b >= t_best.max():
            break  # every ray already hit something nearer than this box (and all later ones) can be
        t_lo = (scene.box_min[b][:, None] - o_rows) * inv
        t_hi = (scene.box_max[b][:, None] - o_rows) * inv
        t_min = np.minimum(t_lo, t_hi)
        t_max = np.maximum(t_lo, t_hi)
        t_near = np.maximum(np.maximum(t_min[0], t_min[1]), t_min[2])
        t_far = np.minimum(np.minimum(t_max[0], t_max[1]), t_max[2])
        rays = np.flatnonzero((t_near <= t_far) & (t_near > _T_MIN_M) & (t_near < t_best))
        if len(rays) == 0:
            continue
        t_hit, ax_hit = t_near[rays], t_min[:, rays].argmax(axis=0)
        rec_hit = np.full(len(rays), -1, np.int64)
        pockets = recesses_of.get(int(b))
        if pockets is not None:
            o_r = o if o.ndim == 1 else o[rays]
            t_hit, ax_hit, rec_hit = _enter_recesses(scene, pockets, o_r, d[rays], t_hit, ax_hit)
            nearer = t_hit < t_best[rays]
            rays, t_hit, ax_hit, rec_hit = rays[nearer], t_hit[nearer], ax_hit[nearer], rec_hit[nearer]
        t_best[rays], box[rays], axis[rays], recess[rays] = t_hit, b, ax_hit, rec_hit
    return _Raw(t_best, box, axis, recess)


def _enter_recesses(scene: Scene, pockets: I64, o: F64, d: F64, t: F64, ax: I64) -> tuple[F64, I64, I64]:
    """Move hits that land in a recess opening to where the ray leaves the pocket (its back or a side)."""
    face = 2 * ax + (np.take_along_axis(d, ax[:, None], axis=1)[:, 0] < 0)
    p = o + t[:, None] * d
    rect = scene.recess_rect[pockets]
    axes = _IN_PLANE[scene.recess_face[pockets] // 2]  # (k,2)
    pa, pb = p[:, axes[:, 0]], p[:, axes[:, 1]]  # (m,k)
    inside = ((face[:, None] == scene.recess_face[pockets]) & (pa >= rect[:, 0]) & (pa <= rect[:, 1])
              & (pb >= rect[:, 2]) & (pb <= rect[:, 3]))
    rays = np.flatnonzero(inside.any(axis=1))
    rec = np.full(len(t), -1, np.int64)
    if len(rays) == 0:
        return t, ax, rec
    r = pockets[inside[rays].argmax(axis=1)]
    o_r = o if o.ndim == 1 else o[rays]
    t_lo = (scene.recess_min[r] - o_r) / d[rays]
    t_hi = (scene.recess_max[r] - o_r) / d[rays]
    t_max = np.maximum(t_lo, t_hi)
    t, ax = t.copy(), ax.copy()
    t[rays], ax[rays], rec[rays] = t_max.min(axis=1), t_max.argmin(axis=1), r
    return t, ax, rec


def _resolve_surfaces(scene: Scene, o: F64, d: F64, raw: _Raw) -> Hits:
    """Normals, albedo (face, recess, paint, texture) and emission of the hit surfaces."""
    n = len(d)
    hit = np.flatnonzero(raw.box >= 0)
    b, ax, rec = raw.box[hit], raw.axis[hit], raw.recess[hit]
    d_ax = d[hit, ax]
    normal = np.zeros((n, 3))
    normal[hit, ax] = -np.sign(d_ax)
    face = 2 * ax + (d_ax < 0)
    p = o[hit] + raw.t[hit, None] * d[hit]
    albedo_hit = scene.face_albedo[b, face]
    emission_hit = np.zeros(len(hit))
    in_rec = np.flatnonzero(rec >= 0)
    if len(in_rec):
        r = rec[in_rec]
        back = ax[in_rec] == scene.recess_face[r] // 2
        albedo_hit[in_rec] = np.where(back, scene.recess_albedo[r], scene.face_albedo[b[in_rec], scene.recess_face[r]])
    plain = np.flatnonzero(rec < 0)
    _apply_paint(scene, plain, b[plain] * 6 + face[plain], p, albedo_hit, emission_hit)
    surface_key = np.where(rec < 0, b * 6 + face, 6 * scene.n_boxes + rec * 6 + face)
    coords = np.stack([p[np.arange(len(hit)), _IN_PLANE[ax, k]] for k in range(2)], axis=1)
    albedo_hit *= 1.0 + scene.texture_amp[b] * value_noise(coords, surface_key)
    albedo = np.zeros(n)
    emission = np.zeros(n)
    albedo[hit] = np.clip(albedo_hit, 0.0, 1.0)
    emission[hit] = emission_hit
    return Hits(raw.t, albedo, normal, emission)


def _apply_paint(scene: Scene, rows: I64, key: I64, p: F64, albedo: F64, emission: F64) -> None:
    """Overwrite ``albedo``/``emission`` at ``rows`` where a paint covers the hit; later paints win.

    ``rows`` index the hit arrays ``p``, ``albedo``, ``emission``; ``key`` (len(rows),) is box * 6 + face.
    """
    if len(scene.paint_box) == 0 or len(rows) == 0:
        return
    paint_key = scene.paint_box * 6 + scene.paint_face
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    for k in np.unique(paint_key):
        start, stop = np.searchsorted(sorted_key, [k, k + 1])
        if start == stop:
            continue
        paints = np.flatnonzero(paint_key == k)
        axes = _IN_PLANE[k % 6 // 2]
        rect = scene.paint_rect[paints]
        block = max(1, _PAINT_BLOCK // len(paints))
        for s in range(start, stop, block):
            sel = rows[order[s : min(s + block, stop)]]
            pa, pb = p[sel, axes[0], None], p[sel, axes[1], None]
            inside = (pa >= rect[:, 0]) & (pa <= rect[:, 1]) & (pb >= rect[:, 2]) & (pb <= rect[:, 3])
            covered = np.flatnonzero(inside.any(axis=1))
            top = paints[len(paints) - 1 - inside[covered, ::-1].argmax(axis=1)]
            albedo[sel[covered]] = scene.paint_albedo[top]
            emission[sel[covered]] = scene.paint_emission[top]
