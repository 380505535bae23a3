"""Rokoko Studio datagrams: decoding (v2/v3, LZ4/plain, version spellings, missing or broken hands, actor
choice), malformed input raising only the protocol error, and encode/decode round trips."""
from __future__ import annotations

import json

import lz4.frame
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from helpers.rokoko_messages import pack, studio_actor, studio_hands, v3_message
from touchanything.devices.hardware.rokoko_protocol import (
    HAND_JOINT_NAMES,
    LZ4_MAGIC,
    MAX_JSON_BYTES,
    RokokoProtocolError,
    decode_datagram,
    encode_datagram,
)


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
