"""`touchanything devices` and the discovery functions behind it: end to end on this machine (no hardware:
one line per kind, nothing else), and the finders on real stand-ins — a folder of symlinks to ptys carrying
simulated JQ gloves in place of /dev/serial/by-id, real video files in place of /dev/video* — whose scene
snippet reads back as a scene whose devices connect."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers.simulated_rig import glove_sample
from touchanything.app.cli import main
from touchanything.app.commands.devices_command import Findings, report_lines, scene_snippet
from touchanything.app.sessions.scene import read_scene
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.hardware.camera_source import CameraFormat
from touchanything.devices.hardware.discovery import (
    Discovery,
    FoundOak,
    FoundTracker,
    find_opencv_cameras,
    find_serial_ports,
    video_devices,
)
from touchanything.devices.hardware.registry import create_device
from touchanything.devices.sim.glove_serial import SimulatedGloveSerial

ROOT = Path(__file__).resolve().parents[2]
KINDS = ("OpenCV cameras:", "OAK cameras:", "serial ports:", "Vive trackers:")


def write_video(path: Path, frames: int = 5, fps: int = 20, size: tuple[int, int] = (48, 64)) -> Path:
    with VideoWriter(path, fps=fps) as writer:
        for k in range(frames):
            writer.write(np.full((*size, 3), 30 * k, np.uint8))
    return path


def test_the_command_on_this_machine_prints_one_line_per_kind_and_nothing_else():
    result = subprocess.run([sys.executable, "-m", "touchanything.app.cli", "devices"], cwd=ROOT,
                            capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONWARNINGS": "default"})
    assert result.returncode == 0 and result.stderr == "", result.stderr
    lines = result.stdout.splitlines()
    assert [line.split()[0] + " " + line.split()[1] for line in lines[:4]] == list(KINDS), result.stdout
    assert not any(word in result.stdout for word in ("Traceback", "WARN", "[depthai]", "[warning]"))
    if not video_devices():
        assert lines[0] == "OpenCV cameras: none found (nothing under /dev/video*)"
    if not Path("/dev/serial/by-id").is_dir():
        assert lines[2] == "serial ports:   none found (nothing under /dev/serial/by-id)"
    if all(line.split(":", 1)[1].strip().startswith("none found (") for line in lines[:4]):
        assert lines[4:] == ["", "nothing found to put in a scene file (scenes/sim.toml runs the simulated rig "
                                 "without hardware)"]


def test_a_bad_listen_time_is_one_line(capsys):
    assert main(["devices", "--listen", "nan"]) == 2
    assert capsys.readouterr().err == "touchanything devices: error: --listen must be a number of seconds ≥ 0, got nan\n"


def test_serial_ports_are_listened_to_for_gloves_and_the_snippet_connects(tmp_path):
    by_id = tmp_path / "by-id"
    by_id.mkdir()
    silent_master, silent_slave = os.openpty()
    (by_id / "usb-FTDI_Other_Device-if00").symlink_to(os.ttyname(silent_slave))
    (by_id / "usb-Not_A_Tty-if00").symlink_to(write_video(tmp_path / "not_a_tty.mp4"))
    try:
        with SimulatedGloveSerial("left", lambda k: glove_sample("left", k), by_id, "usb-Juqiao_A-if00") as left, \
                SimulatedGloveSerial("right", lambda k: glove_sample("right", k), by_id, "usb-Juqiao_B-if00") as right:
            started = time.monotonic()
            found = find_serial_ports(by_id, listen_s=0.3)
            assert time.monotonic() - started < 3
            ports = {Path(port.port).name: port for port in found.found}
            assert set(ports) == {"usb-FTDI_Other_Device-if00", "usb-Juqiao_A-if00", "usb-Juqiao_B-if00",
                                  "usb-Not_A_Tty-if00"}
            assert ports["usb-Juqiao_A-if00"].sides == ("left",) and ports["usb-Juqiao_B-if00"].sides == ("right",)
            assert ports["usb-Juqiao_A-if00"].device == os.path.realpath(left.path)
            assert "JQ glove packets heard (left " in ports["usb-Juqiao_A-if00"].detail
            assert ports["usb-FTDI_Other_Device-if00"].sides == ()
            assert ports["usb-FTDI_Other_Device-if00"].detail.startswith("no JQ glove packets heard in 0.3 s")
            assert ports["usb-Not_A_Tty-if00"].detail.startswith("cannot open it: ")
            findings = Findings(Discovery(reason="x"), Discovery(reason="y"), found, Discovery(reason="z"))
            snippet = scene_snippet(findings)
            assert "# [gloves.SIDE]" in snippet and f'# port = "{by_id / "usb-FTDI_Other_Device-if00"}"' in snippet
            scene_file = tmp_path / "scene.toml"
            scene_file.write_text(snippet)
            scene = read_scene(scene_file)
            assert scene.gloves["left"].port == str(left.path) and scene.gloves["right"].port == str(right.path)
            with create_device(scene.gloves["right"]) as glove:
                deadline = time.monotonic() + 5
                while glove.latest() is None and time.monotonic() < deadline:
                    time.sleep(0.01)
                assert glove.latest().side == "right"
    finally:
        os.close(silent_master)
        os.close(silent_slave)
    assert find_serial_ports(tmp_path / "nothing-here").reason == f"nothing under {tmp_path / 'nothing-here'}"
    assert find_serial_ports(by_id, listen_s=0).found[0].detail == "not listened to"


def test_video_nodes_are_probed_silently_and_report_what_they_negotiate(tmp_path, capfd):
    dev, by_id = tmp_path / "dev", tmp_path / "by-id"
    dev.mkdir()
    by_id.mkdir()
    small = write_video(tmp_path / "small.mp4", fps=20, size=(48, 64))
    large = write_video(tmp_path / "large.mp4", fps=25, size=(120, 160))
    (dev / "video0").symlink_to(small)  # a "camera" node that is a real video file
    (dev / "video10").symlink_to(large)
    (dev / "video2").write_bytes(b"not a video")
    (dev / "videox").touch()
    (by_id / "usb-Acme_Cam-video-index0").symlink_to(dev / "video0")
    assert video_devices(dev) == [str(dev / "video0"), str(dev / "video2"), str(dev / "video10")]
    found = find_opencv_cameras(dev=dev, by_id=by_id)
    assert [(c.source, c.device, c.format) for c in found.found] == [
        (str(by_id / "usb-Acme_Cam-video-index0"), str(dev / "video0"), CameraFormat(64, 48, 20.0)),
        (str(dev / "video10"), str(dev / "video10"), CameraFormat(160, 120, 25.0))]
    none = find_opencv_cameras([97, "/dev/video97"])
    assert none.found == () and none.reason == "none of 97, /dev/video97 opens as a camera (in use, or not a camera)"
    assert find_opencv_cameras(dev=tmp_path / "empty").reason == f"nothing under {tmp_path / 'empty'}/video*"
    assert capfd.readouterr() == ("", "")  # OpenCV's probe warnings stay quiet

    findings = Findings(found, Discovery((FoundOak("18443010D1A2B30F00", "1.2.3", "UNBOOTED"),)), Discovery(reason="-"),
                        Discovery(tuple(FoundTracker(f"LHR-{k}", k != 1) for k in range(4))))
    lines = report_lines(findings)
    assert lines[:3] == ["OpenCV cameras: 2 found",
                         f"  {by_id / 'usb-Acme_Cam-video-index0'} ({dev / 'video0'}): 64×48 at 20 fps",
                         f"  {dev / 'video10'}: 160×120 at 25 fps"]
    assert "  LHR-1 (not tracking)" in lines and "serial ports:   none found (-)" in lines
    scene_file = tmp_path / "scene.toml"
    scene_file.write_text(scene_snippet(findings))
    scene = read_scene(scene_file)
    assert scene.cameras["ego"].device_id == "18443010D1A2B30F00"
    assert (scene.cameras["wrist_left"].source, scene.cameras["wrist_left"].fps) == (str(by_id / "usb-Acme_Cam-video-index0"), 20)
    assert (scene.cameras["wrist_right"].width, scene.cameras["wrist_right"].height) == (160, 120)
    assert scene.trackers.roles == {"LHR-0": "chest", "LHR-1": "left_wrist", "LHR-2": "right_wrist"}
    assert '# "LHR-3" = "ROLE"' in scene_file.read_text()
    camera = create_device(scene.cameras["wrist_right"])
    with camera:  # what the snippet asks for is what the file gives: nothing to report
        assert camera.negotiated == CameraFormat(160, 120, 25.0) and "negotiated" not in camera.status()


@pytest.mark.parametrize("listen", ["0", "0.05"])
def test_the_command_in_process(listen, capsys):
    assert main(["devices", "--listen", listen]) == 0
    out = capsys.readouterr().out
    assert all(kind in out for kind in KINDS)
