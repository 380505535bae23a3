"""The simulated world where the cameras matter: near misses never touch and their actions always do, soft
objects give way visibly, a hover is visible at the model's input size, the pose noise is WiLoR-like, and
the pose-ambiguity statistic moves the right way."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from touchanything.app.cli import main
from touchanything.core.snapshot import FPS, HANDS
from touchanything.devices.sim.cameras import head_camera, wrist_camera
from touchanything.devices.sim.catalogue import (
    AIR_PUSH,
    GRASP,
    HOVER,
    HOVER_PRESS,
    MISS,
    PRESS,
    PUSH,
    REST,
    REST_HOVER,
    SCENES,
    SQUEEZE,
    UNTOUCHED,
)
from touchanything.devices.sim.episode_generator import _scene, script_motion
from touchanything.devices.sim.episode_stats import EpisodeStats
from touchanything.devices.sim.pose_ambiguity import APART, nearest_rms, pose_statistics
from touchanything.devices.sim.pose_estimate import TIME_CONSTANT, estimate_joints, smooth_noise
from touchanything.devices.sim.renderer import render
from touchanything.devices.sim.shapes import pose_at
from touchanything.devices.sim.task_scripts import Planner
from touchanything.devices.sim.touch import touch_frame
from touchanything.devices.sim.world import make_object, static_faces

HEAD = head_camera(np.array([0.0, -0.2, 0.45]), np.array([0.0, 0.2, 0.0]))
MODEL_SIZE = 112


def _world(objects=("mug_red", "box_cardboard")):
    return [make_object(objects[0], 0.12, 0.25), make_object(objects[1], -0.2, 0.28)]


def _run(objects, actions, seed: int = 0):
    """Plan `actions` [(action, where, hand, variant)] one after the other over `objects`, with idle in between;
    returns the sampled motion and, per frame, the hands' contact (T, 2), true head-camera joints (T, 2, 21, 3)
    and the soft objects' compression (T, S)."""
    planner = Planner(objects, np.random.default_rng(seed))
    initial = [shape.pose.copy() for shape in objects]
    t = planner.idle(0.0, 0.5)
    for action, where, hand, variant in actions:
        t = planner.idle(planner.run(action, t, where, hand, variant), 0.4)
    for shape, pose in zip(objects, initial):
        shape.pose = pose
    motion = script_motion(objects, planner.script, int(t * FPS))
    touching = np.zeros((len(motion.times), 2), bool)
    joints = np.zeros((len(motion.times), 2, 21, 3))
    squash = np.zeros((len(motion.times), len(objects)))
    for k in range(len(motion.times)):
        hands, pressure = touch_frame(objects, motion.object_poses[k], motion.hand_poses[k], motion.flexion[k], HANDS)
        for h, hand in enumerate(hands):
            tactile = np.isnan(hand.bend) & ~np.isnan(hand.cell_points[..., 0])
            touching[k, h] = (pressure[h][tactile] > 0.0).any()
            joints[k, h] = HEAD.to_camera(hand.joints)
        squash[k] = [shape.squash for shape in objects]
    for shape, pose in zip(objects, initial):
        shape.pose, shape.squash = pose, 0.0
    return planner.script, motion, touching, joints, squash


def _segments(script):
    return [s for s in script.segments if s.action != "idle"]


TABLE_SPOT = np.array([0.2, 0.12, 0.0])
ACTIONS = [
    (GRASP, 0, 1, None), (GRASP, 0, 1, MISS), (SQUEEZE, 0, 1, MISS), (PRESS, 1, 0, None), (PRESS, 1, 0, HOVER),
    (PRESS, 1, 0, HOVER_PRESS), (PRESS, TABLE_SPOT, 1, HOVER), (REST, TABLE_SPOT, 1, None), (REST, TABLE_SPOT, 1, REST_HOVER),
    (REST, 1, 0, REST_HOVER), (PUSH, 0, 1, None), (PUSH, 0, 1, AIR_PUSH),
]


@pytest.fixture(scope="module")
def near_miss_run():
    return _run(_world(), ACTIONS)


def test_a_near_miss_never_produces_pressure_and_its_action_always_does(near_miss_run):
    script, motion, touching, _, _ = near_miss_run
    segments = _segments(script)
    assert [s.action for s in segments] == [GRASP, MISS, MISS, PRESS, HOVER, HOVER_PRESS, HOVER, REST, REST_HOVER, REST_HOVER, PUSH,
                                            AIR_PUSH]
    idle = (motion.labels == "idle")
    assert not touching[idle].any()
    for seg in segments:
        inside = (motion.times >= seg.start) & (motion.times < seg.end)
        hand = seg.hands[-1]
        if seg.action in UNTOUCHED:
            assert not touching[inside, hand].any(), seg
        else:
            assert touching[inside, hand].sum() >= 5, seg


def test_a_missed_grasp_leaves_the_object_and_a_hold_lifts_it(near_miss_run):
    script, motion, _, _, _ = near_miss_run
    hold, miss = _segments(script)[:2]
    mug_z = motion.object_poses[:, 0, 2, 3]
    during = lambda seg: (motion.times >= seg.start) & (motion.times < seg.end)  # noqa: E731
    assert mug_z[during(hold)].max() - mug_z[0] > 0.07
    assert np.ptp(mug_z[during(miss)]) == 0.0


def test_a_push_moves_the_object_and_an_air_push_does_not(near_miss_run):
    script, motion, _, _, _ = near_miss_run
    push, air = _segments(script)[-2:]
    at = lambda t: motion.object_poses[np.searchsorted(motion.times, t), 0, :3, 3]  # noqa: E731
    assert 0.02 <= at(push.end)[1] - at(push.start)[1] <= 0.081
    np.testing.assert_array_equal(at(air.start), at(air.end - 0.05))


def _sponge_scene(squash: float | None):
    """A flat hand resting on a sponge (pressed 2 cm into it); `squash` overrides its compression."""
    sponge = make_object("sponge_yellow", 0.1, 0.25)
    objects = [sponge, make_object("mug_red", -0.2, 0.28)]
    script, motion, touching, _, squashes = _run(objects, [(REST, 0, 1, None)], seed=3)
    k = int(np.argmax(squashes[:, 0]))
    hands, pressure = touch_frame(objects, motion.object_poses[k], motion.hand_poses[k], motion.flexion[k], HANDS)
    if squash is not None:
        sponge.squash = squash
    scene = SCENES["Home"]
    world = _scene(static_faces(scene), objects, hands, np.array([60.0, 80.0, 120.0]), scene.lighting)
    images = [render(camera, world) for camera in (HEAD, wrist_camera("right", motion.hand_poses[k, 1]))]
    return squashes[k, 0], pressure, [cv2.resize(i, (MODEL_SIZE, MODEL_SIZE), interpolation=cv2.INTER_AREA) for i in images]


def _yellow(image: np.ndarray) -> np.ndarray:
    r, g, b = (image[..., c].astype(int) for c in range(3))
    return (r > 150) & (g > 120) & (b < 90) & (r - b > 100)


def test_a_pressed_soft_object_compresses_visibly_at_the_models_input_size():
    squash, pressure, (head, wrist) = _sponge_scene(None)
    assert 0.006 < squash < 0.6 * 2 * make_object("sponge_yellow", 0, 0).height
    assert 0.1 < np.nanmax(pressure[1]) < 0.9  # it gives way: the hand is not 2 cm deep in a rigid block
    _, _, (head_rigid, wrist_rigid) = _sponge_scene(0.0)
    assert _yellow(head).sum() < _yellow(head_rigid).sum() - 10  # fewer sponge pixels at 112 × 112
    assert _changed(wrist, wrist_rigid) >= 15


def _changed(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels where some channel differs by more than 30 levels."""
    return int((np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > 30).sum())


def _rest_images(gap: float):
    objects = _world()
    script, motion, touching, _, _ = _run(objects, [(REST, TABLE_SPOT, 1, None)], seed=5)
    k = int(np.flatnonzero(touching[:, 1])[len(np.flatnonzero(touching[:, 1])) // 2])
    poses = motion.hand_poses[k].copy()
    poses[1, 2, 3] += gap
    hands, pressure = touch_frame(objects, motion.object_poses[k], poses, motion.flexion[k], HANDS)
    scene = SCENES["Office"]
    world = _scene(static_faces(scene), objects, hands, np.array([60.0, 80.0, 120.0]), scene.lighting)
    image = render(wrist_camera("right", poses[1]), world)
    tactile = np.isnan(hands[1].bend) & ~np.isnan(hands[1].cell_points[..., 0])
    return cv2.resize(image, (MODEL_SIZE, MODEL_SIZE), interpolation=cv2.INTER_AREA), pressure[1][tactile].max()


def test_a_hand_hovering_a_centimetre_above_the_table_looks_different_from_one_resting_on_it():
    resting, pressure = _rest_images(0.0)
    deeper, _ = _rest_images(-0.002)
    hovering, hover_pressure = _rest_images(0.012)
    assert pressure > 0.1 and hover_pressure == 0.0
    assert _changed(resting, hovering) > max(3 * _changed(resting, deeper), 300)  # of 112 × 112 wrist-camera pixels


def test_pose_noise_is_centimetre_level_slow_and_larger_for_a_hidden_hand():
    rng = np.random.default_rng(4)
    noise = smooth_noise(rng, 3000, FPS)
    assert abs(noise.std() - 1.0) < 0.1
    lag = int(FPS * TIME_CONSTANT / 2)
    assert np.corrcoef(noise[:-lag].ravel(), noise[lag:].ravel())[0, 1] > 0.6  # does not average out in a 0.5 s window
    pose = pose_at([0.15, 0.2, 0.1], np.eye(3))
    flex = np.full(5, 0.3)
    truth = estimate_joints("right", pose, flex, HEAD, np.zeros(11), 0.0)
    errors = {h: [np.sqrt(np.mean(np.sum((estimate_joints("right", pose, flex, HEAD, n, h) - truth) ** 2, -1)))
                  for n in noise[::10, 1]] for h in (0.0, 1.0)}
    assert 0.01 < np.median(errors[0.0]) < 0.04
    assert np.median(errors[1.0]) > 2 * np.median(errors[0.0])


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 40), st.integers(0, 40), st.integers(0, 2**31))
def test_nearest_rms_is_the_smallest_rms_joint_distance_to_a_pose_of_another_moment(queries, pool, seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(0, 0.1, (queries, 21, 3)), rng.normal(0, 0.1, (pool, 21, 3))
    a_keys, b_keys = rng.integers(0, 2, (queries, 2)) * [1, 20], rng.integers(0, 2, (pool, 2)) * [1, 20] + [0, 7]
    expected = [min((np.sqrt(np.mean(np.sum((x - y) ** 2, -1))) for y, ky in zip(b, b_keys)
                     if ky[0] != kx[0] or abs(ky[1] - kx[1]) >= APART), default=np.inf) for x, kx in zip(a, a_keys)]
    np.testing.assert_allclose(nearest_rms(a, b, a_keys, b_keys), expected, atol=1e-9)


def _stats(motion, touching, joints, error: float) -> EpisodeStats:
    stats = EpisodeStats(Path("ep"), "Home", "task", [], len(motion.times), False, None)
    stats.start_poses(motion.labels)
    stats.poses[:], stats.touching[:], stats.pose_valid[:] = joints, touching, True
    stats.pose_error[:] = error
    return stats


def _grip(motion) -> np.ndarray:
    """The right wrist's position when its fingers are most closed."""
    return motion.hand_poses[int(np.argmax(motion.flexion[:, 1, 1])), 1, :3, 3]


def test_pose_ambiguity_counts_the_same_grip_that_holds_one_mug_and_closes_in_the_air_short_of_another():
    """Episode 2 misses a mug; episode 1 holds a mug placed so that its grip is the miss's grip: the hold's
    contact is pose-ambiguous with the miss in the data set (and not with a hold in its place)."""
    _, miss, miss_touching, miss_joints, _ = _run(_world(), [(GRASP, 0, 1, MISS)])
    _, hold, _, _, _ = _run(_world(), [(GRASP, 0, 1, None)])
    shift = _grip(miss) - _grip(hold)
    assert 0.015 <= np.linalg.norm(shift) <= 0.1 and abs(shift[0]) > 0.9 * np.linalg.norm(shift)  # backed off along the palm normal
    moved = [make_object("mug_red", 0.12 + shift[0], 0.25), make_object("box_cardboard", -0.2, 0.28)]
    _, held, held_touching, held_joints, _ = _run(moved, [(GRASP, 0, 1, None)])
    np.testing.assert_allclose(_grip(held), _grip(miss), atol=1e-9)
    _, other, other_touching, other_joints, _ = _run(_world(), [(GRASP, 0, 1, None)])
    shares = {}
    for name, (motion, touching, joints) in {"miss": (miss, miss_touching, miss_joints),
                                             "hold": (other, other_touching, other_joints)}.items():
        episodes = [_stats(held, held_touching, held_joints, 0.02), _stats(motion, touching, joints, 0.02)]
        card = pose_statistics(episodes)
        assert card["pose_ambiguity"]["tolerance_mm"] == 20.0 and card["pose_error_mm"]["median"] == 20.0
        shares[name] = card["pose_ambiguity"]["by_hand_and_task"]["right/hold"]["ambiguous_share"]
    assert shares["miss"] > shares["hold"] + 0.5, shares
    none = _stats(miss, miss_touching, miss_joints, 0.02)
    none.pose_valid[:] = False
    assert pose_statistics([none]) == {"pose_error_mm": None, "pose_ambiguity": None}


def test_simulate_prints_the_pose_error_and_ambiguity(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "out"), "--episodes", "1", "--seconds", "4", "--seed", "8"]) == 0
    out = capsys.readouterr().out
    assert "pose-ambiguous contact:" in out and "pose error (RMS over joints): median" in out
    # one episode cannot fill a train and a test list: said, not left for `train` to find
    split = json.loads((tmp_path / "out" / "split.json").read_text())
    assert sum(map(len, split.values())) == 1 and f"split     train {len(split['train'])}, val " in out
    assert "warning   the " in out and "list(s) is empty" in out and "simulate more episodes" in out
    card = (tmp_path / "out" / "dataset_card.md").read_text()
    assert "## Pose error and pose ambiguity" in card
