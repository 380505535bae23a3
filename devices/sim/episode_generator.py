"""Generate one simulated EgoTouch episode: plan a script, then for every frame pose the hands, compute
touch, render the three cameras and write every stream through `RawEpisodeWriter`."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.devices.episodes.episode_files import write_camera_matrices
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.raw_episode import CAMERA_FILE
from touchanything.devices.hand_pose import wilor_focal_px
from touchanything.devices.rig.pose_transform import wilor_from_camera
from touchanything.devices.sim.cameras import HEIGHT, WIDTH, head_camera, wrist_camera
from touchanything.devices.sim.catalogue import BIMANUAL_ACTIONS, CATALOGUE, SCENES, UNSEEN_OBJECTS
from touchanything.devices.sim.hand_model import hand_state
from touchanything.devices.sim.renderer import Capsules, Lighting, render
from touchanything.devices.sim.rig import quat_wxyz, rokoko_joints, tracker_poses
from touchanything.devices.sim.shapes import FaceSet
from touchanything.devices.sim.task_scripts import SIDES, Planner
from touchanything.devices.sim.touch import Glove, cell_pressure
from touchanything.devices.sim.visibility import visible
from touchanything.devices.sim.world import make_object, object_timeline, static_faces
from touchanything.devices.snapshot import FPS, VIEW_NAMES
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.devices.tactile_pipeline import TactileConfig

WILOR_FOCAL = wilor_focal_px(WIDTH, HEIGHT)
GLOVE_COLOUR = (44, 44, 50)
SLEEVES = ((60, 80, 120), (120, 60, 50), (80, 80, 80), (150, 140, 120), (40, 90, 70))
CAMERAS = ("chest", "left", "right")
"""The cameras' names in `camera_matrix.txt` and the dataset card, in `VIEW_NAMES` order."""
CONTACT = 0.1
DEAD_COLUMN_PROBABILITY = 0.25
VISIBILITY_EVERY = 5
"""Contact visibility is sampled every fifth frame (a statistic; sphere tracing is the costly part)."""


@dataclass(frozen=True)
class EpisodeSpec:
    """One episode to generate: scene category, length, its own seed, and whether it uses unseen objects."""

    scene: str
    seconds: float
    seed: int
    unseen: bool
    trajectory_id: str


@dataclass
class EpisodeStats:
    """Counts for the dataset card; contact means a tactile cell above 0.1 (before the glove).
    contact["<hand>/<action>"] = [frames in contact, frames];
    visible["<camera>/<hand>"] = [contact points visible from the camera, contact points of that hand]."""

    folder: Path
    scene: str
    task: str
    objects: list[str]
    frames: int
    unseen: bool
    dead_column: int | None
    contact: dict = field(default_factory=dict)
    visible: dict = field(default_factory=dict)


def _pick_objects(spec: EpisodeSpec, rng: np.random.Generator) -> list[str]:
    pool = SCENES[spec.scene].objects
    unseen = [o for o in pool if o in UNSEEN_OBJECTS]
    seen = [o for o in pool if o not in UNSEEN_OBJECTS]
    first = rng.choice(unseen) if spec.unseen and unseen else rng.choice(seen)
    second = rng.choice([o for o in seen if o != first])
    return [str(first), str(second)]


def plan(spec: EpisodeSpec, rng: np.random.Generator):
    """Objects, script and task name of an episode."""
    ids = _pick_objects(spec, rng)
    side = rng.choice([-1.0, 1.0])
    objects = [make_object(ids[0], side * rng.uniform(0.08, 0.14), rng.uniform(0.2, 0.28)),
               make_object(ids[1], -side * rng.uniform(0.13, 0.2), rng.uniform(0.22, 0.32))]
    planner = Planner(objects, rng)
    t = planner.idle(0.0, rng.uniform(0.5, 1.0))
    first_action = None
    while t < spec.seconds - 2.5:
        obj = 0 if first_action is None or rng.random() < 0.6 else 1
        actions = CATALOGUE[ids[obj]].actions
        bimanual = [a for a in actions if a in BIMANUAL_ACTIONS]
        single = [a for a in actions if a not in BIMANUAL_ACTIONS]
        action = rng.choice(bimanual) if bimanual and (not single or rng.random() < 0.35) else rng.choice(single)
        first_action = first_action or f"{action}_{ids[obj]}"
        t = planner.run(str(action), t, obj, hand=int(rng.random() < 0.6))
        t = planner.idle(t, rng.uniform(0.3, 0.8))
    for track in planner.script.tracks:
        track.hold(max(spec.seconds, t))
    return objects, ids, planner.script, first_action or "idle"


def _wilor(head, joints: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, bool]:
    """Head-camera joints in the WiLoR convention (focal 5000/256·640: depth scaled), with estimator noise."""
    uv, _, ok = head.project(joints)
    valid = bool((ok & head.in_image(uv)).mean() >= 0.6 and rng.random() > 0.03)
    out = wilor_from_camera(head.to_camera(joints), WILOR_FOCAL / head.focal * rng.normal(1.0, 0.02))
    return (out + rng.normal(0.0, 0.003, out.shape)).astype(np.float32), valid


def _labels(script, times: np.ndarray) -> np.ndarray:
    """(T, 2) action name per frame and hand ('idle' outside its segments)."""
    labels = np.full((len(times), 2), "idle", dtype=object)
    for seg in script.segments:
        inside = (times >= seg.start) & (times < seg.end)
        for hand in seg.hands:
            labels[inside, hand] = seg.action
    return labels


def generate_episode(root: Path, spec: EpisodeSpec, layout: TactileLayout | None = None) -> EpisodeStats:
    """Write `<root>/<Scene>/<task>/<trajectory_id>/` and return its statistics."""
    rng = np.random.default_rng(spec.seed)
    layout = layout or TactileLayout.default()
    objects, ids, script, task = plan(spec, rng)
    scene = SCENES[spec.scene]
    frames = int(round(spec.seconds * FPS))
    times = np.arange(frames) / FPS
    tracks = [track.sample(times) for track in script.tracks]
    hand_poses = np.zeros((frames, 2, 4, 4))
    for h in range(2):
        hand_poses[:, h] = np.eye(4)
        hand_poses[:, h, :3, :3], hand_poses[:, h, :3, 3] = tracks[h][1], tracks[h][0]
    timeline = object_timeline(objects, script.attachments, hand_poses, times)
    dead = int(rng.integers(2, 19)) if rng.random() < DEAD_COLUMN_PROBABILITY else None
    glove = Glove.draw(rng, dead)
    config = TactileConfig(broken_columns=(("right", dead),) if dead is not None else ())
    lighting = Lighting(scene.lighting.light, scene.lighting.ambient, scene.lighting.background_top,
                        scene.lighting.background_bottom, scene.lighting.gain * rng.uniform(0.9, 1.1))
    sleeve = np.array(SLEEVES[int(rng.integers(len(SLEEVES)))], float)
    head_base, head_target = np.array([0.0, -0.2, 0.45]) + rng.normal(0, 0.015, 3), np.array([0.0, 0.2, 0.0])
    statics = static_faces(scene)
    labels = _labels(script, times)
    folder = Path(root) / spec.scene / task / spec.trajectory_id
    stats = EpisodeStats(folder, spec.scene, task, ids, frames, spec.unseen, dead)
    with RawEpisodeWriter(folder, layout, config, crf=23) as writer:
        for k in range(frames):
            for shape, pose in zip(objects, timeline.poses[k]):
                shape.pose = pose
            hands = [hand_state(SIDES[h], hand_poses[k, h], tracks[h][2][k]) for h in range(2)]
            pressure = np.stack([cell_pressure(hand, objects) for hand in hands])
            sway = 0.01 * np.array([np.sin(0.9 * times[k]), np.sin(0.6 * times[k] + 1.0), 0.5 * np.sin(1.3 * times[k])])
            cameras = [head_camera(head_base + sway, head_target)] + [wrist_camera(SIDES[h], hand_poses[k, h]) for h in range(2)]
            faces = FaceSet.concat([statics] + [shape.faces() for shape in objects] + [hand.palm.faces() for hand in hands])
            colours = np.array([GLOVE_COLOUR] * (len(hands[0].bone_radius) - 1) + [sleeve])
            bones = Capsules(np.concatenate([h.bone_a for h in hands]), np.concatenate([h.bone_b for h in hands]),
                             np.concatenate([h.bone_radius for h in hands]), np.concatenate([colours, colours]))
            spheres = [(s.pose[:3, 3], s.size[0], np.asarray(s.colour, float)) for s in objects if s.kind == "sphere"]
            images = [render(camera, faces, bones, spheres, lighting) for camera in cameras]
            _count(stats, hands, pressure, labels[k], cameras if k % VISIBILITY_EVERY == 0 else [], objects)
            wilor = [_wilor(cameras[0], hand.joints, rng) for hand in hands]
            writer.write(EpisodeFrame(
                images=dict(zip(VIEW_NAMES, images)),
                wilor=(np.stack([w[0] for w in wilor]), np.array([w[1] for w in wilor])),
                rokoko=(rokoko_joints(np.stack([h.joints for h in hands])), np.ones(2, bool)),
                glove=(glove.raw(pressure, layout, rng), np.ones(2, bool), np.stack([quat_wxyz(p[:3, :3]) for p in hand_poses[k]])),
                trackers=(tracker_poses(cameras[0].pose, hand_poses[k]), np.ones(3, bool)),
            ))
    write_camera_matrices(folder / CAMERA_FILE, {name: cam.matrix for name, cam in zip(CAMERAS, cameras)})
    return stats


def _count(stats: EpisodeStats, hands, pressure: np.ndarray, labels, cameras, objects) -> None:
    for h, hand in enumerate(hands):
        touching = (np.nan_to_num(pressure[h]) > CONTACT) & ~np.isnan(hand.cell_points[..., 0])
        entry = stats.contact.setdefault(f"{SIDES[h]}/{labels[h]}", [0, 0])
        entry[0] += int(touching.any())
        entry[1] += 1
        if not touching.any():
            continue
        points = hand.cell_points[touching]
        for name, camera in zip(CAMERAS, cameras):
            entry = stats.visible.setdefault(f"{name}/{SIDES[h]}", [0, 0])
            entry[0] += int(visible(camera, points, objects, hands).sum())
            entry[1] += len(points)
