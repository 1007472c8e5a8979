"""The wire protocol: msgpack with raw numpy buffers, space descriptions, messages, error codes."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest
from gymnasium import spaces

from multion_client import errors
from multion_client.protocol import (
    API_VERSION,
    EXT_NDARRAY,
    CreateSession,
    Error,
    Observations,
    Reset,
    SessionInfo,
    Step,
    StepResult,
    decode,
    encode,
    encode_items,
    join_encoded,
    session_path,
    space_from_wire,
    space_to_wire,
)
from multion_client.wire import decode_keeping_encoded, decode_small_arrays, encode_with_encoded


def test_routes_are_versioned() -> None:
    assert API_VERSION == "v1"
    assert session_path("abc") == "/v1/sessions/abc"
    assert session_path("abc", "step") == "/v1/sessions/abc/step"


@pytest.mark.parametrize(
    "array",
    [
        np.arange(24, dtype=np.float32).reshape(2, 3, 4),
        np.random.default_rng(0).integers(0, 255, (8, 8, 3), dtype=np.uint8),
        np.array(7, dtype=np.int16),  # 0-d
        np.zeros((0, 3)),
        np.array([True, False]),
        np.arange(10, dtype=">i4"),  # big-endian stays big-endian
        np.arange(12).reshape(3, 4)[:, ::2],  # not contiguous
        np.array([1 + 2j], dtype=np.complex64),
    ],
)
def test_arrays_round_trip_exactly(array: np.ndarray) -> None:
    out = decode(encode({"x": array}))["x"]
    assert isinstance(out, np.ndarray)
    assert out.dtype == array.dtype and out.shape == array.shape
    assert out.tobytes() == np.ascontiguousarray(array).tobytes()
    assert out.flags.writeable


def test_numpy_scalars_stay_scalars() -> None:
    for value in (np.int64(3), np.float32(0.5), np.bool_(True), np.uint8(200)):
        out = decode(encode(value))
        assert type(out) is type(value) and out == value


def test_arrays_travel_as_raw_bytes_not_lists() -> None:
    image = np.zeros((64, 64, 3), np.uint8)
    data = encode(image)
    assert (
        len(data) < image.nbytes + 64
    )  # a list of ints would take at least one byte each + headers
    packed = msgpack.unpackb(data, ext_hook=lambda code, payload: (code, payload))
    assert packed[0] == EXT_NDARRAY and packed[1].endswith(image.tobytes())


def test_plain_values_and_nesting() -> None:
    obj = {"a": [1, 2.5, None, True, "s", b"raw"], "b": {"c": (1, 2)}, "arr": [np.ones(2)]}
    out = decode(encode(obj))
    assert out["a"] == [1, 2.5, None, True, "s", b"raw"]
    assert out["b"] == {"c": [1, 2]}  # tuples become lists
    assert out["arr"][0].tolist() == [1.0, 1.0]


def test_unencodable_values_are_refused() -> None:
    with pytest.raises(TypeError, match="dtype"):
        encode(np.array(["a", None], dtype=object))
    with pytest.raises(TypeError, match="set"):
        encode({1, 2})


@pytest.mark.parametrize(
    "data",
    [
        b"\xc1",  # never used byte
        b"\x92\x01",  # array of 2 with one item
        b"\x01\x02",  # extra data
        msgpack.packb(msgpack.ExtType(EXT_NDARRAY, b"\x03<f4\x01" + bytes([2]) + b"\x00" * 7)),
        msgpack.packb(msgpack.ExtType(EXT_NDARRAY, b"\x02")),  # truncated header
        msgpack.packb(msgpack.ExtType(EXT_NDARRAY, b"\x03|O8\x00" + b"\x00" * 8)),  # object dtype
    ],
)
def test_malformed_input_is_a_clear_error(data: bytes) -> None:
    with pytest.raises(errors.MalformedMessage):
        decode(data)


def test_join_encoded_matches_whole_encoding() -> None:
    a = [{"x": np.arange(3)}, {"x": np.arange(2)}]
    b = [{"x": np.arange(1)}]
    data = join_encoded([("obs", 3, [encode_items(a), encode_items(b)]), ("r", 0, [])])
    out = decode(data)
    assert [o["x"].tolist() for o in out["obs"]] == [[0, 1, 2], [0, 1], [0]]
    assert out["r"] == []


def test_an_observation_passed_on_encoded_decodes_as_the_original() -> None:
    observation = {"rgb": np.arange(12, dtype=np.uint8).reshape(2, 2, 3), "gps": np.ones(2)}
    reply = encode({"observations": [observation], "infos": [{"metrics": {"spl": 0.5}}]})
    decoded = decode_keeping_encoded(reply, "observations")
    assert decoded["infos"] == [{"metrics": {"spl": 0.5}}]  # the rest is decoded
    (kept,) = decoded["observations"]
    assert kept == encode(observation)  # the item's own encoding, as it was
    answer = decode(encode_with_encoded({"episode": 3, "observation": {}}, {"observation": kept}))
    assert answer["episode"] == 3
    np.testing.assert_array_equal(answer["observation"]["rgb"], observation["rgb"])
    with pytest.raises(errors.MalformedMessage):
        decode_keeping_encoded(reply[:-3], "observations")


def test_small_arrays_are_decoded_and_images_skipped() -> None:
    reply = encode({"gps": np.array([1.5, -2.0], np.float32), "rgb": np.zeros((64, 64, 3))})
    decoded = decode_small_arrays(reply, 256)
    assert decoded["rgb"] is None and decoded["gps"].tolist() == [1.5, -2.0]


def test_spaces_round_trip() -> None:
    space = spaces.Dict(
        {
            "rgb": spaces.Box(0, 255, (16, 16, 3), np.uint8),
            "gps": spaces.Box(-np.inf, np.inf, (2,), np.float32),
            "odd": spaces.Box(np.array([0.0, -1.0]), np.array([1.0, 2.0]), dtype=np.float64),
            "goal": spaces.Discrete(8),
            "shifted": spaces.Discrete(3, start=-1),
        }
    )
    back = space_from_wire(decode(encode(space_to_wire(space))))
    assert back == space
    assert list(back.spaces) == list(space.spaces)  # order kept
    # uniform bounds travel as scalars, so a big image space stays small on the wire
    assert len(encode(space_to_wire(spaces.Box(0, 255, (256, 256, 3), np.uint8)))) < 200


def test_unsupported_spaces() -> None:
    with pytest.raises(TypeError):
        space_to_wire(spaces.MultiBinary(3))
    with pytest.raises(errors.MalformedMessage):
        space_from_wire({"type": "Graph"})
    with pytest.raises(errors.MalformedMessage):
        space_from_wire({"type": "Discrete"})


def test_messages_round_trip() -> None:
    info = SessionInfo("s1", 2, True, spaces.Dict({"goal": spaces.Discrete(8)}), spaces.Discrete(4))
    messages = [
        CreateSession({"camera": {"width": 8}}, 2, True),
        info,
        Reset([1, None], [{"episode_index": 0}, None]),
        Step([0, 3]),
        Observations([{"goal": np.int64(1)}], [{"episode_id": "e"}]),
        StepResult([{}], [0.5], [False], [True], [{}]),
        Error("episode_over", "call reset"),
    ]
    for message in messages:
        back = type(message).from_wire(decode(encode(message.to_wire())))
        if isinstance(message, Observations):
            assert back.observations[0]["goal"] == 1 and back.infos == message.infos
        else:
            assert back == message


@pytest.mark.parametrize(
    ("cls", "data", "match"),
    [
        (CreateSession, {"num_envs": 0}, "num_envs"),
        (CreateSession, {"num_envs": True}, "num_envs"),
        (CreateSession, {"config": []}, "config"),
        (CreateSession, {"auto_reset": 1}, "auto_reset"),
        (CreateSession, {"confg": {}}, "unknown field"),
        (CreateSession, [1, 2], "expected a map"),
        (Reset, {"seeds": [1.5]}, "seeds"),
        (Reset, {"options": [3]}, "options"),
        (Step, {}, "missing"),
        (Step, {"actions": 1}, "list"),
        (StepResult, {"observations": [], "rewards": [1], "terminated": [], "truncated": [],
                      "infos": []}, "lengths"),
    ],
)  # fmt: skip
def test_messages_are_validated(cls: type, data: object, match: str) -> None:
    with pytest.raises(errors.MalformedMessage, match=match):
        cls.from_wire(data)  # type: ignore[attr-defined]


def test_error_codes_map_to_classes() -> None:
    for code, cls in errors.ERRORS.items():
        error = errors.error_from_code(code, "why")
        assert type(error) is cls and error.code == code and error.message == "why"
        assert code in str(error) and "why" in str(error)
    assert isinstance(errors.error_from_code("invalid_action", "x"), ValueError)
    assert isinstance(errors.error_from_code("episode_over", "x"), RuntimeError)
    assert isinstance(errors.SessionNotFound("x"), errors.MultiONError)
    # unknown codes fall back on the HTTP status, keeping the server's code
    fallback = errors.error_from_code("brand_new", "m", 429)
    assert isinstance(fallback, errors.LimitExceeded) and fallback.code == "brand_new"
    assert errors.WorkerFailed("x").to_wire() == {
        "error": {"code": "worker_failed", "message": "x"}
    }
