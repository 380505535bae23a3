"""Generate one simulated EgoTouch episode: plan a script, then for every frame pose the hands, let soft
objects give way, compute touch, estimate the hand poses as WiLoR would, render the three cameras and write
every stream through `RawEpisodeWriter`."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.hand_pose import wilor_focal_px
from touchanything.core.snapshot import FPS, HANDS, VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_files import write_camera_matrices
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.raw_episode import CAMERA_FILE
from touchanything.devices.sim.cameras import HEIGHT, WIDTH, Camera, head_camera, wrist_camera
from touchanything.devices.sim.catalogue import BIMANUAL_ACTIONS, CATALOGUE, PRESS, REST, SCENES, SIZE_SCALE, UNSEEN_OBJECTS
from touchanything.devices.sim.episode_stats import CAMERAS, EpisodeStats
from touchanything.devices.sim.hand_model import HandState
from touchanything.devices.sim.pose_estimate import camera_from_wilor, estimate_joints, hidden_share, smooth_noise, wilor_joints
from touchanything.devices.sim.renderer import Capsules, Lighting, Scene, render
from touchanything.devices.sim.rig import quat_wxyz, rokoko_joints, tracker_poses
from touchanything.devices.sim.shadows import cast_shadows
from touchanything.devices.sim.shapes import FaceSet, Shape
from touchanything.devices.sim.task_scripts import NEAR_MISSES, Planner
from touchanything.devices.sim.touch import Glove, touch_frame
from touchanything.devices.sim.world import make_object, object_timeline, static_faces
from touchanything.devices.tactile_pipeline import TactileConfig

WILOR_FOCAL = wilor_focal_px(WIDTH, HEIGHT)
GLOVE_COLOUR = (44, 44, 50)
SLEEVES = ((60, 80, 120), (120, 60, 50), (80, 80, 80), (150, 140, 120), (40, 90, 70))
DEAD_COLUMN_PROBABILITY = 0.25
VISIBILITY_EVERY = 5
"""Contact visibility is sampled every fifth frame (a statistic; sphere tracing is the costly part)."""
NEAR_MISS_SHARE = 0.45
"""The share of actions run as one of their near misses (`task_scripts.NEAR_MISSES`)."""
TABLE_SHARE = 0.15
"""The share of one-handed actions that press or rest on a free spot of the table instead of an object."""


@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to generate: scene category, length, its own seed, and whether it uses unseen objects."""

    scene: str
    seconds: float
    seed: int
    unseen: bool
    trajectory_id: str


def _pick_objects(spec: EpisodeSpec, rng: np.random.Generator) -> list[str]:
    pool = SCENES[spec.scene].objects
    unseen = [o for o in pool if o in UNSEEN_OBJECTS]
    seen = [o for o in pool if o not in UNSEEN_OBJECTS]
    first = rng.choice(unseen) if spec.unseen and unseen else rng.choice(seen)
    second = rng.choice([o for o in seen if o != first])
    return [str(first), str(second)]


def _place(ids: list[str], rng: np.random.Generator) -> list[Shape]:
    """The two objects on opposite sides, sizes scaled, at least 4 cm apart."""
    scales = rng.uniform(*SIZE_SCALE, 2)
    reach = [scale * CATALOGUE[i].size[0] for i, scale in zip(ids, scales)]
    side = rng.choice([-1.0, 1.0])
    first = rng.uniform(0.08, 0.14)
    second = max(rng.uniform(0.13, 0.2), reach[0] + reach[1] + 0.04 - first)
    return [make_object(ids[0], side * first, rng.uniform(0.2, 0.28), scales[0]),
            make_object(ids[1], -side * second, rng.uniform(0.22, 0.32), scales[1])]


def _choose(planner: Planner, ids: list[str], first: bool, rng: np.random.Generator):
    """The next action: (action, object index or table point, hand, near-miss variant or None)."""
    obj = 0 if first or rng.random() < 0.6 else 1
    actions = CATALOGUE[ids[obj]].actions
    bimanual = [a for a in actions if a in BIMANUAL_ACTIONS]
    single = [a for a in actions if a not in BIMANUAL_ACTIONS]
    action = str(rng.choice(bimanual) if bimanual and (not single or rng.random() < 0.35) else rng.choice(single))
    hand = int(rng.random() < 0.6)
    where = obj
    if action not in BIMANUAL_ACTIONS and rng.random() < TABLE_SHARE:
        spot = planner.table_spot(hand)
        if spot is not None:
            action, where = str(rng.choice([PRESS, REST])), spot
    variant = str(rng.choice(NEAR_MISSES[action])) if action in NEAR_MISSES and rng.random() < NEAR_MISS_SHARE else None
    return action, where, hand, variant


def plan(spec: EpisodeSpec, rng: np.random.Generator):
    """Objects (at their initial poses), script and task name of an episode."""
    ids = _pick_objects(spec, rng)
    objects = _place(ids, rng)
    initial = [shape.pose.copy() for shape in objects]
    planner = Planner(objects, rng)
    t = planner.idle(0.0, rng.uniform(0.5, 1.0))
    task = None
    while t < spec.seconds - 2.5:
        action, where, hand, variant = _choose(planner, ids, task is None, rng)
        t = planner.run(action, t, where, hand, variant)
        task = task or f"{planner.script.segments[-1].action}_{ids[where] if isinstance(where, int) else 'table'}"
        t = planner.idle(t, rng.uniform(0.3, 0.8))
    for track in planner.script.tracks:
        track.hold(max(spec.seconds, t))
    for shape, pose in zip(objects, initial):
        shape.pose = pose
    return objects, ids, planner.script, task or "idle"


def _labels(script, times: np.ndarray) -> np.ndarray:
    """(T, 2) action name per frame and hand ('idle' outside its segments)."""
    labels = np.full((len(times), 2), "idle", dtype=object)
    for seg in script.segments:
        inside = (times >= seg.start) & (times < seg.end)
        for hand in seg.hands:
            labels[inside, hand] = seg.action
    return labels


@dataclass
class ScriptMotion:
    """A script sampled at the frame rate: times (T,) s, wrist poses (T, 2, 4, 4), flexion (T, 2, 5), object
    poses (T, S, 4, 4), action labels (T, 2)."""

    times: np.ndarray
    hand_poses: np.ndarray
    flexion: np.ndarray
    object_poses: np.ndarray
    labels: np.ndarray


def script_motion(objects: list[Shape], script, frames: int) -> ScriptMotion:
    """Sample `script` (planned over `objects` at their initial poses) at `FPS` for `frames` frames."""
    times = np.arange(frames) / FPS
    tracks = [track.sample(times) for track in script.tracks]
    hand_poses = np.repeat(np.eye(4)[None, None], frames, axis=0).repeat(2, axis=1)
    for h in range(2):
        hand_poses[:, h, :3, :3], hand_poses[:, h, :3, 3] = tracks[h][1], tracks[h][0]
    timeline = object_timeline(objects, script.attachments, hand_poses, times)
    return ScriptMotion(times, hand_poses, np.stack([tracks[0][2], tracks[1][2]], axis=1), timeline.poses, _labels(script, times))


def _pose_valid(head: Camera, joints: np.ndarray, rng: np.random.Generator) -> bool:
    """WiLoR finds a hand when at least 60 % of its joints are in the image, bar 3 % random drop-outs."""
    uv, _, ok = head.project(joints)
    return bool((ok & head.in_image(uv)).mean() >= 0.6 and rng.random() > 0.03)


def _scene(statics: FaceSet, objects: list[Shape], hands: list[HandState], sleeve: np.ndarray, lighting: Lighting) -> Scene:
    faces = FaceSet.concat([shape.faces() for shape in objects] + [hand.palm.faces() for hand in hands])
    colours = np.array([GLOVE_COLOUR] * (len(hands[0].bone_radius) - 1) + [sleeve])
    bones = Capsules(np.concatenate([h.bone_a for h in hands]), np.concatenate([h.bone_b for h in hands]),
                     np.concatenate([h.bone_radius for h in hands]), np.concatenate([colours, colours]))
    spheres = [(s.pose[:3, 3], s.size[0], np.asarray(s.colour, float)) for s in objects if s.kind == "sphere"]
    return Scene(statics, faces, bones, spheres, cast_shadows(hands, objects, lighting), lighting)


def generate_episode(root: Path, spec: EpisodeSpec, layout: TactileLayout | None = None) -> EpisodeStats:
    """Write `<root>/<Scene>/<task>/<trajectory_id>/` and return its statistics."""
    rng = np.random.default_rng(spec.seed)
    layout = layout or TactileLayout.default()
    objects, ids, script, task = plan(spec, rng)
    scene = SCENES[spec.scene]
    frames = int(round(spec.seconds * FPS))
    motion = script_motion(objects, script, frames)
    dead = int(rng.integers(2, 19)) if rng.random() < DEAD_COLUMN_PROBABILITY else None
    glove = Glove.draw(rng, dead)
    config = TactileConfig(broken_columns=(("right", dead),) if dead is not None else ())
    lighting = Lighting(scene.lighting.light, scene.lighting.ambient, scene.lighting.background_top,
                        scene.lighting.background_bottom, scene.lighting.gain * rng.uniform(0.9, 1.1))
    sleeve = np.array(SLEEVES[int(rng.integers(len(SLEEVES)))], float)
    head_base, head_target = np.array([0.0, -0.2, 0.45]) + rng.normal(0, 0.015, 3), np.array([0.0, 0.2, 0.0])
    noise = smooth_noise(rng, frames, FPS)
    statics = static_faces(scene)
    folder = Path(root) / spec.scene / task / spec.trajectory_id
    stats = EpisodeStats(folder, spec.scene, task, ids, frames, spec.unseen, dead)
    stats.start_poses(motion.labels)
    with RawEpisodeWriter(folder, layout, config, crf=23) as writer:
        for k, t in enumerate(motion.times):
            hands, pressure = touch_frame(objects, motion.object_poses[k], motion.hand_poses[k], motion.flexion[k], HANDS)
            sway = 0.01 * np.array([np.sin(0.9 * t), np.sin(0.6 * t + 1.0), 0.5 * np.sin(1.3 * t)])
            cameras = [head_camera(head_base + sway, head_target)] + [wrist_camera(HANDS[h], motion.hand_poses[k, h]) for h in range(2)]
            world = _scene(statics, objects, hands, sleeve, lighting)
            images = [render(camera, world) for camera in cameras]
            stats.record_frame(k, hands, pressure, cameras, objects, k % VISIBILITY_EVERY == 0)
            wilor, estimate = _estimate(k, stats, hands, motion, cameras[0], objects, noise[k], rng)
            writer.write(EpisodeFrame(
                images=dict(zip(VIEW_NAMES, images)),
                wilor=wilor,
                rokoko=(rokoko_joints(estimate), np.ones(2, bool)),
                glove=(glove.raw(pressure, layout, rng), np.ones(2, bool), np.stack([quat_wxyz(p[:3, :3]) for p in motion.hand_poses[k]])),
                trackers=(tracker_poses(cameras[0].pose, motion.hand_poses[k]), np.ones(3, bool)),
            ))
    write_camera_matrices(folder / CAMERA_FILE, {name: cam.matrix for name, cam in zip(CAMERAS, cameras)})
    return stats


def _estimate(k: int, stats: EpisodeStats, hands: list[HandState], motion: ScriptMotion, head: Camera,
              objects: list[Shape], noise: np.ndarray, rng: np.random.Generator):
    """The frame's WiLoR stream ((2, 21, 3) joints, (2,) valid) and the estimated world joints (2, 21, 3) the
    Rokoko stream carries; records the pose the model reads in `stats`."""
    depth_scale = WILOR_FOCAL / head.focal
    wilor, valid, world = [], [], []
    for h, hand in enumerate(hands):
        hidden = hidden_share(head, hand.joints, objects, hands[1 - h])
        world.append(estimate_joints(HANDS[h], motion.hand_poses[k, h], motion.flexion[k, h], head, noise[h], hidden))
        valid.append(_pose_valid(head, hand.joints, rng))
        wilor.append(wilor_joints(head, world[-1], depth_scale, rng))
        stats.record_estimate(k, h, camera_from_wilor(wilor[-1].astype(np.float64), depth_scale), valid[-1], hidden)
    return (np.stack(wilor), np.array(valid)), np.stack(world)
