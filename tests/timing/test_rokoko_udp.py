"""The Rokoko UDP receiver on a real loopback socket (bad datagrams dropped and counted, actor choice,
prompt disconnect, busy ports, bad options) and the simulated Studio sender end to end."""
from __future__ import annotations

import os
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from helpers.rokoko_messages import DEADLINE_S, GLOVE_AT_REST, pack, studio_actor, studio_hands, v3_message
from touchanything.core.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, UserError
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.hardware.rokoko_protocol import LZ4_MAGIC, encode_datagram
from touchanything.devices.hardware.rokoko_udp import RokokoConfig, RokokoReceiver
from touchanything.devices.sim.rokoko_sender import RokokoSenderConfig, SimulatedRokokoSender, episode_hands_provider


def wait_for(predicate, timeout: float = DEADLINE_S) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()



# ---- UDP receiver --------------------------------------------------------------------------------------

def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@pytest.fixture
def sender_socket():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield sock
    sock.close()


def test_receiver_drops_and_counts_bad_datagrams_while_good_ones_flow(sender_socket):
    hands = studio_hands()
    limit = 6000
    good = [encode_datagram(hands + k, [True, True], timestamp=k / 30) for k in range(3)]
    padded = encode_datagram(hands, [True, False], compress=False, timestamp=99.0)
    exactly_limit = padded + b" " * (limit - len(padded))
    bad = [LZ4_MAGIC + b"garbage", b"\xff\xfe\xfd", b"{\"version\": 3,", b"", os.urandom(limit + 1),
           b"x" * 65000]
    sequence = [good[0], bad[0], bad[1], good[1], bad[2], bad[3], bad[4], bad[5], exactly_limit, good[2]]
    with RokokoReceiver(RokokoConfig(host="127.0.0.1", port=0, max_datagram_bytes=limit)) as receiver:
        target = receiver.bound_address
        assert target[1] != 0 and receiver.latest() is None
        assert "no data yet" in receiver.status()
        for datagram in sequence:
            sender_socket.sendto(datagram, target)
            time.sleep(0.002)
        assert wait_for(lambda: receiver.counters.datagrams == len(sequence))
        counters = receiver.counters
        assert (counters.samples, counters.malformed, counters.oversized, counters.no_hand) == (4, 4, 2, 0)
        reading = receiver.latest()
        np.testing.assert_array_equal(reading.frame.joints, (hands + 2).astype(np.float32))
        assert reading.frame.timestamp == 2 / 30
        assert "6 dropped" in receiver.status() and receiver.status().startswith("connected")

        sender_socket.sendto(encode_datagram(hands, [False, False]), target)
        assert wait_for(lambda: receiver.counters.no_hand == 1)
        assert not receiver.latest().frame.hands_present.any()
        assert "hands none" in receiver.status()
    assert receiver.status() == "disconnected" and not receiver.is_connected


def test_receiver_follows_the_configured_actor(sender_socket):
    hands = studio_hands()
    first, _ = studio_actor(hands, name="A")
    second, _ = studio_actor(hands + 1, name="B", seed=3)
    with RokokoReceiver(RokokoConfig(port=0, actor="B")) as receiver:
        sender_socket.sendto(pack(v3_message([first, second])), receiver.bound_address)
        assert wait_for(lambda: receiver.latest() is not None)
        assert receiver.latest().frame.actor == "B"
        sender_socket.sendto(pack(v3_message([first])), receiver.bound_address)
        assert wait_for(lambda: receiver.counters.malformed == 1)
        assert "no actor named 'B'" in receiver.status()


def test_disconnect_is_prompt_and_leaks_nothing():
    threads, fds = threading.active_count(), open_fds()
    receiver = RokokoReceiver(RokokoConfig(port=0, poll_s=0.05))
    for _ in range(3):
        receiver.connect()
        assert receiver.is_connected
        with pytest.raises(DeviceAlreadyConnectedError, match="already connected"):
            receiver.connect()
        started = time.monotonic()
        receiver.disconnect()
        assert time.monotonic() - started < 2.0
    receiver.disconnect()
    with pytest.raises(DeviceNotConnectedError, match="not connected"):
        _ = receiver.bound_address
    assert threading.active_count() == threads and open_fds() == fds


def test_busy_port_is_a_user_error_and_cleans_up():
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    port = busy.getsockname()[1]
    try:
        threads, fds = threading.active_count(), open_fds()
        receiver = RokokoReceiver(RokokoConfig(host="127.0.0.1", port=port))
        with pytest.raises(UserError, match=f"127.0.0.1:{port}: Address already in use") as error:
            receiver.connect()
        assert "\n" not in str(error.value)
        assert not receiver.is_connected and threading.active_count() == threads and open_fds() == fds
    finally:
        busy.close()


@pytest.mark.parametrize("config, message", [
    (RokokoConfig(host="no-such-host.invalid", port=0), "no-such-host.invalid:0: unknown host"),
    (RokokoConfig(host="192.0.2.1", port=0), "192.0.2.1:0: Cannot assign requested address"),
])
def test_an_address_that_cannot_be_bound_is_a_user_error(config, message):
    with pytest.raises(UserError, match=message):
        RokokoReceiver(config).connect()


@pytest.mark.parametrize("settings, message", [
    ({"port": 70000}, "port 70000 is out of range"),
    ({"port": 0, "max_datagram_bytes": 0}, "max datagram size 0"),
    ({"port": 0, "poll_s": 0}, "poll time must be positive"),
])
def test_bad_options_are_user_errors_when_the_config_is_made(settings, message):
    with pytest.raises(UserError, match=message):
        RokokoConfig(**settings)


# ---- simulated sender ----------------------------------------------------------------------------------

def write_rokoko_episode(folder: Path, frames: int = 20) -> Path:
    """A recording-style episode folder with Rokoko hands (right hand missing every 4th frame) and gloves."""
    rng = np.random.default_rng(7)
    base = studio_hands().astype(np.float32)
    with RawEpisodeWriter(folder) as writer:
        for k in range(frames):
            joints = (base + rng.normal(0, 0.01, base.shape)).astype(np.float32)
            writer.write(EpisodeFrame(
                rokoko=(joints, np.array([True, k % 4 != 1])),
                glove=GLOVE_AT_REST))
    return folder


def test_sender_to_receiver_on_loopback_replays_the_episode_exactly(tmp_path):
    episode = open_episode(write_rokoko_episode(tmp_path / "Home" / "task" / "0001"))
    stored = episode.hands("rokoko")
    assert stored is not None and not stored.valid[:, 1].all()
    readings = {}
    with RokokoReceiver(RokokoConfig(port=0)) as receiver:
        host, port = receiver.bound_address
        sender = SimulatedRokokoSender(episode_hands_provider(episode), RokokoSenderConfig(host=host, port=port))
        with sender:
            started = time.monotonic()
            while time.monotonic() - started < 1.0:
                reading = receiver.latest()
                if reading is not None:
                    readings[reading.t_us] = reading
                time.sleep(0.003)
            elapsed = time.monotonic() - started
        assert wait_for(lambda: receiver.counters.datagrams == sender.frames_sent)
        counters = receiver.counters
    assert sender.send_errors == 0 and 15 <= sender.frames_sent <= 34
    assert abs(sender.frames_sent + sender.frames_skipped - 30 * elapsed) <= 4
    assert counters.samples == sender.frames_sent and counters.malformed == counters.oversized == 0
    ordered = [readings[t] for t in sorted(readings)]
    assert len(ordered) >= 10
    stamps = [r.frame.timestamp for r in ordered]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    for reading in ordered:
        index = round(reading.frame.timestamp * 30) % episode.num_frames
        np.testing.assert_array_equal(reading.frame.joints, stored.joints[index])
        assert reading.frame.hands_present.tolist() == stored.valid[index].tolist()
        assert reading.frame.fps == 30 and reading.frame.actor == "sim"
    assert 15 <= receiver.rate_hz() <= 60


def test_sender_rejects_bad_settings(tmp_path):
    with pytest.raises(UserError, match="positive number"):
        SimulatedRokokoSender(lambda k: (np.zeros((2, 21, 3)), np.zeros(2, bool)), RokokoSenderConfig(fps=0))
    sender = SimulatedRokokoSender(lambda k: (np.zeros((2, 21, 3)), np.zeros(2, bool)),
                                   RokokoSenderConfig(host="no-such-host.invalid"))
    with pytest.raises(UserError, match="unknown host"):
        sender.start()
    assert not sender.is_running
    folder = tmp_path / "Home" / "task" / "0002"
    with RawEpisodeWriter(folder) as writer:
        writer.write(EpisodeFrame(glove=GLOVE_AT_REST))
    with pytest.raises(UserError, match="no Rokoko hand stream"):
        episode_hands_provider(open_episode(folder))


def test_sender_skips_frames_after_a_stall_instead_of_bursting():
    hands, asked, stalled = studio_hands(), [], []

    def stalling(index: int) -> tuple[np.ndarray, np.ndarray]:
        """The first call from frame 3 on takes 0.3 s (9 frame periods)."""
        asked.append(index)
        if index >= 3 and not stalled:
            stalled.append(index)
            time.sleep(0.3)
        return hands, np.ones(2, bool)

    with RokokoReceiver(RokokoConfig(port=0)) as receiver:
        host, port = receiver.bound_address
        with SimulatedRokokoSender(stalling, RokokoSenderConfig(host=host, port=port)) as sender:
            assert wait_for(lambda: sender.frames_sent >= 12)
        assert wait_for(lambda: receiver.counters.samples == sender.frames_sent)
    assert asked[asked.index(stalled[0]) + 1] >= stalled[0] + 8
    assert sender.frames_skipped == asked[-1] + 1 - sender.frames_sent
