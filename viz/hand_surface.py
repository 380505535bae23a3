"""A hand surface built from its 21 joints — a tube of capsules along each finger (one capsule per bone, closed
at the base and rounded at the tip) and a palm slab — whose vertices each carry the tactile cell they show, so a
(21, 21) pressure grid paints onto it (`vertex_values`). No MANO files are needed.

Cells follow the official grid geometry (`viz.hand_regions`; left-hand columns, the right hand mirrored
c → 20 − c): each finger's three columns run across the palm side of its tube (little-finger side → thumb
side), the fingertip pad rows 2–3 lie on the distal bone, rows 4–5 on the middle bone and the bend strip rows
7–11 on the proximal bone; the thumb's pad rows 6–7 on its distal bone, 8–9 on its proximal bone and its bend
rows 11–12 on its metacarpal; the palm rows 13–17 on the palm side of the slab, row 13 along the knuckles
(little finger at column 2, index at 14, the thumb's ball at columns 16–19) and row 17 at the wrist. The back
of the hand carries no cell.

Joints: (21, 3) in any metric right-handed frame (WiLoR's head-camera frame: metres), official order. Sizes
scale with the hand (finger radius 16 % of the knuckle width). Triangles wind counter-clockwise seen from
outside for both hands (`tests/viz/test_hand_surface.py` checks the signed volume).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from touchanything.viz.hand_regions import FINGER_JOINTS

RING = 6
"""Vertices around a finger; 0 faces the palm side, 1 and RING − 1 are 60° towards the thumb / little finger."""
FINGER_ROWS = ((0.0, -1), (0.1, 11), (0.3, 10), (0.5, 9), (0.7, 8), (0.9, 7), (1.25, 5), (1.75, 4), (2.25, 3),
               (2.75, 2))
"""(position along the finger in bones from the knuckle, grid row or −1) of each ring of a finger; the tip's
apex shows the last row too."""
THUMB_ROWS = ((0.0, -1), (0.33, 12), (0.67, 11), (1.25, 9), (1.75, 8), (2.25, 7), (2.75, 6))
"""The same for the thumb (from its base joint 1: metacarpal, proximal, distal bone)."""
CENTRE_COLUMN = {"thumb": 18, "index": 14, "middle": 10, "ring": 6, "little": 2}
"""The middle column of each finger's pads on the left-hand grid."""
PALM_ROWS, PALM_COLUMNS = np.arange(13, 18), np.arange(1, 20)
FINGER_RADIUS, THUMB_SCALE, TIP_TAPER, PALM_HALF_THICKNESS = 0.16, 1.15, 0.8, 0.18
"""Finger radius and palm half-thickness as fractions of the knuckle width |J5 − J17|; the thumb is thicker, the
tips thinner."""
EPS = 1e-9


@dataclass(frozen=True)
class HandTopology:
    """What does not change from frame to frame: triangles (F, 3) int32 and, per vertex, the flat index
    r · 21 + c of its cell in the hand's own grid (−1: no cell)."""

    triangles: np.ndarray
    cells: np.ndarray

    @property
    def num_vertices(self) -> int:
        return len(self.cells)


def _column(side: int, column: int) -> int:
    """A left-grid column in the grid of hand `side` (0 left, 1 right: mirrored)."""
    return column if side == 0 else 20 - column


def _ring_cells(side: int, row: int, centre: int) -> list[int]:
    cells = [-1] * RING
    if row >= 0:
        for k, offset in ((0, 0), (1, 1), (RING - 1, -1)):
            cells[k] = row * 21 + _column(side, centre + offset)
    return cells


def _tube(first: int, rings: int, flip: bool) -> list[tuple[int, int, int]]:
    """Triangles of a tube of `rings` rings from vertex `first` on, closed by a base-centre vertex after the
    rings and a tip apex after that."""
    out = []
    for i in range(rings - 1):
        for k in range(RING):
            a, b = first + i * RING + k, first + i * RING + (k + 1) % RING
            c, d = b + RING, a + RING
            out += [(a, b, c), (a, c, d)]
    base, apex = first + rings * RING, first + rings * RING + 1
    last = first + (rings - 1) * RING
    out += [(base, first + (k + 1) % RING, first + k) for k in range(RING)]
    out += [(last + k, last + (k + 1) % RING, apex) for k in range(RING)]
    return [(a, c, b) for a, b, c in out] if flip else out


def _palm_triangles(first: int, flip: bool) -> list[tuple[int, int, int]]:
    """The palm slab: a grid of len(PALM_ROWS) × len(PALM_COLUMNS) vertices on the palm side, the same on the
    back, and a strip along their border."""
    rows, cols = len(PALM_ROWS), len(PALM_COLUMNS)
    back = first + rows * cols

    def at(r: int, c: int) -> int:
        return first + r * cols + c

    out = []
    for r in range(rows - 1):
        for c in range(cols - 1):
            a, b, d, e = at(r, c), at(r, c + 1), at(r + 1, c), at(r + 1, c + 1)
            out += [(a, d, b), (b, d, e)]
            out += [(a + back - first, b + back - first, d + back - first), (b + back - first, e + back - first, d + back - first)]
    border = ([at(0, c) for c in range(cols)] + [at(r, cols - 1) for r in range(1, rows)]
              + [at(rows - 1, c) for c in range(cols - 2, -1, -1)] + [at(r, 0) for r in range(rows - 2, 0, -1)])
    for k, a in enumerate(border):
        b = border[(k + 1) % len(border)]
        out += [(a, b, b + back - first), (a, b + back - first, a + back - first)]
    return [(a, c, b) for a, b, c in out] if flip else out


@functools.lru_cache(maxsize=2)
def hand_topology(side: int) -> HandTopology:
    """The triangles and cells of hand `side` (0 left, 1 right); cached (read-only arrays)."""
    triangles, cells = [], []
    flip = side == 0  # the left hand is the mirror image: its ring frames are left-handed
    for finger in FINGER_JOINTS:
        rows = THUMB_ROWS if finger == "thumb" else FINGER_ROWS
        first = len(cells)
        for _, row in rows:
            cells += _ring_cells(side, row, CENTRE_COLUMN[finger])
        tip_row = rows[-1][1]
        cells += [-1, tip_row * 21 + _column(side, CENTRE_COLUMN[finger])]
        triangles += _tube(first, len(rows), flip)
    first = len(cells)
    cells += [r * 21 + _column(side, c) for r in PALM_ROWS for c in PALM_COLUMNS]
    cells += [-1] * (len(PALM_ROWS) * len(PALM_COLUMNS))
    triangles += _palm_triangles(first, flip)
    topology = HandTopology(np.array(triangles, np.int32), np.array(cells, np.int32))
    topology.triangles.flags.writeable = False
    topology.cells.flags.writeable = False
    return topology


def _unit(v: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """v / |v| along the last axis; `fallback` where |v| is (nearly) zero or not finite."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(norm) & (norm > EPS)
    return np.where(ok, v / np.where(ok, norm, 1.0), fallback)


def palm_frame(joints: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(palm-side normal, thumbward, fingerward unit vectors, knuckle width) of hand `side`'s (21, 3) joints."""
    thumbward = joints[5] - joints[17]
    width = float(np.linalg.norm(thumbward))
    if not np.isfinite(width) or width < EPS:
        width = max(float(np.linalg.norm(joints[9] - joints[0])) * 0.7, EPS)
    thumbward = _unit(thumbward, np.array([1.0, 0.0, 0.0]))
    fingerward = joints[[5, 9, 13, 17]].mean(axis=0) - joints[0]
    fingerward = _unit(fingerward - thumbward * np.dot(fingerward, thumbward), np.array([0.0, -1.0, 0.0]))
    # a right hand held palm towards you, fingers up, has its thumb on the right: its palm side is
    # thumbward × fingerward; the left hand is the mirror image
    normal = cross(thumbward, fingerward) if side == 1 else cross(fingerward, thumbward)
    return normal, thumbward, fingerward, width


@functools.lru_cache(maxsize=1)
def _ring_plan() -> tuple[np.ndarray, ...]:
    """Per ring of all five fingers in topology order: its bone's joints (start, end), its position along the
    bone (0–1) and the finger (from the base, in bones), whether it is the thumb's; and per finger its first ring
    and ring count."""
    starts, ends, fractions, positions, thumb, first, count = [], [], [], [], [], [], []
    for finger, chain in FINGER_JOINTS.items():
        rows = THUMB_ROWS if finger == "thumb" else FINGER_ROWS
        first.append(len(starts))
        count.append(len(rows))
        for position, _ in rows:
            bone = min(int(position), len(chain) - 2)
            starts.append(chain[bone])
            ends.append(chain[bone + 1])
            fractions.append(position - bone)
            positions.append(position)
            thumb.append(finger == "thumb")
    return (np.array(starts), np.array(ends), np.array(fractions)[:, None], np.array(positions), np.array(thumb),
            np.array(first), np.array(count))


def _perpendicular(v: np.ndarray) -> np.ndarray:
    """(N, 3) unit vectors perpendicular to the rows of `v` (for degenerate frames)."""
    trial = np.where(np.abs(v[:, 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    return _unit(cross(v, trial), np.array([1.0, 0.0, 0.0]))


def _fingers(joints: np.ndarray, normal: np.ndarray, thumbward: np.ndarray, width: float, side: int) -> list[np.ndarray]:
    """Per finger in topology order: its ring vertices (rings·RING, 3), then its base centre and tip apex (2, 3).
    The ring frame (palm side, thumbward, along the bone) is right-handed for the right hand and left-handed for
    the left, which keeps the winding of `hand_topology` outward in every pose."""
    starts, ends, fractions, positions, thumb, first, count = _ring_plan()
    start, end = joints[starts], joints[ends]
    centre = start + fractions * (end - start)
    along = _unit(end - start, _perpendicular(np.broadcast_to(normal, start.shape)))
    volar = np.where(thumb[:, None], _unit(normal - 0.7 * thumbward, normal), normal)
    v = _unit(volar - along * np.sum(volar * along, axis=1, keepdims=True), _perpendicular(along))
    lateral = (1.0 if side else -1.0) * cross(along, v)
    radius = width * FINGER_RADIUS * np.where(thumb, THUMB_SCALE, 1.0)
    taper = (radius * (1.0 - (1.0 - TIP_TAPER) * positions / 3.0))[:, None, None]
    angle = 2 * np.pi * np.arange(RING) / RING
    rings = centre[:, None] + taper * (np.cos(angle)[None, :, None] * v[:, None] + np.sin(angle)[None, :, None] * lateral[:, None])
    parts = []
    for k, n in zip(first, count):
        last = k + n - 1
        apex = end[last] + along[last] * radius[last] * TIP_TAPER * 0.6
        parts += [rings[k:k + n].reshape(-1, 3), np.stack([centre[k], apex])]
    return parts


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (..., 3) arrays (np.cross costs more in call overhead than in arithmetic)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def _palm(joints: np.ndarray, normal: np.ndarray, width: float) -> np.ndarray:
    """Palm-side then back-side grid vertices of the palm slab: the knuckle line (row 13) runs from just past
    the little finger's knuckle through the index finger's to the ball of the thumb, the wrist line (row 17)
    from the little-finger side of the wrist to the thumb's base joint."""
    across = joints[5] - joints[17]
    top = _along(PALM_COLUMNS, (1, 2, 14, 19), (joints[17] - 0.08 * across, joints[17], joints[5], joints[5] + 0.3 * across))
    bottom = _along(PALM_COLUMNS, (1, 19), (joints[0] - 0.45 * across, joints[1]))
    t = ((PALM_ROWS - 13) / 4.0)[:, None, None]
    grid = ((1 - t) * top[None] + t * bottom[None]).reshape(-1, 3)
    offset = normal * width * PALM_HALF_THICKNESS
    return np.concatenate([grid + offset, grid - offset])


def _along(columns: np.ndarray, knots: tuple, points: tuple) -> np.ndarray:
    """(len(columns), 3): the polyline through `points` at the column `knots`, at each column."""
    points = np.stack(points)
    return np.stack([np.interp(columns, knots, points[:, k]) for k in range(3)], axis=1)


def hand_vertices(joints: np.ndarray, side: int) -> np.ndarray | None:
    """(V, 3) float32 vertex positions of the surface of hand `side`'s (21, 3) joints (0 left, 1 right), in
    their frame, in the order of `hand_topology(side)`; None when a joint is not finite."""
    joints = np.asarray(joints, np.float64)
    if joints.shape != (21, 3) or not np.isfinite(joints).all():
        return None
    normal, thumbward, _, width = palm_frame(joints, side)
    parts = _fingers(joints, normal, thumbward, width, side)
    parts.append(_palm(joints, normal, width))
    return np.concatenate(parts).astype(np.float32)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(V, 3) float32 unit normals of a mesh's (V, 3) vertices with (F, 3) triangles wound outwards: per vertex
    the sum of its triangles' edge cross products (each twice its triangle's area along its normal, so larger
    triangles weigh more), normalised. Degenerate triangles add nothing; a vertex with no other (or whose sum
    is zero or not finite) gets (0, 0, −1), towards WiLoR's camera — every normal is finite and unit length."""
    corners = np.asarray(vertices, np.float64)[triangles]
    corner_of = np.asarray(triangles).reshape(-1)
    with np.errstate(over="ignore", invalid="ignore"):
        faces = cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        sums = np.stack([np.bincount(corner_of, np.repeat(faces[:, k], 3), minlength=len(vertices)) for k in range(3)], axis=1)
        return _unit(sums, np.array([0.0, 0.0, -1.0])).astype(np.float32)


def vertex_values(grid: np.ndarray | None, topology: HandTopology) -> np.ndarray:
    """(V,) float32: each vertex's cell of one hand's (21, 21) grid; NaN where the vertex has no cell, the cell
    is outside the layout (NaN), or there is no grid."""
    if grid is None:
        return np.full(topology.num_vertices, np.nan, np.float32)
    flat = np.asarray(grid, np.float32).reshape(-1)
    return np.where(topology.cells >= 0, flat[np.maximum(topology.cells, 0)], np.nan).astype(np.float32)
