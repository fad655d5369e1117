"""The framing and the JSON spelling against docs/PROTOCOL.md's examples."""

import json
import socket
import threading

import pytest

from crazyflie_cosim import protocol as p


def test_the_advance_time_frame_is_the_documented_40_bytes():
    # PROTOCOL.md §2 (protocol/tests/golden.rs checks the same bytes).
    frame = p.encode_frame(p.advance_time(32))
    assert frame == bytes.fromhex("24000000") + b'{"command":"ADVANCE_TIME","time":32}'
    assert len(frame) == 40


# PROTOCOL.md §4 and §12: example bodies as our encoder writes them.
EXAMPLES = r"""
{"command":"GET_INIT_DATA","image_encoding":"base64"}
{"COORDINATE_X":-2.6,"COORDINATE_Y":0.0,"COORDINATE_Z":0.015,"TIME":2.0,"TIMESTEP":32,"command":"GET_INIT_DATA","image_encoding":"base64"}
{"ALTITUDE":0.25,"COORDINATE_X":-2.6,"COORDINATE_Y":1e-05,"COORDINATE_Z":0.25,"PITCH":2.5e-07,"PITCH_RATE":-0.0,"RANGE_BACK":0.5,"RANGE_FRONT":2000.0,"RANGE_LEFT":1234.5,"RANGE_RIGHT":2000.0,"ROLL":-0.001,"ROLL_RATE":0.0,"TIME":2.032,"YAW":1.5707963267948966,"YAW_RATE":12.5,"command":"GET_SENSORS"}
{"camera":{"data":[0,9,10,255],"height":2,"width":2},"command":"GET_IMAGE"}
{"camera":{"data":"AAkK/w==","encoding":"base64","height":2,"width":2},"command":"GET_IMAGE"}
{"command":"SET_VELOCITY","m1":48.5,"m2":50.0,"m3":47.25,"m4":0.1}
{"STOP_TIME":1024,"TIME":146.208,"command":"STOP"}
{"COLLISIONS":2,"COORDINATE_X":1.0,"COORDINATE_Y":2.0,"COORDINATE_Z":3.0,"OMEGA_X":0.01,"OMEGA_Y":0.02,"OMEGA_Z":0.03,"QW":1.0,"QX":0.0,"QY":0.0,"QZ":0.0,"TIME":3.0,"VELOCITY_X":0.1,"VELOCITY_Y":0.2,"VELOCITY_Z":0.3,"W1":-48.0,"W2":48.0,"W3":-48.0,"W4":48.0,"command":"GET_STATE"}
{"command":"ERROR","error":"unknown command \"FLY\""}
{"command":"RADIO_SEND","data":"cGluZw==","offset_ps":1234,"radio":"uwb"}
{"command":"RADIO_RECV","packets":[{"data":"cGluZw==","from":"A","radio":"uwb","rssi":-72.77940008672037,"rx_stamp":550213700365,"time_ps":2000172261733}],"tx_done":[]}
""".strip().splitlines()


@pytest.mark.parametrize("line", EXAMPLES)
def test_documented_bodies_are_spelled_byte_for_byte(line):
    assert p.dumps(json.loads(line)) == line


@pytest.mark.parametrize(
    "value, text",
    [(2.0, "2.0"), (0.015, "0.015"), (0.0001, "0.0001"), (1e-05, "1e-05"), (1e14, "100000000000000.0"),
     (1e15, "1e+15"), (-0.0, "-0.0"), (float("nan"), "null"), (float("inf"), "null"), (1.5e300, "1.5e+300"),
     (123.456, "123.456"), (5e-324, "5e-324")],
)  # fmt: skip
def test_doubles_are_laid_out_as_nlohmann_dump(value, text):
    assert p.dumps({"command": "X", "v": value}) == '{"command":"X","v":' + text + "}"


def test_requests_are_built_as_documented():
    assert p.dumps(p.radio_send("uwb", b"ping", 1234)) == EXAMPLES[9]
    assert p.dumps(p.get_init_data("base64")) == EXAMPLES[0]
    assert p.dumps(p.set_velocity(48.5, 50, 47.25, 0.1)) == EXAMPLES[5]
    with pytest.raises(ValueError, match="must be >= 0"):
        p.set_velocity(-1, 0, 0, 0)
    with pytest.raises(ValueError, match="finite"):
        p.set_velocity(float("nan"), 0, 0, 0)
    with pytest.raises(ValueError, match="1-127 bytes"):
        p.radio_send("uwb", b"")
    with pytest.raises(ValueError, match="non-negative integer"):
        p.advance_time(1.5)


def test_replies_parse_into_their_types():
    s = p.parse_reply(json.loads(EXAMPLES[2]))
    assert (s.time_s, s.y, s.range_left, s.yaw_rate) == (2.032, 1e-05, 1234.5, 12.5)
    a = p.parse_reply(json.loads(EXAMPLES[3]))
    b = p.parse_reply(json.loads(EXAMPLES[4]))
    assert a == b == p.Image(2, 2, bytes([0, 9, 10, 255]))
    st = p.parse_reply(json.loads(EXAMPLES[7]))
    assert (st.collisions, st.w1, st.qw) == (2, -48.0, 1.0)
    r = p.parse_reply(json.loads(EXAMPLES[10]))
    assert r.packets[0].data == b"ping" and r.packets[0].sender == "A" and r.tx_done == ()
    with pytest.raises(p.RemoteError, match='unknown command "FLY"'):
        p.parse_reply(json.loads(EXAMPLES[8]))
    # null is how NaN travels (§3).
    assert p.parse_reply({"command": "GET_DATA_2", "VELOCITY": None, "VELOCITY_X": 0, "VELOCITY_Y": 1}).velocity != 0
    with pytest.raises(p.ProtocolError, match="3 pixels for 2x2"):
        p.decode_image({"width": 2, "height": 2, "data": [1, 2, 3]})
    with pytest.raises(p.ProtocolError, match="not an integer 0-255"):
        p.decode_image({"width": 1, "height": 1, "data": [256]})


def _pair():
    a, b = socket.socketpair()
    return a, b


def test_frames_survive_one_byte_writes_and_a_clean_close():
    a, b = _pair()
    frame = p.encode_frame(p.get_state()) + p.encode_frame(p.stop())

    def trickle():
        for i in range(len(frame)):
            a.send(frame[i : i + 1])
        a.close()

    t = threading.Thread(target=trickle)
    t.start()
    assert p.loads(p.recv_frame(b)) == {"command": "GET_STATE"}
    assert p.loads(p.recv_frame(b)) == {"command": "STOP"}
    assert p.recv_frame(b) is None  # end of stream between frames
    t.join()
    b.close()


def test_truncated_and_oversized_frames_are_errors():
    a, b = _pair()
    a.sendall(b"\x10\x00\x00\x00{")
    a.close()
    with pytest.raises(p.Truncated, match="in the middle of a frame"):
        p.recv_frame(b)
    b.close()
    a, b = _pair()
    a.sendall(b"\xff\xff\xff\x7f")
    with pytest.raises(p.FrameTooLarge, match="exceeds the maximum frame size"):
        p.recv_frame(b)
    a.close()
    b.close()
    with pytest.raises(p.ProtocolError, match="no string"):
        p.loads(b'{"x":1}')
    with pytest.raises(p.ProtocolError, match="invalid JSON"):
        p.loads(b"{")


def test_endpoints_parse_as_documented():
    from crazyflie_cosim.client import Endpoint

    assert Endpoint.parse("unix:/tmp/w.sock") == Endpoint("unix", path="/tmp/w.sock")
    assert Endpoint.parse("/tmp/w.sock") == Endpoint("unix", path="/tmp/w.sock")
    assert Endpoint.parse("tcp:worldhost:7000") == Endpoint("tcp", host="worldhost", port=7000)
    assert Endpoint.parse("tcp:[::1]:7000") == Endpoint("tcp", host="::1", port=7000)
    assert str(Endpoint.parse("tcp:h:1")) == "tcp:h:1"
    for bad in ("tcp:host", "tcp::7000", "tcp:h:70000", "unix:"):
        with pytest.raises(ValueError, match="bad endpoint"):
            Endpoint.parse(bad)


def test_a_malformed_radio_recv_reply_is_a_protocol_error():
    ok = {"command": "RADIO_RECV", "packets": [], "tx_done": []}
    assert p.parse_reply(ok).packets == ()
    packet = {"radio": "uwb", "data": "AAE=", "from": "bravo", "rssi": -60.0, "time_ps": 5}
    assert p.parse_reply(dict(ok, packets=[packet])).packets[0].data == b"\x00\x01"
    for bad in ({"data": "not base64!"}, {"time_ps": "x"}, {"rssi": None}):
        with pytest.raises(p.ProtocolError, match="bad RADIO_RECV reply"):
            p.parse_reply(dict(ok, packets=[dict(packet, **bad)]))
    with pytest.raises(p.ProtocolError, match="bad RADIO_RECV reply"):
        p.parse_reply(dict(ok, packets=[{"radio": "uwb"}]))
