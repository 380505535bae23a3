"""The simulated live rig: a recorded (simulated) episode replayed through the real device protocols, so
`touchanything live --scene scenes/sim.toml` runs the whole live path with no hardware.

- Gloves: one pseudo-terminal per hand streaming the JQ byte protocol at 100 Hz per packet type, behind a
  stable symlink in `link_dir` (like /dev/serial/by-id), read by the real JQ glove adapter.
- Hand mocap: Rokoko Studio-style LZ4 JSON v3 datagrams at 30 fps to a UDP port on loopback, read by the
  real Rokoko receiver.
- Cameras: the episode's video files, which the scene's OpenCV camera sources play paced at 30 fps.
- Trackers: the episode's recorded Vive poses served at 30 fps (OpenVR needs a running SteamVR, which no
  byte stream can stand in for), in the shape the OpenVR adapter produces.
Every stream loops over the episode, all from the same start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.core.snapshot import HANDS, TRACKER_ROLES
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.hardware.openvr_trackers import TrackerReading
from touchanything.devices.hardware.threaded_source import ThreadedSource, now_us
from touchanything.devices.sim.glove_serial import SimulatedGloveSerial, episode_glove_provider
from touchanything.devices.sim.rokoko_sender import RokokoSenderConfig, SimulatedRokokoSender, episode_hands_provider


@dataclass(frozen=True)
class SimulatedRigConfig:
    """episode: a raw episode folder or .hdf5 with glove, Rokoko and tracker streams; link_dir: where
    the gloves' serial links appear (created if missing); where the Rokoko datagrams go."""

    episode: Path
    link_dir: Path = Path("/tmp/touchanything-sim")
    rokoko_host: str = "127.0.0.1"
    rokoko_port: int = 14043

    def glove_port(self, hand: str) -> Path:
        return self.link_dir / f"usb-Juqiao_JQ_glove_{hand}-if00"


class EpisodeTrackers(ThreadedSource[TrackerReading]):
    """The episode's tracker poses as a live source (the ThreadedSource contract): at every frame period
    it publishes the pose of the frame due then, stamped with that frame's due time, looping."""

    def __init__(self, episode: Episode) -> None:
        if episode.trackers is None or episode.num_frames == 0:
            raise UserError(f"{episode.path}: the episode has no tracker stream to simulate")
        super().__init__("recorded trackers")
        self.episode = episode
        self._period_us = 1e6 / episode.fps
        self._start_us = 0
        self._next_tick = 0

    def _open(self) -> None:
        self._start_us, self._next_tick = now_us(), 0

    def _step(self) -> None:
        """Wait for the next frame's due time; publish the frame due now (skipping any that went by)."""
        due_us = self._start_us + round(self._next_tick * self._period_us)
        if self._stop.wait(max(due_us - now_us(), 0) / 1e6):
            return
        tick = max(self._next_tick, math.floor((now_us() - self._start_us) / self._period_us))
        frame = tick % self.episode.num_frames
        trackers = self.episode.trackers
        poses = {role: trackers.poses[frame, r].copy() for r, role in enumerate(TRACKER_ROLES) if trackers.valid[frame, r]}
        t_us = self._start_us + round(tick * self._period_us)
        self._publish(TrackerReading(poses, t_us), t_us)
        self._next_tick = tick + 1

    def _close(self) -> None:
        """Nothing to release: the episode belongs to the simulated rig."""


class SimulatedLiveRig:
    """`start()` opens the episode and starts every simulated stream; `stop()` ends them."""

    def __init__(self, config: SimulatedRigConfig) -> None:
        self.config = config
        self.episode: Episode | None = None
        self.trackers: EpisodeTrackers | None = None
        self._gloves: list[SimulatedGloveSerial] = []
        self._sender: SimulatedRokokoSender | None = None

    def start(self) -> None:
        try:
            self.episode = open_episode(self.config.episode)
            self.config.link_dir.mkdir(parents=True, exist_ok=True)
            for hand in HANDS:
                port = self.config.glove_port(hand)
                self._gloves.append(SimulatedGloveSerial(hand, episode_glove_provider(self.episode, hand),
                                                         port.parent, port.name))
            self._sender = SimulatedRokokoSender(episode_hands_provider(self.episode), RokokoSenderConfig(
                self.config.rokoko_host, self.config.rokoko_port, fps=self.episode.fps))
            self._sender.start()
            self.trackers = EpisodeTrackers(self.episode)
        except OSError as exc:
            self.stop()
            raise UserError(f"simulated rig: {exc}") from None
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        if self._sender is not None:
            self._sender.stop()
            self._sender = None
        while self._gloves:
            self._gloves.pop().close()
        if self.episode is not None:
            self.episode.close()
            self.episode = None
