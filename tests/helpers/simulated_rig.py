"""A small live rig for tests: two simulated gloves on ptys read by JQGlove, a simulated Rokoko Studio on
loopback read by RokokoReceiver, an OpenCVCamera playing a video file written here, and a stand-in for
the Vive trackers (OpenVR has no simulator). Every sample says which one it is, so tests can check that a
Snapshot holds exactly what a simulator sent."""
from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import HANDS, Snapshot
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.hardware.jq_glove import JQGlove, JQGloveConfig
from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
from touchanything.devices.hardware.openvr_trackers import TrackerReading
from touchanything.devices.hardware.rokoko_udp import RokokoConfig, RokokoReceiver
from touchanything.devices.hardware.threaded_source import now_us
from touchanything.devices.rig.rig_inputs import RigInput, camera_fill, glove_fill, mocap_fill, trackers_fill
from touchanything.devices.sim.glove_serial import SimulatedGloveSerial
from touchanything.devices.sim.rokoko_sender import RokokoSenderConfig, SimulatedRokokoSender

CAMERA_SIZE = (160, 120)
CHEST_POSE = np.array([0.1, 1.2, 0.3, 1.0, 0.0, 0.0, 0.0], np.float32)


def glove_sample(side: str, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample k of a glove: a raw ramp shifted by k, and k in the quaternion's x (so a reading names its k)."""
    h = HANDS.index(side)
    raw = ((np.arange(256) + k + 100 * h) % 256).astype(np.uint8)
    return raw, np.array([1.0, k, h, 0.0], np.float32)


def mocap_hands(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Rokoko frame k: both hands, joint positions moving by 1 mm per frame (joint 0's z is k mm)."""
    joints = np.tile(np.linspace(-0.1, 0.1, 21, dtype=np.float32)[None, :, None], (2, 1, 3))
    joints[..., 2] += np.float32(k / 1000)
    joints[0, 0, 2] = np.float32(k / 1000)
    return joints, np.array([True, True])


def to_model(joints: np.ndarray, present: np.ndarray, trackers: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A stand-in for the mocap → head-camera transform: a fixed scale and shift; valid with a chest pose."""
    model = joints * np.float32(20) + np.array([0, 0, 50], np.float32)
    return model, present & ("chest" in trackers)


def frame_picture(k: int) -> np.ndarray:
    """A smooth RGB picture for video frame k (compresses well, decodes close)."""
    w, h = CAMERA_SIZE
    y, x = np.mgrid[0:h, 0:w]
    image = np.empty((h, w, 3), np.uint8)
    image[..., 0] = (x * 255 // (w - 1) + 8 * k) % 256
    image[..., 1] = y * 255 // (h - 1)
    image[..., 2] = (4 * k) % 256
    return image


class StandInTrackers:
    """The chest tracker at a fixed pose, sampled when asked (the LatestSource protocol)."""

    def latest(self) -> TrackerReading:
        return TrackerReading({"chest": CHEST_POSE}, now_us())

    def status(self) -> str:
        return "stand-in chest tracker"


def synthetic_snapshot(k: int) -> Snapshot:
    """Frame k of a recording that names k in every stream: picture, joints, glove ramp (left glove only
    on even frames), trackers from frame 10 on."""
    joints = np.full((42, 3), k / 7, np.float32)
    joints[:, 2] += 40
    raw = np.stack([(np.arange(256) + k) % 256, np.full(256, k % 256)]).astype(np.uint8)
    return Snapshot(
        frame_index=k, t_us=1_000_000 + k * 33_333, images={"ego": frame_picture(k)},
        joints=joints, joints_valid=np.array([True, k % 3 != 0]),
        pressure_raw=raw, imu_wxyz=np.array([[1, 0, 0, 0], [0, 1, 0, 0]], np.float32),
        glove_present=np.array([k % 2 == 0, True]),
        trackers={"chest": np.full(7, k, np.float32)} if k >= 10 else {},
    )


@dataclass
class Rig:
    inputs: list[RigInput]
    gloves: dict[str, SimulatedGloveSerial]


@contextlib.contextmanager
def simulated_rig(folder: Path) -> Iterator[Rig]:
    """Start the simulators and connect the adapters; everything is stopped and closed on exit."""
    video = folder / "camera.mp4"
    with VideoWriter(video) as writer:
        for k in range(30):
            writer.write(frame_picture(k))
    with contextlib.ExitStack() as stack:
        gloves = {side: stack.enter_context(SimulatedGloveSerial(side, lambda k, s=side: glove_sample(s, k), folder))
                  for side in HANDS}
        readers = {side: JQGlove(JQGloveConfig(str(gloves[side].path), side)) for side in HANDS}
        receiver = RokokoReceiver(RokokoConfig(port=0))
        camera = OpenCVCamera(OpenCVCameraConfig(str(video), *CAMERA_SIZE, loop=True))
        for source in (*readers.values(), receiver, camera):
            stack.enter_context(source)
        sender = SimulatedRokokoSender(mocap_hands, RokokoSenderConfig(port=receiver.bound_address[1]))
        stack.enter_context(sender)
        inputs = [RigInput("ego", camera, camera_fill("ego")),
                  RigInput("mocap", receiver, mocap_fill(to_model)),
                  *(RigInput(f"glove_{side}", readers[side], glove_fill(side)) for side in HANDS),
                  RigInput("trackers", StandInTrackers(), trackers_fill())]
        yield Rig(inputs, gloves)
