"""The client against real world-server processes."""

import hashlib

import pytest

from crazyflie_cosim import Drone, World, WorldServer
from crazyflie_cosim import protocol as p
from crazyflie_cosim.server import WorldServerError


def test_one_drone_hovers_climbs_and_stops_cleanly():
    with WorldServer("scenarios/worlds/empty.toml") as srv:
        with World.connect(srv.endpoint) as w:
            d = w["cf1"]
            assert (d.init.time_s, d.init.timestep_ms, d.clock_ms) == (2.0, 32, 2000)
            # 60 rad/s on every motor lifts the 50 g drone (4 * 4e-5 * 60^2 =
            # 0.58 N > 0.49 N) once the motors got there (30 rad/s per s).
            for _ in range(100):
                d.set_velocity(60, 60, 60, 60)
            s = d.state()
            assert s.time_s == pytest.approx(5.2) and d.clock_ms == 5200
            assert s.z > 0.1 and s.vz > 0
            assert (s.w1, s.w2) == (-60.0, 60.0)  # the spin signs of PROTOCOL.md §6.3
            # Pipelined requests are answered in order (§5.2).
            d.send(p.get_sensors())
            d.send(p.get_data_2())
            assert isinstance(d.receive(), p.Sensors) and isinstance(d.receive(), p.Data2)
            img = d.image()
            assert (img.width, img.height, len(img.pixels)) == (320, 320, 320 * 320)
            stop = d.stop()
            assert stop.time_s > s.time_s and stop.stop_time_ms > 0
        assert srv.wait(10) == 0


def test_the_three_image_encodings_give_the_same_pixels():
    digests = set()
    for encoding in ("array", "base64", "shm"):
        with WorldServer() as srv, World.connect(srv.endpoint, image_encoding=encoding) as w:
            assert w["cf1"].init.image_encoding == encoding
            img = w["cf1"].image()
            w.stop()
        assert (img.width, img.height) == (320, 320) and len(set(img.pixels)) > 2  # gates, ground, sky
        digests.add(hashlib.sha256(img.pixels).hexdigest())
    assert len(digests) == 1  # the start view of the course, whatever the encoding


def test_a_bad_request_is_a_one_line_error_and_the_world_exits_non_zero():
    with WorldServer() as srv:
        d = Drone.connect(srv.endpoint)
        d.claim()
        d.advance_time(16)  # not a multiple of the 32 ms timestep
        with pytest.raises(p.RemoteError, match="not a multiple of the 32 ms timestep") as e:
            d.state()
        assert "\n" not in e.value.reason
        d.close()
        assert srv.wait(10) != 0


def test_a_missing_binary_or_world_is_reported():
    with pytest.raises(WorldServerError, match="does not exist"):
        WorldServer("no/such/world.toml")


def test_a_bad_world_server_path_is_reported(monkeypatch):
    monkeypatch.setenv("COSIM_WORLD_SERVER", "/nonexistent/world-server")
    with pytest.raises(WorldServerError, match="not an executable"):
        WorldServer()


def test_a_world_that_fails_to_start_says_why(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[start]\nposition = [0.0, 0.0]\n")
    with pytest.raises(WorldServerError, match="exited before listening"):
        WorldServer(bad)


def _drive_three(world_file, trace):
    """One thread, three drones: claims, a climb, radio rounds, lockstep."""
    with WorldServer(world_file, trace=trace) as srv:
        # A deadlock fails the test after 20 s instead of hanging it.
        with World.connect(srv.endpoint, ["alpha", "bravo", "charlie"], reply_timeout=20) as w:
            assert [d.init.drone for d in w] == ["alpha", "bravo", "charlie"]
            received = {n: [] for n in w.names}
            for step in range(20):
                reqs = {n: [p.set_velocity(55, 55, 55, 55)] for n in w.names}
                if step == 5:
                    reqs["alpha"].insert(0, p.radio_send("uwb", b"ping", 1234))
                for n in w.names:
                    reqs[n] += [p.get_state(), p.radio_recv()]
                replies = w.request(reqs)
                for n, (state, radio) in replies.items():
                    assert state.time_s == pytest.approx(2.0 + 0.032 * (step + 1))
                    received[n] += [(pk.sender, pk.data) for pk in radio.packets]
            distances = w["alpha"].state().drone_distances
            stops = w.stop()
        assert srv.wait(10) == 0
    assert received["bravo"] == received["charlie"] == [("alpha", b"ping")]
    assert received["alpha"] == []
    assert distances == pytest.approx({"bravo": 2.0, "charlie": 4.0}, abs=0.05)
    return stops


def test_one_thread_drives_three_drones_twice_with_identical_traces(three_drone_world, tmp_path):
    results = [_drive_three(three_drone_world, tmp_path / f"world{k}.trace") for k in range(2)]
    assert results[0] == results[1]
    assert (tmp_path / "world0.trace").read_bytes() == (tmp_path / "world1.trace").read_bytes()


def test_advance_time_and_the_radio_of_a_single_drone_world():
    # A single-drone world has the channel too; its frames reach nobody but
    # their end is reported in tx_done (PROTOCOL.md §12.3).
    with WorldServer("scenarios/worlds/empty.toml") as srv, World.connect(srv.endpoint) as w:
        d = w["cf1"]
        d.radio_send("uwb", b"ping", offset_ps=1234)
        d.advance_time(320)
        assert d.clock_ms == 2320
        r = d.radio_recv()
        assert r.packets == () and len(r.tx_done) == 1
        # It left at 2000 ms + 1234 ps and was on the air for its airtime.
        assert r.tx_done[0].radio == "uwb" and 2_000_000_001_234 < r.tx_done[0].time_ps < 2_001_000_000_000
        assert d.sensors().time_s == pytest.approx(2.32)
        w.stop()
