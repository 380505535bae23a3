"""Rokoko Studio hand mocap: datagram decoding (v2/v3, LZ4/plain), the UDP receiver on a real loopback
socket, and the simulated sender end to end."""
from __future__ import annotations

import json
import os
import socket
import threading
import time
from pathlib import Path

import lz4.frame
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from devices.episode_loader import open_episode
from devices.episode_writer import EpisodeFrame, RawEpisodeWriter
from devices.errors import UserError
from devices.rokoko_protocol import (HAND_JOINT_NAMES, LZ4_MAGIC, MAX_JSON_BYTES, RokokoProtocolError,
                                     decode_datagram, encode_datagram)
from devices.rokoko_udp import RokokoConfig, RokokoReceiver
from devices.sim.hand_model import hand_state
from devices.sim.rokoko_sender import RokokoSenderConfig, SimulatedRokokoSender, episode_hands_provider
from devices.sim.shapes import pose_at
from devices.sim.task_scripts import PALM_DOWN, REST_FLEX, SIDES

BODY_JOINTS = (
    "hip", "spine", "chest", "neck", "head",
    "leftShoulder", "leftUpperArm", "leftLowerArm", "rightShoulder", "rightUpperArm", "rightLowerArm",
    "leftUpLeg", "leftLeg", "leftFoot", "leftToe", "leftToeEnd",
    "rightUpLeg", "rightLeg", "rightFoot", "rightToe", "rightToeEnd",
)
FACE_SHAPES = 52
GLOVE_AT_REST = (np.zeros((2, 256), np.uint8), np.ones(2, bool), np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)))
"""A glove sample (raw, present, quaternions); an episode folder needs a glove or a head video to be found."""
DEADLINE_S = 10.0


def studio_hands() -> np.ndarray:
    """(2, 21, 3) float64 hands of the simulator's kinematic model in Studio coordinates (Y up, Z forward)."""
    hands = [hand_state(side, pose_at(np.array([0.18 * (2 * h - 1), 0.25, 1.05]), PALM_DOWN), REST_FLEX)
             for h, side in enumerate(SIDES)]
    return np.stack([hand.joints[:, [0, 2, 1]] for hand in hands])


def joint_entry(position, rng: np.random.Generator) -> dict:
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    return {"position": dict(zip("xyz", map(float, position))), "rotation": dict(zip("xyzw", map(float, quat)))}


def studio_actor(hands: np.ndarray, present=(True, True), name: str = "Actor1", seed: int = 0,
                 body: bool = True) -> tuple[dict, dict]:
    """A full-body actor as Studio sends it: (actor entry, joint dict)."""
    rng = np.random.default_rng(seed)
    joints = {name_: joint_entry(rng.uniform(-0.5, 1.7, 3), rng) for name_ in BODY_JOINTS} if body else {}
    for h in range(2):
        if present[h]:
            joints.update({n: joint_entry(p, rng) for n, p in zip(HAND_JOINT_NAMES[h], hands[h])})
    meta = {"hasGloves": any(present), "hasLeftGlove": present[0], "hasRightGlove": present[1],
            "hasBody": body, "hasFace": True}
    face = {"faceId": f"{name}_face", **{f"shape{i}": float(rng.uniform(0, 100)) for i in range(FACE_SHAPES)}}
    actor = {"name": name, "color": [255, 120, 0], "meta": meta,
             "dimensions": {"totalHeight": 1.8, "hipHeight": 0.95}, "body": joints, "face": face}
    return actor, joints


def v3_message(actors: list[dict], version: object = "3,0") -> dict:
    prop = {"name": "Stick", "color": [0, 0, 255], "type": 2,
            "position": {"x": 0.1, "y": 1.2, "z": 0.3}, "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
    return {"version": version, "fps": 60.0, "scene": {"timestamp": 12.3456, "actors": actors, "props": [prop]}}


def pack(message: dict, compress: bool = True) -> bytes:
    text = json.dumps(message).encode()
    return lz4.frame.compress(text) if compress else text


def wait_for(predicate, timeout: float = DEADLINE_S) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


# ---- decoding -------------------------------------------------------------------------------------------

def test_full_body_v3_lz4_datagram_decodes_both_hands_in_official_order():
    hands = studio_hands()
    actor, _ = studio_actor(hands)
    datagram = pack(v3_message([actor]))
    assert datagram.startswith(LZ4_MAGIC) and len(datagram) > 3000
    frame = decode_datagram(datagram)
    assert frame.joints.dtype == np.float32 and frame.joints.shape == (2, 21, 3)
    np.testing.assert_array_equal(frame.joints, hands.astype(np.float32))
    assert frame.hands_present.tolist() == [True, True]
    assert (frame.timestamp, frame.fps, frame.actor) == (12.3456, 60.0, "Actor1")
    assert not frame.joints.flags.writeable
    # wrist, then thumb tip at index 4 and pinky (Little) tip at index 20, as in the official order
    left = actor["body"]
    assert frame.joints[0, 4, 1] == np.float32(left["leftThumbTip"]["position"]["y"])
    assert frame.joints[0, 20, 2] == np.float32(left["leftLittleTip"]["position"]["z"])


@pytest.mark.parametrize("version", ["3,0", "3.0", "3", 3, 3.0])
def test_v3_version_spellings(version):
    actor, _ = studio_actor(studio_hands())
    assert decode_datagram(pack(v3_message([actor], version))).hands_present.all()


@pytest.mark.parametrize("version", ["2,0", 2, "3,0"])
def test_v2_layout_joints_on_the_actor(version):
    """v2: joints directly on the actor, top-level timestamp; Studio 1's "JSON v2.5" says version 3."""
    hands = studio_hands()
    _, joints = studio_actor(hands, present=(False, True))
    message = {"version": version, "timestamp": 7.5, "props": [], "faces": [],
               "trackers": [{"name": "T1", "position": {"x": 0, "y": 1, "z": 0}}],
               "actors": [{"id": "suit1", "profileName": "Default", **joints}]}
    frame = decode_datagram(pack(message, compress=False))
    assert frame.hands_present.tolist() == [False, True]
    np.testing.assert_array_equal(frame.joints[1], hands[1].astype(np.float32))
    assert (frame.timestamp, frame.fps, frame.actor) == (7.5, None, "suit1")


def test_plain_json_datagram():
    hands = studio_hands()
    actor, _ = studio_actor(hands)
    frame = decode_datagram(pack(v3_message([actor]), compress=False))
    np.testing.assert_array_equal(frame.joints, hands.astype(np.float32))


def test_missing_glove_leaves_that_hand_absent_with_zeros():
    hands = studio_hands()
    actor, _ = studio_actor(hands, present=(True, False))
    frame = decode_datagram(pack(v3_message([actor])))
    assert frame.hands_present.tolist() == [True, False]
    assert not frame.joints[1].any()
    np.testing.assert_array_equal(frame.joints[0], hands[0].astype(np.float32))


@pytest.mark.parametrize("spoil", ["nan", "inf_float32", "missing_joint", "missing_axis", "null_position"])
def test_incomplete_or_non_finite_hand_is_absent(spoil):
    actor, joints = studio_actor(studio_hands())
    position = joints["rightIndexMedial"]["position"]
    if spoil == "nan":
        position["y"] = float("nan")
    elif spoil == "inf_float32":
        position["y"] = 1e39
    elif spoil == "missing_joint":
        del joints["rightIndexMedial"]
    elif spoil == "missing_axis":
        del position["z"]
    else:
        joints["rightIndexMedial"]["position"] = None
    frame = decode_datagram(pack(v3_message([actor])))
    assert frame.hands_present.tolist() == [True, False]


def test_first_actor_with_a_hand_is_chosen_unless_named():
    hands = studio_hands()
    body_only, _ = studio_actor(hands, present=(False, False), name="Suit")
    gloved, _ = studio_actor(hands, name="Gloves", seed=1)
    message = v3_message([body_only, gloved])
    assert decode_datagram(pack(message)).actor == "Gloves"
    named = decode_datagram(pack(message), actor="Suit")
    assert named.actor == "Suit" and not named.hands_present.any()
    with pytest.raises(RokokoProtocolError, match="no actor named 'Nobody'"):
        decode_datagram(pack(message), actor="Nobody")
    no_hands = decode_datagram(pack(v3_message([body_only])))
    assert no_hands.actor == "Suit" and not no_hands.hands_present.any()


def spoiled(path: str, value: object) -> bytes:
    message = v3_message([studio_actor(studio_hands())[0]])
    target = message
    keys = path.split(".")
    for key in keys[:-1]:
        target = target[int(key)] if isinstance(target, list) else target[key]
    target[keys[-1]] = value
    return pack(message)


@pytest.mark.parametrize("data, reason", [
    (LZ4_MAGIC + b"\x00" * 30, "bad LZ4 frame"),
    (lz4.frame.compress(b"{}" * 500)[:-30], "truncated LZ4 frame"),
    (lz4.frame.compress(b" " * (MAX_JSON_BYTES + 10)), "LZ4 payload too large"),
    (b"\xff\xfe{}", "not UTF-8 text"),
    (lz4.frame.compress("{\"version\": 3, \"x\": \"\xff\"}".encode("latin-1")), "not UTF-8 text"),
    (b"{\"version\": 3,", "invalid JSON"),
    (b"", "invalid JSON"),
    (b"[" * 200_000, "invalid JSON"),
    (b"[1, 2]", "not a JSON object"),
    (b"{\"scene\": {\"actors\": []}}", "missing or unreadable version"),
    (b"{\"version\": \"three\"}", "unreadable version"),
    (b"{\"version\": 1, \"actors\": []}", "JSON v1 is not supported"),
    (b"{\"version\": 3, \"scene\": []}", "'scene' is not an object"),
    (b"{\"version\": 3, \"scene\": {\"actors\": []}}", "no actors"),
    (b"{\"version\": 3, \"scene\": {}}", "no actors"),
    (b"{\"version\": 2, \"actors\": \"me\"}", "no actors"),
    (b"{\"version\": 3, \"scene\": {\"actors\": [7]}}", "an actor is not an object"),
    (b"{\"version\": 3, \"scene\": {\"actors\": [{\"body\": [1]}]}}", "'body' is not an object"),
])
def test_malformed_datagrams_raise_a_short_reason(data, reason):
    with pytest.raises(RokokoProtocolError, match=reason):
        decode_datagram(data)


@pytest.mark.parametrize("path, value, reason", [
    ("scene.actors.0.body.leftHand", "here", "joint leftHand is not an object"),
    ("scene.actors.0.body.leftHand", {"position": [0, 1, 2]}, "position is not an object"),
    ("scene.actors.0.body.rightRingTip", {"position": {"x": "0.1", "y": 0, "z": 0}}, "non-numeric coordinate"),
    ("scene.actors.0.body.rightRingTip", {"position": {"x": True, "y": 0, "z": 0}}, "non-numeric coordinate"),
])
def test_wrong_types_inside_an_actor_are_malformed(path, value, reason):
    with pytest.raises(RokokoProtocolError, match=reason):
        decode_datagram(spoiled(path, value))


def test_huge_numbers_do_not_crash():
    message = {"version": 10**400, "scene": {"timestamp": 10**400, "actors": [{}]}}
    with pytest.raises(RokokoProtocolError, match="version"):
        decode_datagram(json.dumps(message).encode())
    message["version"] = 3
    frame = decode_datagram(json.dumps(message).encode())
    assert frame.timestamp is None and not frame.hands_present.any()


def test_encode_rejects_bad_input():
    joints, present = np.zeros((2, 21, 3)), np.ones(2, bool)
    with pytest.raises(ValueError, match="expected"):
        encode_datagram(joints[:, :20], present)
    with pytest.raises(ValueError, match="version"):
        encode_datagram(joints, present, version=4)
    joints[0, 3, 1] = np.nan
    with pytest.raises(ValueError):
        encode_datagram(joints, present)
    assert not decode_datagram(encode_datagram(joints, [False, True])).hands_present[0]


datagram_bytes = st.one_of(
    st.binary(max_size=2000),
    st.binary(max_size=400).map(lambda b: LZ4_MAGIC + b),
    st.binary(max_size=2000).map(lz4.frame.compress),
    st.tuples(st.binary(min_size=1, max_size=600), st.integers(0, 599), st.integers(0, 255)).map(
        lambda t: (lambda c: c[:t[1] % len(c)] + bytes([t[2]]) + c[t[1] % len(c) + 1:])(lz4.frame.compress(t[0]))),
)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(datagram_bytes)
def test_arbitrary_bytes_raise_only_the_protocol_error(data):
    try:
        frame = decode_datagram(data)
    except RokokoProtocolError as exc:
        assert exc.reason
    else:
        assert frame.joints.shape == (2, 21, 3)


json_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), st.text(max_size=5),
                         st.floats(allow_nan=True, allow_infinity=True))
json_keys = st.sampled_from(["x", "y", "z", "position", "body"])
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=3), st.dictionaries(json_keys, inner, max_size=3)), max_leaves=8)
joint_values = st.one_of(json_values, st.fixed_dictionaries({"position": st.one_of(
    json_values, st.fixed_dictionaries({a: json_values for a in "xyz"}))}))
v3_bodies = st.dictionaries(st.sampled_from(HAND_JOINT_NAMES[1][:3]), joint_values, max_size=3)
actor_values = st.one_of(json_values, st.dictionaries(
    st.sampled_from(["name", "body", *HAND_JOINT_NAMES[0][:3]]), st.one_of(joint_values, v3_bodies), max_size=4))
message_values = st.fixed_dictionaries({
    "version": st.one_of(json_values, st.sampled_from(["3,0", "2.0", 3, 2])),
    "fps": json_values, "timestamp": json_values,
    "scene": st.one_of(json_values, st.fixed_dictionaries({"timestamp": json_values,
                                                          "actors": st.lists(actor_values, max_size=3)})),
    "actors": st.lists(actor_values, max_size=3)})


@settings(max_examples=300, deadline=None)
@given(message_values, st.booleans())
def test_structured_garbage_raises_only_the_protocol_error(message, compress):
    try:
        frame = decode_datagram(pack(message, compress))
    except RokokoProtocolError as exc:
        assert exc.reason
    else:
        assert frame.joints.dtype == np.float32 and frame.hands_present.dtype == bool


@settings(max_examples=60, deadline=None)
@given(arrays(np.float32, (2, 21, 3), elements=st.floats(allow_nan=False, allow_infinity=False, width=32)),
       arrays(bool, (2,)), st.sampled_from([2, 3]), st.booleans(), st.floats(0, 1e6))
def test_encode_decode_round_trip_is_exact(joints, present, version, compress, timestamp):
    frame = decode_datagram(encode_datagram(joints, present, version=version, compress=compress,
                                            timestamp=timestamp, actor="A"))
    assert frame.hands_present.tolist() == present.tolist()
    expected = np.where(present[:, None, None], joints, 0)
    np.testing.assert_array_equal(frame.joints, expected)
    assert frame.timestamp == timestamp and frame.actor == "A"
    assert frame.fps == (30 if version == 3 else None)


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
        assert (counters.decoded, counters.malformed, counters.oversized, counters.no_hand) == (4, 4, 2, 0)
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
        with pytest.raises(RuntimeError, match="already connected"):
            receiver.connect()
        started = time.monotonic()
        receiver.disconnect()
        assert time.monotonic() - started < 2.0
    receiver.disconnect()
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
    (RokokoConfig(port=70000), "port 70000 is out of range"),
    (RokokoConfig(port=0, max_datagram_bytes=0), "max datagram size 0"),
    (RokokoConfig(port=0, poll_s=0), "poll time must be positive"),
])
def test_bad_options_are_user_errors(config, message):
    with pytest.raises(UserError, match=message):
        RokokoReceiver(config).connect()


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
    assert counters.decoded == sender.frames_sent and counters.malformed == counters.oversized == 0
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
        assert wait_for(lambda: receiver.counters.decoded == sender.frames_sent)
    assert asked[asked.index(stalled[0]) + 1] >= stalled[0] + 8
    assert sender.frames_skipped == asked[-1] + 1 - sender.frames_sent
