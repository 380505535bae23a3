"""The one device contract, held by every live source that can run here (an OpenCV camera on a real video
file, a JQ glove on a pty, the Rokoko receiver on loopback, the simulated rig's recorded trackers, the rig
clock), and the one registry of device kinds that the scene reader and the live rig share."""
from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from helpers.simulated_rig import glove_sample
from touchanything.app.cli import main
from touchanything.app.sessions.scene import read_scene
from touchanything.core.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, UserError
from touchanything.devices.camera_pose.estimator import CameraPoseConfig
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.hardware import registry
from touchanything.devices.hardware.camera_hands import CameraHands
from touchanything.devices.hardware.jq_glove import JQGlove, JQGloveConfig
from touchanything.devices.hardware.oak_camera import OakCamera, OakCameraConfig
from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
from touchanything.devices.hardware.openvr_trackers import OpenVRTrackers, OpenVRTrackersConfig
from touchanything.devices.hardware.rokoko_udp import RokokoConfig, RokokoReceiver
from touchanything.devices.hardware.threaded_source import SourceCounters, ThreadedSource
from touchanything.devices.rig.rig_clock import RigClock
from touchanything.devices.sim.device_emulator import EpisodeTrackers
from touchanything.devices.sim.glove_serial import SimulatedGloveSerial
from touchanything.devices.sim.rokoko_sender import RokokoSenderConfig, SimulatedRokokoSender


def wait_for(predicate: Callable[[], object], timeout: float = 10.0) -> object:
    deadline = time.monotonic() + timeout
    while not (result := predicate()):
        assert time.monotonic() < deadline, "condition not met before the deadline"
        time.sleep(0.005)
    return result


@contextlib.contextmanager
def camera(tmp_path: Path) -> Iterator[ThreadedSource]:
    video = tmp_path / "clip.mp4"
    with VideoWriter(video) as writer:
        for k in range(10):
            writer.write(np.full((48, 64, 3), 20 * k, np.uint8))
    yield OpenCVCamera(OpenCVCameraConfig(str(video), width=64, height=48, loop=True))


@contextlib.contextmanager
def glove(tmp_path: Path) -> Iterator[ThreadedSource]:
    with SimulatedGloveSerial("left", lambda k: glove_sample("left", k), tmp_path) as simulated:
        yield JQGlove(JQGloveConfig(str(simulated.path), "left"))


@contextlib.contextmanager
def rokoko(tmp_path: Path) -> Iterator[ThreadedSource]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # a free port for the receiver
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    hands = (np.zeros((2, 21, 3), np.float32), np.ones(2, bool))
    with SimulatedRokokoSender(lambda k: hands, RokokoSenderConfig(port=port)):
        yield RokokoReceiver(RokokoConfig(port=port))


@contextlib.contextmanager
def recorded_trackers(tmp_path: Path, episode_dir: Path) -> Iterator[ThreadedSource]:
    with open_episode(episode_dir) as episode:
        yield EpisodeTrackers(episode)


@contextlib.contextmanager
def rig_clock(tmp_path: Path) -> Iterator[ThreadedSource]:
    yield RigClock([])


SOURCES = {"camera": camera, "glove": glove, "rokoko": rokoko, "rig clock": rig_clock}


@pytest.mark.parametrize("kind", [*SOURCES, "recorded trackers"])
def test_every_source_keeps_the_one_contract(kind, tmp_path, episode_dir):
    threads = threading.active_count()
    make = SOURCES.get(kind) or (lambda path: recorded_trackers(path, episode_dir))
    with make(tmp_path) as source:
        assert isinstance(source, ThreadedSource) and not source.is_connected
        assert source.latest() is None and source.rate_hz() == 0 and source.age_ms() is None
        with source:
            assert source.is_connected
            with pytest.raises(DeviceAlreadyConnectedError) as error:
                source.connect()
            assert isinstance(error.value, UserError) and "\n" not in str(error.value)
            assert str(error.value) == f"{source.name} is already connected; disconnect it first"
            wait_for(lambda: source.counters.samples >= 3)
            assert source.latest().t_us > 0 and wait_for(lambda: source.rate_hz() > 0)
            assert 0 <= source.age_ms() < 5_000 and isinstance(source.counters, SourceCounters)
            assert not source.retrying and source.down_reason is None and source.counters.reconnects == 0
            status = source.status()
            assert status and "\n" not in status and "last error" not in status, status
        assert not source.is_connected
        source.disconnect()  # a second disconnect does nothing
        assert source.latest() is not None  # the last sample stays readable until the next connect
        source.connect()  # and a disconnected source connects again, from fresh counters
        assert source.counters.samples <= 1
        source.disconnect()
    assert wait_for(lambda: threading.active_count() <= threads, timeout=5)


def test_sources_that_cannot_run_here_fail_to_connect_with_one_line_and_leave_nothing(tmp_path):
    threads = threading.active_count()
    absent = [OpenCVCamera(OpenCVCameraConfig(97)), OakCamera(OakCameraConfig(device_id="14442C10D13EABCE00")),
              JQGlove(JQGloveConfig(str(tmp_path / "no-glove"), "right")),
              OpenVRTrackers(OpenVRTrackersConfig({"LHR-1": "chest"}))]
    for source in absent:
        with pytest.raises(UserError) as error:
            source.connect()
        assert "\n" not in str(error.value) and not source.is_connected and source.status() == "disconnected"
    assert threading.active_count() == threads


def test_not_connected_is_a_typed_error():
    receiver = RokokoReceiver(RokokoConfig(port=0))
    with pytest.raises(DeviceNotConnectedError, match="^Rokoko receiver is not connected") as error:
        _ = receiver.bound_address
    assert isinstance(error.value, UserError)


# --- the registry -----------------------------------------------------------------------------------------


def test_the_registry_maps_each_kind_to_its_config_and_device():
    assert set(registry.KINDS) == {"opencv", "oak", "jq", "rokoko", "openvr", "camera"}
    assert registry.kinds_for("hands") == ("rokoko", "camera")
    assert registry.kinds_for("camera") == ("opencv", "oak")
    examples = [OpenCVCameraConfig(0), OakCameraConfig(), JQGloveConfig("/dev/ttyACM0", "left"), RokokoConfig(),
                OpenVRTrackersConfig({"LHR-1": "chest"})]
    for config in examples:
        kind = registry.kind_of(config)
        device = registry.create_device(config)
        assert isinstance(config, kind.config) and isinstance(device, ThreadedSource) and device.config is config
        assert type(device) is kind.device and registry.device_kind(kind.name, kind.role) is kind
    ego = OpenCVCamera(OpenCVCameraConfig(0))
    hands = registry.create_device(CameraPoseConfig(), {"ego": ego})
    assert type(hands) is CameraHands and hands.camera is ego and registry.kind_of(hands.config).reads == "ego"
    with pytest.raises(UserError, match=r'^hands kind "camera" needs the ego camera \(\[cameras.ego\]\)$'):
        registry.create_device(CameraPoseConfig())
    with pytest.raises(UserError, match="^kind must be \"opencv\" or \"oak\", got 'jq'$"):
        registry.device_kind("jq", "camera")
    with pytest.raises(TypeError, match="no device kind"):
        registry.kind_of(object())


def test_scene_sections_are_read_through_the_registry(tmp_path):
    (tmp_path / "clip.mp4").touch()
    scene = tmp_path / "scene.toml"
    scene.write_text('[cameras.ego]\nkind = "opencv"\nsource = "clip.mp4"\n'
                     '[cameras.wrist_left]\nkind = "oak"\ndevice_id = "X"\n'
                     '[gloves.right]\nkind = "jq"\nport = "ports/right"\nreconnect_backoff_s = [0.2, 1.0]\n'
                     '[trackers]\n[trackers.roles]\n"LHR-1" = "chest"\n')
    read = read_scene(scene)
    assert read.cameras["ego"] == OpenCVCameraConfig(str(tmp_path / "clip.mp4"))
    assert read.cameras["wrist_left"] == OakCameraConfig(device_id="X")
    assert read.gloves["right"] == JQGloveConfig(str(tmp_path / "ports" / "right"), "right", reconnect_backoff_s=(0.2, 1.0))
    assert read.trackers == OpenVRTrackersConfig({"LHR-1": "chest"})
    for text, message in [('[gloves.left]\nkind = "oak"\nport = "x"\n', '[gloves.left] kind must be "jq", got \'oak\''),
                          ('[hands]\nsource = "leap"\n', '[hands] source must be "rokoko" or "camera", got \'leap\''),
                          ('[trackers]\nkind = "openxr"\n', '[trackers] kind must be "openvr"'),
                          ("[trackers]\nrate_hz = 30\n", "[trackers] needs a roles setting"),
                          ("[gloves.left]\nport = 'x'\nreconnect_backoff_s = [2, 1]\n", "back-off")]:
        scene.write_text(text)
        with pytest.raises(UserError, match="^" + str(scene).replace(".", r"\.") + ": ") as error:
            read_scene(scene)
        assert message in str(error.value) and "\n" not in str(error.value)


def test_a_device_error_reaches_the_command_line_as_one_line(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[gloves.left]\nport = "{tmp_path / "no-glove"}"\n')
    assert main(["record", "--scene", str(scene), "--out", str(tmp_path / "take"), "--seconds", "0.1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("touchanything record: error: glove port ") and "Traceback" not in err
