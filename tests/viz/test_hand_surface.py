"""The hand surface built from 21 joints, the tactile cells painted on it, and its CPU rendering (`--hand3d`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.comparison_video import comparison_frame
from touchanything.viz.hand3d_panel import HAND3D_HEIGHT, TITLE_HEIGHT, UNPAINTED, draw_hand, hand3d_panel
from touchanything.viz.hand_surface import hand_topology, hand_vertices, palm_frame, vertex_normals, vertex_values
from touchanything.viz.pressure_panel import BACKGROUND

SAMPLE = Path(__file__).resolve().parents[2] / "recordings" / "sample" / "Home" / "slide_box_cardboard" / "sim0007_00000"


@pytest.fixture(scope="module")
def sample_hands() -> np.ndarray:
    """(frames, 2, 21, 3) WiLoR joints of the bundled sample where both hands are valid."""
    with open_episode(SAMPLE) as episode:
        return episode.wilor.joints[episode.wilor.valid.all(axis=1)][::25]


def _components(triangles: np.ndarray, count: int) -> np.ndarray:
    parent = np.arange(count)

    def root(v: int) -> int:
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for a, b, c in triangles:
        parent[root(b)] = root(a)
        parent[root(c)] = root(a)
    return np.array([root(v) for v in range(count)])


def test_every_part_is_closed_and_wound_outwards_in_every_pose(sample_hands):
    for side in (0, 1):
        topology = hand_topology(side)
        edges = np.sort(topology.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, uses = np.unique(edges, axis=0, return_counts=True)
        assert (uses == 2).all()  # closed: every edge is shared by exactly two triangles
        parts = _components(topology.triangles, topology.num_vertices)
        for joints in sample_hands[:, side]:
            v = hand_vertices(joints, side).astype(np.float64)
            a, b, c = v[topology.triangles].transpose(1, 0, 2)
            volume = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6
            per_part = np.bincount(parts[topology.triangles[:, 0]], weights=volume)
            assert (per_part[np.unique(parts)] > 0).all()  # six parts (five fingers, the palm), all outward


def test_every_cell_of_the_layout_is_painted_and_nothing_outside_the_grid():
    layout = TactileLayout.default()
    for side in (0, 1):
        cells = hand_topology(side).cells
        painted = {(c // 21, c % 21) for c in cells[cells >= 0]}
        valid = {tuple(rc) for rc in np.argwhere(layout.valid[side])}
        assert valid <= painted and len(painted - valid) == 4  # only the palm's top-right corner, outside the layout


def test_a_cell_paints_its_own_region(sample_hands):
    joints = sample_hands[0]
    for side, (row, column, tip) in ((0, (2, 14, 8)), (1, (2, 6, 8))):  # index fingertip pad; the right grid mirrored
        grid = np.zeros((21, 21), np.float32)
        grid[row, column] = 1.0
        topology = hand_topology(side)
        values = vertex_values(grid, topology)
        hot = np.flatnonzero(values == 1.0)
        assert hot.size >= 2 and np.isnan(values).sum() > 0
        vertices = hand_vertices(joints[side], side)
        tips = joints[side][[4, 8, 12, 16, 20]]
        nearest = np.argmin(np.linalg.norm(vertices[hot][:, None] - tips[None], axis=-1), axis=1)
        assert (nearest == [4, 8, 12, 16, 20].index(tip)).all()
        normal = palm_frame(joints[side].astype(np.float64), side)[0]
        axis = joints[side][[7, 8]].mean(axis=0)
        assert (np.dot(vertices[hot] - axis, normal) > 0).all()  # on the palm side of the finger


def test_degenerate_joints_give_a_finite_surface_or_none():
    rng = np.random.default_rng(1)
    cases = {"zeros": np.zeros((21, 3)), "collinear": np.outer(np.arange(21), [1.0, 0, 0]),
             "huge": rng.normal(0, 1e6, (21, 3)), "tiny": rng.normal(0, 1e-12, (21, 3)), "random": rng.normal(0, 1, (21, 3))}
    for name, joints in cases.items():
        for side in (0, 1):
            vertices = hand_vertices(joints, side)
            assert vertices is not None and np.isfinite(vertices).all(), name
    bad = np.zeros((21, 3))
    bad[3, 1] = np.nan
    assert hand_vertices(bad, 0) is None and hand_vertices(np.full((21, 3), np.inf), 1) is None
    assert np.isnan(vertex_values(None, hand_topology(0))).all()


def test_vertex_normals_are_area_weighted_unit_and_finite_on_degenerate_surfaces(sample_hands):
    corner = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])  # a tetrahedron wound outwards
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    normals = vertex_normals(corner, triangles)
    assert np.allclose(normals[0], -np.ones(3) / np.sqrt(3))  # three equal faces meet at the origin
    # the apex: faces −y and −x (area 1/2 each) and (1, 1, 1)/√3 (area √3/2) sum to +z only when weighted by area
    assert np.allclose(normals[3], [0.0, 0.0, 1.0])
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [5, 5, 5], [1e300, 0, 0], [0, 1e300, 0]])  # collinear, unused, overflowing
    normals = vertex_normals(flat, np.array([[0, 1, 2], [0, 4, 5]]))
    assert np.isfinite(normals).all() and np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    for joints in (np.zeros((21, 3)), sample_hands[0, 1]):
        normals = vertex_normals(hand_vertices(joints, 1), hand_topology(1).triangles)
        assert normals.dtype == np.float32 and np.isfinite(normals).all() and np.allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_the_panel_paints_measured_and_predicted_pressure(sample_hands):
    joints = sample_hands[0].reshape(42, 3)
    measured = np.where(TactileLayout.default().valid, 0.0, np.nan).astype(np.float32)
    predicted = measured.copy()
    measured[0, 13:18, 1:16] = 1.0  # left palm pressed (red), predicted nothing (blue)
    panel = hand3d_panel(joints, np.array([True, True]), measured, predicted)
    assert panel.shape == (HAND3D_HEIGHT, 1440, 3)
    views = [panel[TITLE_HEIGHT:, k * 360:(k + 1) * 360].astype(int) for k in range(4)]
    red = [((v[..., 0] > 150) & (v[..., 2] < 80)).sum() for v in views]
    assert red[0] > 500 and red[1] == red[2] == red[3] == 0
    assert all((np.abs(v - BACKGROUND).sum(axis=-1) > 30).mean() > 0.05 for v in views)  # a hand in every view


def test_the_panel_says_what_is_missing_and_survives_bad_poses(sample_hands):
    joints = sample_hands[0].reshape(42, 3).copy()
    joints[21:] = np.nan
    panel = hand3d_panel(joints, np.array([True, True]), None, np.zeros((2, 21, 21), np.float32))
    body = panel[TITLE_HEIGHT:].astype(int)
    drawn = [(np.abs(body[:, k * 360:(k + 1) * 360] - BACKGROUND).sum(axis=-1) > 30).mean() for k in range(4)]
    assert drawn[0] == drawn[1] == drawn[3] == 0 and drawn[2] > 0.05  # measured n/a; the right hand has no pose
    assert draw_hand(np.full((21, 3), np.nan), 0, 100, 100) is None and draw_hand(np.zeros((21, 3)), 0, 100, 100) is None
    canvas = np.zeros((100, 100, 3), np.uint8)
    draw_hand(sample_hands[0, 1], 1, 100, 100).paint(canvas, None)
    drawn = canvas[canvas.sum(axis=-1) > 0].astype(int)
    assert len(drawn) > 500  # shaded, but grey: without a grid nothing is painted
    assert (np.abs(drawn[:, 0] - drawn[:, 1]) <= 2).all() and (drawn[:, 2] >= drawn[:, 0]).all()
    assert UNPAINTED[0] == UNPAINTED[1] < UNPAINTED[2]


def test_the_comparison_frame_grows_by_the_panel():
    panel = np.full((HAND3D_HEIGHT, 1440, 3), 7, np.uint8)
    frame = comparison_frame({}, None, None, "footer", np.zeros((150, 1440, 3), np.uint8), panel)
    assert frame.shape == (806 + HAND3D_HEIGHT, 1440, 3) and (frame[630:630 + HAND3D_HEIGHT] == 7).all()
