"""Rerun recordings (`--rerun FILE.rrd`, `--rerun-serve`): written by replay, live and eval, read back with the
SDK's own reader — entities, frame counts and values (the maps as numbers, the hand surfaces' normals and
paints, the joints' names, the blueprint's paint per view) — and the output checks before any work."""
from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
from rerun.chunk import RrdReader

from helpers.rerun_reading import recording_rows
from touchanything.app.cli import main
from touchanything.app.sessions.rerun_sink import MAX_PENDING, RerunSink, seconds_since_first
from touchanything.core.snapshot import Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.viz.colormap import PRESSURE_LUT, apply
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.hand_surface import hand_topology
from touchanything.viz.pressure_panel import BACKGROUND
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
SAMPLE = ROOT / "recordings" / "sample" / "Workbench" / "hold_and_press_button_box_yellow" / "sim0007_00001"
PER_FRAME = ("/world/hands", "/world/surface/left", "/world/surface/right", "/pressure/measured", "/pressure/predicted",
             "/pressure/measured/left", "/pressure/predicted/right", "/pressure/difference", "/contact/measured",
             "/contact/predicted", "/metrics/rolling", "/metrics/cumulative", "/engine", "/trackers/chest", "/cameras/ego/hands")
JOINT_LABELS = ["wrist", "thumb_1", "thumb_2", "thumb_3", "thumb_4", "index_1", "index_2", "index_3", "index_4", "middle_1",
                "middle_2", "middle_3", "middle_4", "ring_1", "ring_2", "ring_3", "ring_4", "pinky_1", "pinky_2", "pinky_3", "pinky_4"]
"""The official joint order, written out (not derived from the code under test)."""


def _values(rows, frame: int) -> np.ndarray:
    """The (21, 21) map a value image holds at `frame` (its buffer, float16)."""
    return np.frombuffer(bytes(rows.at("DepthImage:buffer", frame)[0]), np.float16).reshape(21, 21)


def _no_display(monkeypatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)


def test_replay_writes_a_recording_the_sdk_reads_back(episode_dir, tmp_path, capsys, monkeypatch):
    _no_display(monkeypatch)
    out = tmp_path / "rec" / "replay.rrd"
    assert main(["replay", str(episode_dir), "--rerun", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Writing the Rerun recording only" in printed and f"rerun     {out}" in printed
    assert "frames    40 replayed (no video written), 40 with a prediction" in printed and "video     " not in printed
    assert out.is_file() and [p.name for p in out.parent.iterdir()] == ["replay.rrd"]  # renamed into place
    assert len(RrdReader(out).recordings()) == 1
    rows, static = recording_rows(out)
    assert set(PER_FRAME) <= set(rows)
    for entity in ("/cameras/ego", "/cameras/wrist_left", "/cameras/wrist_right"):  # the episode's MP4s as video assets
        assert "AssetVideo:blob" in static[entity]
        assert rows[entity].data_frames("VideoFrameReference:timestamp") == list(range(40))
    assert rows["/pressure/measured"].data_frames("EncodedImage:blob") == list(range(40))
    assert rows["/pressure/predicted/left"].data_frames("DepthImage:buffer") == list(range(40))
    right = rows["/world/surface/right"]
    assert right.data_frames("Mesh3D:vertex_positions") == [f for f in range(40) if f % 7 != 3]  # conftest: invalid every 7th
    assert sorted(set(right.data_frames("PredictedPressure:vertex_colors"))) == [f for f in range(40) if f % 7 != 3]
    assert right.at("PredictedPressure:albedo_factor", 4) == [0xFFFFFFFF]  # shown: the prediction outranks the placeholder
    assert "Mesh3D:triangle_indices" in static["/world/surface/right"]
    with open_episode(episode_dir) as episode:
        truth = ground_truth_for_metrics(episode.pressure.grids, False)
        stamps = episode.timestamps_us
    # conftest's gloves press raw sensors 0-59 by int(200 sin(frame / 6)): the left layout reads them (it uses sensors
    # 0-165), the right one does not (64-229). Frame 12 (sin 0.91): the left hand in contact, the right not; frame
    # 25 (sin < 0, no press): neither; frame 0 (the baseline) neither
    contact = rows["/contact/measured"]
    assert [contact.at("Scalars:scalars", f) for f in (12, 25, 0)] == [[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    png = np.frombuffer(bytes(rows["/pressure/measured"].at("EncodedImage:blob", 12)[0]), np.uint8)
    rgba = cv2.cvtColor(cv2.imdecode(png, cv2.IMREAD_UNCHANGED), cv2.COLOR_BGRA2RGBA)
    assert rgba.shape == (21, 43, 4)
    cells = np.isfinite(truth[12, 1])
    assert (rgba[:, 22:, :3][cells] == apply(truth[12, 1][cells], PRESSURE_LUT, 0.0, 1.0, (0, 0, 0))).all()
    assert (rgba[:, 22:, :3][~cells] == BACKGROUND).all() and (rgba[:, 22:, 3] == 255).all() and (rgba[:, 21, 3] == 0).all()
    values = _values(rows["/pressure/measured/right"], 12)  # the numbers beneath the colours
    assert (np.isnan(values) == ~cells).all()
    r, c = np.unravel_index(np.nanargmax(truth[12, 1]), (21, 21))
    assert truth[12, 1, r, c] > 0.05 and values[r, c] == np.float16(truth[12, 1, r, c])
    assert np.allclose(values[cells], truth[12, 1][cells], atol=5e-4)
    cumulative = rows["/metrics/cumulative"].at("Scalars:scalars", 39)
    assert f"volumetric_iou {cumulative[2]:.3f}" in printed
    latency, step = rows["/engine"].at("Scalars:scalars", 5)
    assert latency > 0 and step > 0
    capture = [c for c in RrdReader(out).stream() if c.entity_path == "/engine" and not c.is_static][0].to_record_batch()
    frames, times = capture.column("frame").to_pylist(), capture.column("capture_time").to_pylist()
    assert all(round(t.total_seconds() * 1e6) == stamps[f] for f, t in zip(frames, times))  # the episode's own clock


def test_the_comparison_video_and_the_recording_come_together_with_the_3d_hands(episode_dir, tmp_path, capsys):
    video, out = tmp_path / "r.mp4", tmp_path / "r.rrd"
    assert main(["replay", str(episode_dir), "--out", str(video), "--hand3d", "--rerun", str(out)]) == 0
    from touchanything.devices.episodes.video_io import VideoReader

    with VideoReader(video) as reader:
        assert reader.num_frames == 40 and reader.height == 806 + 300
    rows, _ = recording_rows(out)
    assert sorted(set(rows["/world/surface/left"].data_frames("PredictedPressure:vertex_colors"))) == list(range(40))


def _two_frames(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A recording of the bundled sample's frame 109 (a press) at frames 0–2: frame 0 with both maps, frame 1
    measured only, frame 2 without the right hand's pose and without maps. Returns (joints (42, 3), valid (2,),
    measured, predicted (2, 21, 21))."""
    with open_episode(SAMPLE) as episode:
        joints, valid = episode.wilor.joints[109].reshape(42, 3), episode.wilor.valid[109]
    assert valid.all()
    measured = np.full((2, 21, 21), np.nan, np.float32)
    measured[:, 2:18, 1:20] = 0.0
    measured[1, 5, 7], measured[0, 14, 3] = 0.625, 1.0
    predicted = measured.copy()
    predicted[1, 5, 7] = 0.3125
    bend = TactileLayout.default().bend
    both, measured_only, nothing = (frame_facts(predicted, None, measured, bend), frame_facts(None, None, measured, bend),
                                    frame_facts(None, None, None, bend))
    recording = RerunRecording(RerunTarget(path), "two frames", {})
    recording.log_observation(0, 0.0, {}, joints, valid, measured, both, {})
    recording.log_prediction(0, 0.0, predicted, both, joints, valid, measured, None, None)
    recording.log_observation(1, 0.033, {}, joints, valid, measured, measured_only, {})
    recording.log_prediction(1, 0.033, None, measured_only, joints, valid, measured, None, None)
    recording.log_observation(2, 0.067, {}, joints, np.array([True, False]), None, nothing, {})
    recording.close()
    return joints, valid, measured, predicted


def test_the_maps_are_logged_as_values_a_hovered_cell_reads(tmp_path):
    _, _, measured, predicted = _two_frames(tmp_path / "v.rrd")
    rows, static = recording_rows(tmp_path / "v.rrd")
    right = _values(rows["/pressure/predicted/right"], 0)
    assert right[5, 7] == 0.3125 and right[2, 1] == 0.0 and np.isnan(right[0, 0])  # a cell outside the layout: NaN
    assert _values(rows["/pressure/measured/right"], 1)[5, 7] == 0.625 and _values(rows["/pressure/measured/left"], 0)[14, 3] == 1.0
    assert rows["/pressure/predicted/right"].data_frames("DepthImage:buffer") == [0]  # no prediction at frame 1: cleared
    assert rows["/pressure/measured/left"].data_frames("DepthImage:buffer") == [0, 1]
    for kind in ("measured", "predicted"):
        for hand in ("left", "right"):
            described = {name: values[0] for name, values in static_values(tmp_path / "v.rrd", f"/pressure/{kind}/{hand}").items()}
            assert described["DepthImage:format"][0] == {"width": 21, "height": 21, "pixel_format": None, "color_model": None,
                                                         "channel_datatype": 33}  # F16
            assert described["DepthImage:meter"] == [1.0] and described["DepthImage:depth_range"] == [[0.0, 1.0]]
            assert described["DepthImage:draw_order"][0] < static_values(tmp_path / "v.rrd", f"/pressure/{kind}")[
                "EncodedImage:draw_order"][0][0]  # beneath the coloured map
        assert static_values(tmp_path / "v.rrd", f"/pressure/{kind}/right")["Transform3D:translation"][0] == [[22.0, 0.0, 0.0]]
    assert "DepthImage:colormap" in static["/pressure/measured/left"]


def static_values(path: Path, entity: str) -> dict[str, list]:
    """{component: its static values} of `entity` in the recording at `path`."""
    out: dict[str, list] = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static and chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            out |= {name: batch.column(name).to_pylist() for name in batch.schema.names if ":" in name}
    return out


def test_the_hand_surfaces_carry_unit_normals_and_one_paint_per_view(tmp_path):
    _, _, measured, predicted = _two_frames(tmp_path / "s.rrd")
    rows, static = recording_rows(tmp_path / "s.rrd")
    for h, hand in enumerate(("left", "right")):
        surface = rows[f"/world/surface/{hand}"]
        positions = np.array(surface.at("Mesh3D:vertex_positions", 0), np.float64)
        normals = np.array(surface.at("Mesh3D:vertex_normals", 0), np.float64)
        assert normals.shape == positions.shape == (hand_topology(h).num_vertices, 3) and np.isfinite(normals).all()
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=0.01)
        corners = positions[hand_topology(h).triangles]  # every face, from the logged positions, faces its corners' normals
        faces = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        facing = np.einsum("fk,fk->f", faces, normals[hand_topology(h).triangles].sum(axis=1))
        assert (facing[np.linalg.norm(faces, axis=1) > 1e-9] > 0).mean() > 0.97
        assert np.ptp(normals, axis=0).min() > 1.0  # they point every way: not one constant
        assert "Mesh3D:triangle_indices" in static[f"/world/surface/{hand}"]
    right = rows["/world/surface/right"]
    shows = [v for v, cell in enumerate(hand_topology(1).cells) if cell == 5 * 21 + 7]
    assert shows
    for kind, value in (("Measured", 0.625), ("Predicted", 0.3125)):
        colours = np.array(right.at(f"{kind}Pressure:vertex_colors", 0), np.uint32)
        expected = apply(np.array([value]), PRESSURE_LUT, 0.0, 1.0, (0, 0, 0))[0].astype(np.uint32)
        assert (colours[shows] == (expected[0] << 24 | expected[1] << 16 | expected[2] << 8 | 255)).all()
        assert right.at(f"{kind}Pressure:albedo_factor", 0) == [0xFFFFFFFF]
    assert right.at("MeasuredPressure:albedo_factor", 1) == [0xFFFFFFFF]
    assert right.at("PredictedPressure:albedo_factor", 1) == [0xFFFFFF00]  # no prediction at frame 1: hidden in its view
    assert right.data_frames("Mesh3D:vertex_positions") == [0, 1]  # no pose at frame 2: cleared
    assert rows["/world/surface/left"].at("MeasuredPressure:albedo_factor", 2) == [0xFFFFFF00]  # no map at frame 2
    maps = {}  # the default blueprint: each 3D view paints both surfaces with one kind's colours
    reader = RrdReader(tmp_path / "s.rrd")
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        if "VisualizerInstruction:component_map" in batch.schema.names:
            view, hand = chunk.entity_path.split("/")[2], chunk.entity_path.split("/overrides/world/surface/")[1].split("/")[0]
            for mapping in batch.column("VisualizerInstruction:component_map").to_pylist()[0]:
                maps.setdefault(view, set()).add((hand, mapping["target"], mapping["source_component"]))
    fields = ("albedo_factor", "vertex_colors")
    assert sorted(map(sorted, maps.values())) == [
        sorted((hand, f"Mesh3D:{field}", f"{kind}Pressure:{field}") for hand in ("left", "right") for field in fields)
        for kind in ("Measured", "Predicted")]


def test_the_joints_are_named_in_the_official_order(tmp_path):
    _two_frames(tmp_path / "j.rrd")
    context = static_values(tmp_path / "j.rrd", "/")["AnnotationContext:context"][0][0]
    assert [entry["class_description"]["info"]["label"] for entry in context] == ["left hand", "right hand"]
    for entry in context:
        keypoints = entry["class_description"]["keypoint_annotations"]
        assert [k["label"] for k in keypoints] == JOINT_LABELS and [k["id"] for k in keypoints] == list(range(21))
    assert static_values(tmp_path / "j.rrd", "/world/hands")["Points3D:show_labels"] == [[False]]  # on hover only


def test_the_output_is_checked_before_any_work(episode_dir, tmp_path, capsys):
    existing = tmp_path / "old.rrd"
    existing.write_bytes(b"keep me")
    video = tmp_path / "v.mp4"
    cases = [([str(existing)], "exists; pass --overwrite"), ([str(tmp_path / "x.mp4")], "must be an .rrd file"),
             ([str(tmp_path)], "must be an .rrd file")]
    for rerun, message in cases:
        assert main(["replay", str(episode_dir), "--out", str(video), "--rerun", *rerun]) == 2
        error = capsys.readouterr().err
        assert message in error and len(error.strip().splitlines()) == 1 and "Traceback" not in error
    assert not video.exists() and existing.read_bytes() == b"keep me"
    if os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        assert main(["replay", str(episode_dir), "--out", str(video), "--rerun", str(locked / "a.rrd")]) == 2
        assert "not writable" in capsys.readouterr().err
    assert main(["replay", str(episode_dir), "--out", str(video), "--rerun", str(existing), "--overwrite"]) == 0
    assert len(RrdReader(existing).recordings()) == 1


def test_the_logger_queue_is_bounded_and_counts_what_it_drops(tmp_path):
    recording = RerunRecording(RerunTarget(tmp_path / "q.rrd"), "queue", {})
    sink = RerunSink(recording, TactileLayout.default().bend, seconds_since_first())
    image = np.zeros((48, 64, 3), np.uint8)
    try:
        for i in range(200):
            snapshot = Snapshot(i, 1_000_000 + i * 33_333, {"ego": image}, np.full((42, 3), np.nan, np.float32), np.zeros(2, bool))
            sink.observe(snapshot, np.full((2, 21, 21), np.nan, np.float32))
            assert sink.pending <= MAX_PENDING
    finally:
        sink.close()
        recording.close()
    assert sink.logged + sink.dropped == 200 and sink.error is None
    assert sink.dropped_kinds == ({"observation": sink.dropped} if sink.dropped else {})  # named by kind in the summary
    assert sink.line().endswith(f"behind ({sink.dropped} observations)" if sink.dropped else "behind")
    rows, _ = recording_rows(tmp_path / "q.rrd")
    assert len(rows["/cameras/ego"].data_frames("EncodedImage:blob")) == sink.logged
    assert rows["/world/hands"].data_frames("Points3D:positions") == []  # NaN joints: cleared, never logged


def test_live_headless_records_the_simulated_rig(tmp_path, capsys):
    out = tmp_path / "live.rrd"
    assert main(["live", "--scene", str(SCENES / "sim.toml"), "--headless", "--seconds", "5", "--rerun", str(out)]) == 0
    printed = capsys.readouterr().out
    snapshots = int(printed.split("summary   ")[1].split()[0])
    logged, dropped = (int(printed.split("rerun     ")[1].split()[k]) for k in (0, 6))
    rows, static = recording_rows(out)
    cameras = rows["/cameras/ego"].data_frames("EncodedImage:blob")
    # every snapshot and prediction was logged or, when the logger fell behind (a busy machine), dropped and counted
    assert logged + dropped >= snapshots and len(cameras) >= 10  # (the rig runs on a little after the summary)
    # + the ticks between the summary and the rig's stop: 0.5 s of 30 fps on a busy CPU
    assert cameras == sorted(set(cameras)) and len(cameras) <= snapshots + 15, (len(cameras), snapshots)
    jpeg = np.frombuffer(bytes(rows["/cameras/ego"].at("EncodedImage:blob", cameras[-1])[0]), np.uint8)
    assert cv2.imdecode(jpeg, cv2.IMREAD_COLOR).shape == (240, 320, 3)  # the live rig's frames at half size
    assert len(rows["/world/surface/left"].data_frames("Mesh3D:vertex_positions")) > 0
    trackers = rows["/trackers/chest"].data_frames("Transform3D:translation")
    assert trackers and trackers == sorted(set(trackers)) and max(trackers) <= max(cameras) + 30
    assert set(rows["/contact/measured"].at("Scalars:scalars", cameras[-1])) <= {0.0, 1.0}
    assert "TransformAxes3D:axis_length" in static["/trackers/chest"]


@pytest.mark.slow
def test_eval_video_writes_one_recording_per_trajectory(sim_hdf5_root, tiny_checkpoint, tmp_path, capsys):
    out = tmp_path / "eval.rrd"
    assert main(["eval", "--checkpoint", str(tiny_checkpoint), "--data", str(sim_hdf5_root), "--split", "train",
                 "--num-traj", "1", "--views", "ego", "all", "--out", str(tmp_path / "eval"), "--video", "--rerun", str(out)]) == 0
    results = json.loads((tmp_path / "eval" / "results.json").read_text())["results"]
    recordings = RrdReader(out).recordings()
    assert len(recordings) == sum(len(r["trajectories"]) for r in results) == 2  # one per trajectory and view configuration
    assert len({r.recording_id for r in recordings}) == 2
    frames = results[0]["trajectories"][0]["frames"]
    marked = []
    for recording in recordings:
        rows, _ = recording_rows(out, recording)
        assert rows["/pressure/measured"].data_frames("EncodedImage:blob") == list(range(frames))
        assert len(rows["/cameras/ego"].data_frames("EncodedImage:blob")) == frames  # HDF5 frames go as JPEG
        marked.append(sorted(entity for entity, entity_rows in rows.items()
                             if entity.endswith("/not_used") and entity_rows.data_frames("Points2D:positions") == [0]))
    # --views ego: the wrist cameras are marked "not used" from the first frame on; all: none is (the merged file
    # keeps the recordings in no fixed order)
    assert sorted(marked) == [[], ["/cameras/wrist_left/not_used", "/cameras/wrist_right/not_used"]]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eval", "eval.rrd"]  # no part left behind


def _dashboard_with_recording(episode: Path, rrd: Path) -> str:
    from touchanything.app.sessions.engine_choice import choose, default_checkpoint
    from touchanything.app.sessions.replay_runs import replay_in_dashboard

    dashboard = replay_in_dashboard(episode, choose(default_checkpoint()), max_frames=30, rerun=RerunTarget(rrd))
    return dashboard.session.rerun.line()


def test_the_dashboard_replay_logs_through_the_session(dashboard_display, episode_dir, tmp_path):
    from tests.timing.test_dashboard import in_fresh_process

    line = in_fresh_process(_dashboard_with_recording, episode_dir, tmp_path / "d.rrd")
    logged = int(line.split()[1])
    rows, static = recording_rows(tmp_path / "d.rrd")
    assert "AssetVideo:blob" in static["/cameras/ego"]  # the raw episode's MP4, not frames
    measured = rows["/pressure/measured"].data_frames("EncodedImage:blob")
    assert len(measured) > 10 and measured == sorted(measured) and logged >= len(measured)
    assert len(rows["/pressure/predicted"].data_frames("EncodedImage:blob")) > 5
