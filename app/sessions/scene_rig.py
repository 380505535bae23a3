"""The live rig of a scene: its sources connected in order (a failed connect disconnects the ones already
up), the simulated rig first when the scene has one, and the 30 Hz rig clock over them. Every device is
built from its config by the device registry and follows the one device contract (ThreadedSource). The
hands come from the mocap (through the `[pose]` calibration) or are estimated from the ego camera."""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from touchanything.app.sessions.scene import Scene
from touchanything.core.errors import UserError
from touchanything.devices.camera_pose.estimator import CameraPoseConfig
from touchanything.devices.hardware.registry import create_device
from touchanything.devices.hardware.threaded_source import ThreadedSource
from touchanything.devices.rig.pose_transform import PoseCalibration, mocap_to_model_frame
from touchanything.devices.rig.rig_clock import RigClock
from touchanything.devices.rig.rig_inputs import (
    RigInput,
    camera_fill,
    camera_hands_fill,
    glove_fill,
    mocap_fill,
    trackers_fill,
)
from touchanything.devices.sim.device_emulator import SimulatedLiveRig


@dataclass
class _Source:
    name: str
    device: ThreadedSource
    input: RigInput


class LiveRig:
    """`start()` connects everything and starts the clock (returned); `stop()` undoes it in reverse.
    `sources` maps each source name to its device (for status rows)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.simulator = SimulatedLiveRig(scene.simulator) if scene.simulator is not None else None
        self.clock: RigClock | None = None
        self._sources: list[_Source] = []

    @property
    def sources(self) -> dict[str, ThreadedSource]:
        return {source.name: source.device for source in self._sources}

    def _plan(self) -> list[_Source]:
        scene, plan, cameras = self.scene, [], {}
        for view, config in scene.cameras.items():
            cameras[view] = camera = create_device(config)
            plan.append(_Source(view, camera, RigInput(view, camera, camera_fill(view))))
        for hand, config in scene.gloves.items():
            glove = create_device(config)
            plan.append(_Source(f"glove_{hand}", glove, RigInput(f"glove_{hand}", glove, glove_fill(hand))))
        trackers = create_device(scene.trackers) if scene.trackers is not None else \
            (self.simulator.trackers if self.simulator is not None else None)
        if trackers is not None:
            plan.append(_Source("trackers", trackers, RigInput("trackers", trackers, trackers_fill())))
        if isinstance(scene.hands, CameraPoseConfig):
            hands = create_device(scene.hands, cameras)
            plan.append(_Source("camera hands", hands, RigInput("camera hands", hands, camera_hands_fill())))
        elif scene.hands is not None:
            if not scene.pose:
                raise UserError(f"{scene.path}: [hands] needs a [pose] calibration to bring the mocap joints "
                                "into the head-camera frame")
            to_model = partial(_model_frame, calibration=PoseCalibration.from_dict(scene.pose))
            mocap = create_device(scene.hands)
            plan.append(_Source("mocap", mocap, RigInput("mocap", mocap, mocap_fill(to_model))))
        return plan

    def start(self) -> RigClock:
        try:
            if self.simulator is not None:
                self.simulator.start()
            for source in self._plan():
                source.device.connect()
                self._sources.append(source)
            self.clock = RigClock([s.input for s in self._sources], self.scene.clock)
            self.clock.connect()
        except BaseException:
            self.stop()
            raise
        return self.clock

    def stop(self) -> None:
        if self.clock is not None:
            self.clock.disconnect()
            self.clock = None
        while self._sources:
            self._sources.pop().device.disconnect()
        if self.simulator is not None:
            self.simulator.stop()

    def __enter__(self) -> RigClock:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _model_frame(mocap, present, trackers, calibration: PoseCalibration):
    hands = mocap_to_model_frame(mocap, present, trackers, calibration)
    return hands.joints, hands.valid
