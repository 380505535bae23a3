"""The hands in a Rerun recording (`viz.rerun_recording`): their annotation (joint names, bones) and their surfaces.

`hand_classes()`: class 0 the left hand and 1 the right, each with the 21 joints as keypoints named in the
official order (`wrist`, `thumb_1` … `pinky_4`, `core.hand_pose.JOINT_NAMES`) and the bones as keypoint
connections; logged once, static, for `world/hands` and `cameras/ego/hands` (a hovered joint says its name).

`HandSurfaces`: one mesh per hand, `world/surface/{left,right}` (`viz.hand_surface`), whose geometry — vertex
positions (V, 3) in the joints' frame (WiLoR's head-camera frame, metres) and area-weighted unit normals (V, 3)
— is logged once per frame and painted twice: `MeasuredPressure:vertex_colors` and
`PredictedPressure:vertex_colors`, (V,) RGB on the official 0–1 scale (grey where a vertex has no cell), each
with an `…:albedo_factor` whose alpha is 0 at a frame without that map (the surface is hidden in that kind's
view). The triangles are static. The default blueprint's two 3D views map the mesh's `vertex_colors` and
`albedo_factor` to one paint each (`paint_overrides`; Rerun's component mappings, experimental in 0.41): one
geometry instead of two per hand, half of what the meshes cost (docs/rerun.md, "Size"). A hand without a valid
pose is cleared at its frame; a viewer without the blueprint shows the surfaces white.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
import rerun as rr
from rerun.blueprint.encodings import VisualizerComponentMapping
from rerun.blueprint.visualizers import Visualizer

from touchanything.core.hand_pose import JOINT_NAMES
from touchanything.core.snapshot import HANDS
from touchanything.viz.hand3d_panel import vertex_colours
from touchanything.viz.hand_projection import HAND_COLOURS
from touchanything.viz.hand_regions import BONES
from touchanything.viz.hand_surface import hand_topology, hand_vertices, vertex_normals
from touchanything.viz.rerun_columns import ColumnBuffer

PAINTS = {"measured": "MeasuredPressure", "predicted": "PredictedPressure"}
"""The archetype name of each kind's paint on the surfaces."""
SHOWN, HIDDEN = (255, 255, 255, 255), (255, 255, 255, 0)
POSITION_STEP, NORMAL_STEP = 2.0 ** -12, 2.0 ** -7
"""Vertex positions are logged rounded to 2⁻¹² m (0.24 mm) and normals' components to 2⁻⁷ (|n| within 0.7 % of 1,
about 0.4° off): float32 values with their low bits zero, which the file's LZ4 compresses to a little over half.
Neither shows: the surface is some 0.1–0.2 m across."""
RECENT_FRAMES = 64
"""Frames whose geometry is remembered as logged (the live logger's queue holds about 8 frames)."""


def surface_entity(hand: str) -> str:
    return f"world/surface/{hand}"


def _rounded(values: np.ndarray, step: float) -> np.ndarray:
    """`values` rounded to multiples of `step` (a power of two, so exact in float32), as float32."""
    return (np.round(values / step) * step).astype(np.float32)


def hand_classes() -> rr.AnnotationContext:
    """Class per hand, its joints named as keypoints and its bones connecting them."""
    joints = [rr.AnnotationInfo(id=k, label=name) for k, name in enumerate(JOINT_NAMES)]
    return rr.AnnotationContext([
        rr.ClassDescription(info=rr.AnnotationInfo(id=h, label=f"{hand} hand", color=HAND_COLOURS[h]),
                            keypoint_annotations=joints, keypoint_connections=BONES) for h, hand in enumerate(HANDS)])


def paint_overrides(kind: str) -> dict[str, Visualizer]:
    """{surface entity: its mesh visualizer with `kind`'s paint as vertex colours and albedo factor}."""
    archetype = PAINTS[kind]
    mappings = [VisualizerComponentMapping(f"Mesh3D:{field}", "SourceComponent", source_component=f"{archetype}:{field}")
                for field in ("vertex_colors", "albedo_factor")]
    return {surface_entity(hand): rr.Mesh3D.from_fields().visualizer(mappings=mappings) for hand in HANDS}


class _Paint:
    """Columns of one kind's paint (`ColumnBuffer` rows): `vertex_colors` (n, 3) uint8 and `albedo_factor` (n, 4)."""

    TYPES = {"vertex_colors": (rr.components.ColorBatch, "rerun.components.Color"),
             "albedo_factor": (rr.components.AlbedoFactorBatch, "rerun.components.AlbedoFactor")}

    def __init__(self, archetype: str) -> None:
        self.archetype = archetype

    def columns(self, **components: np.ndarray) -> rr.ComponentColumnList:
        columns = []
        for name, values in components.items():
            batch, component_type = self.TYPES[name]
            descriptor = rr.ComponentDescriptor(f"{self.archetype}:{name}", archetype=self.archetype, component_type=component_type)
            columns.append(rr.DescribedComponentBatch(batch(values), descriptor).partition())
        return rr.ComponentColumnList(columns)


class HandSurfaces:
    """Logs both hands' surfaces into `rows`: `paint(kind, …)` for each map of a frame (the frame's geometry goes
    with the first paint of that frame)."""

    def __init__(self, rows: ColumnBuffer) -> None:
        self.rows = rows
        self._paints = {kind: _Paint(archetype) for kind, archetype in PAINTS.items()}
        self._shown: OrderedDict[int, tuple[bool, bool]] = OrderedDict()
        self._painted = {(h, kind): -1 for h in range(2) for kind in PAINTS}
        self._cleared = [-1, -1]

    @staticmethod
    def log_static(stream: rr.RecordingStream) -> None:
        for h, hand in enumerate(HANDS):
            stream.log(surface_entity(hand), rr.Mesh3D.from_fields(triangle_indices=hand_topology(h).triangles), static=True)

    def paint(self, kind: str, at: tuple[int, float], joints: np.ndarray, valid: np.ndarray, grids: np.ndarray | None) -> None:
        """`kind`'s (2, 21, 21) maps (None: none at this frame, hidden) on both hands' surfaces at `at` (frame,
        seconds); joints (42, 3) and valid (2,) of that frame."""
        shown = self._shown.get(at[0])
        if shown is None:
            shown = self._shape(at, joints, valid, kind)
        for h in range(2):
            if shown[h]:
                self._put_paint(h, kind, at, None if grids is None else grids[h])

    def _shape(self, at: tuple[int, float], joints: np.ndarray, valid: np.ndarray, painting: str) -> tuple[bool, bool]:
        """Log both hands' geometry at `at` (a hand without a valid pose is cleared); a paint other than `painting`
        that has nothing since the hand was last cleared is logged hidden, so that each view finds its colours."""
        frame = at[0]
        hands = np.asarray(joints, np.float64).reshape(2, 21, 3)
        shown = []
        for h, hand in enumerate(HANDS):
            vertices = hand_vertices(hands[h], h) if valid[h] else None
            shown.append(vertices is not None)
            if vertices is None:
                self.rows.clear(surface_entity(hand), *at)
                self._cleared[h] = max(self._cleared[h], frame)
                continue
            normals = vertex_normals(vertices, hand_topology(h).triangles)
            self.rows.put(surface_entity(hand), rr.Mesh3D, *at, part="geometry", vertex_positions=_rounded(vertices, POSITION_STEP),
                          vertex_normals=_rounded(normals, NORMAL_STEP))
            for kind in PAINTS:
                if kind != painting and not self._cleared[h] < self._painted[h, kind] <= frame:
                    self._put_paint(h, kind, at, None)
        self._shown[frame] = (shown[0], shown[1])
        if len(self._shown) > RECENT_FRAMES:
            self._shown.popitem(last=False)
        return self._shown[frame]

    def _put_paint(self, h: int, kind: str, at: tuple[int, float], grid: np.ndarray | None) -> None:
        self.rows.put(surface_entity(HANDS[h]), self._paints[kind], *at, part=kind, vertex_colors=vertex_colours(grid, h),
                      albedo_factor=np.array([HIDDEN if grid is None else SHOWN], np.uint8))
        self._painted[h, kind] = max(self._painted[h, kind], at[0])
