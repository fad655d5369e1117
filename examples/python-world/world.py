#!/usr/bin/env python3
"""A world server for crazyflie-cosim in plain Python (standard library only).

It speaks the wire protocol of docs/PROTOCOL.md (DESIGN.md section 2) on a UNIX
socket, so `sim-core` flies against it unchanged -- the proof that the world
side can be swapped. It is deliberately small and NOT our reference world:

* The drone is a rigid body reduced to what the platform's PID needs:
  thrust k*w^2 per propeller along body z, roll/pitch torques from the
  propeller arms, yaw torque from the reaction constants, attitude as Euler
  angles integrated from body rates (small-angle kinematics), gravity, and
  a flat ground at z = 0.  No gates, no collisions, no drag.  (A purely
  kinematic model -- velocities set directly -- cannot be driven by motor
  speeds, which is all the platform sends; the PID closes its loops on the
  attitude, so the attitude must respond to the motor differences.)
* Constants are the Bitcraze Webots Crazyflie's (DESIGN.md section 5).
* The camera shows a fixed horizon (sky above, ground below).
* Range sensors always read 2000 mm (nothing within 2 m).

Usage:  world.py --socket PATH [--timestep MS] [--start X,Y,Z] [--yaw RAD]
"""

import argparse
import base64
import json
import math
import os
import socket
import struct
import sys

# Crazyflie constants (DESIGN.md section 5).
MASS = 0.05                      # kg
G = 9.81                         # m/s^2
ARM = 0.031                      # m, propeller offset along x and y
K_THRUST = 4e-5                  # N/(rad/s)^2
K_TORQUE = 2.4e-6                # N*m/(rad/s)^2
MAX_SPEED = 600.0                # rad/s
MOTOR_ACCEL = 30.0               # rad/s per s (Webots's maxTorque as acceleration)
SPIN = (-1.0, 1.0, -1.0, 1.0)    # m1, m3 turn negative; m2, m4 positive
# Propellers m1..m4: front right, back right, back left, front left (body x, y).
PROPS = ((ARM, -ARM), (-ARM, -ARM), (-ARM, ARM), (ARM, ARM))
# Solid cylinder r = 0.05 m, h = 0.03 m.
IXX = MASS * (3 * 0.05 ** 2 + 0.03 ** 2) / 12
IZZ = MASS * 0.05 ** 2 / 2
REST_Z = 0.015                   # body origin when resting on the ground
SUBSTEP_MS = 1                   # integration step (the protocol's step is ts)
WIDTH = HEIGHT = 320


class Drone:
    def __init__(self, start, yaw):
        self.t_ms = 0
        self.p = list(start)
        self.v = [0.0, 0.0, 0.0]
        self.att = [0.0, 0.0, yaw]       # roll, pitch, yaw
        self.rates = [0.0, 0.0, 0.0]     # body angular velocity
        self.w = [0.0] * 4               # signed propeller speeds
        self.target = [0.0] * 4

    def rotation(self):
        """Body-to-world rotation matrix (Z-Y-X Euler angles)."""
        r, p, y = self.att
        cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p),
                                  math.sin(p), math.cos(y), math.sin(y))
        return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
                (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
                (-sp, cp * sr, cp * cr))

    def substep(self, h):
        # Motors: slew towards the target.
        for i in range(4):
            d = self.target[i] - self.w[i]
            lim = MOTOR_ACCEL * h
            self.w[i] += max(-lim, min(lim, d))
        thrust = [K_THRUST * w * w for w in self.w]
        total = sum(thrust)
        tx = sum(py * f for (px, py), f in zip(PROPS, thrust))
        ty = sum(-px * f for (px, py), f in zip(PROPS, thrust))
        tz = sum(-K_TORQUE * w * abs(w) for w in self.w)
        on_ground = self.p[2] <= REST_Z + 1e-9
        if on_ground and total < MASS * G:
            # Resting: the ground holds the drone level and still.
            self.v = [0.0, 0.0, 0.0]
            self.rates = [0.0, 0.0, 0.0]
            self.att[0] = self.att[1] = 0.0
            self.p[2] = REST_Z
            return
        # Semi-implicit Euler: rates and velocities first, then angles, position.
        self.rates[0] += tx / IXX * h
        self.rates[1] += ty / IXX * h
        self.rates[2] += tz / IZZ * h
        for i in range(3):
            self.att[i] += self.rates[i] * h
        rot = self.rotation()
        acc = [rot[i][2] * total / MASS for i in range(3)]
        acc[2] -= G
        for i in range(3):
            self.v[i] += acc[i] * h
            self.p[i] += self.v[i] * h
        if self.p[2] < REST_Z:
            self.p[2] = REST_Z
            self.v[2] = max(self.v[2], 0.0)

    def step(self, ms):
        for _ in range(ms // SUBSTEP_MS):
            self.substep(SUBSTEP_MS / 1000.0)
        self.t_ms += ms

    def quaternion(self):
        r, p, y = (a / 2 for a in self.att)
        cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p),
                                  math.sin(p), math.cos(y), math.sin(y))
        return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def horizon_image():
    """Sky (200) above the middle row, ground (115) below, as JSON text."""
    row_sky = ",".join(["200"] * WIDTH)
    row_ground = ",".join(["115"] * WIDTH)
    rows = [row_sky] * (HEIGHT // 2) + [row_ground] * (HEIGHT - HEIGHT // 2)
    pixels = bytes([200] * (WIDTH * (HEIGHT // 2)) +
                   [115] * (WIDTH * (HEIGHT - HEIGHT // 2)))
    return "[" + ",".join(rows) + "]", base64.b64encode(pixels).decode()


def dump(obj):
    """Compact JSON with sorted keys, as nlohmann's dump() writes it."""
    return json.dumps(obj, separators=(",", ":"), sort_keys=True)


class Server:
    def __init__(self, conn, drone, timestep):
        self.conn = conn
        self.drone = drone
        self.ts = timestep
        self.encoding = "array"
        self.image_array, self.image_b64 = horizon_image()

    def recv(self):
        head = self.read_exact(4)
        if head is None:
            return None
        (n,) = struct.unpack("<I", head)
        if n > 64 * 1024 * 1024:
            raise ValueError("frame of %d bytes refused" % n)
        body = self.read_exact(n)
        if body is None:
            raise ValueError("connection closed inside a frame")
        return json.loads(body.decode("utf-8"))

    def read_exact(self, n):
        buf = bytearray()
        while len(buf) < n:
            chunk = self.conn.recv(n - len(buf))
            if not chunk:
                return None
            buf += chunk
        return bytes(buf)

    def send(self, text):
        data = text.encode("utf-8")
        self.conn.sendall(struct.pack("<I", len(data)) + data)

    def error(self, msg):
        self.send(dump({"command": "ERROR", "error": msg}))

    def serve(self):
        """Serves until STOP (returns True) or a protocol error (False)."""
        d = self.drone
        while True:
            req = self.recv()
            if req is None:
                print("world.py: the platform left before STOP", file=sys.stderr)
                return False
            cmd = req.get("command")
            time_s = d.t_ms / 1000.0
            if cmd == "GET_INIT_DATA":
                self.encoding = req.get("image_encoding", "array")
                if self.encoding not in ("array", "base64"):
                    self.error("unknown image_encoding %r" % self.encoding)
                    continue
                self.send(dump({"command": cmd, "COORDINATE_X": d.p[0],
                                "COORDINATE_Y": d.p[1], "COORDINATE_Z": d.p[2],
                                "TIME": time_s, "TIMESTEP": self.ts,
                                "image_encoding": self.encoding}))
            elif cmd == "GET_SENSORS":
                r, p, y = d.att
                reply = {"command": cmd, "TIME": time_s, "COORDINATE_X": d.p[0],
                         "COORDINATE_Y": d.p[1], "COORDINATE_Z": d.p[2],
                         "ALTITUDE": d.p[2], "ROLL": r, "PITCH": p, "YAW": y,
                         "ROLL_RATE": d.rates[0], "PITCH_RATE": d.rates[1],
                         "YAW_RATE": d.rates[2]}
                for side in ("FRONT", "LEFT", "BACK", "RIGHT"):
                    reply["RANGE_" + side] = 2000.0
                self.send(dump(reply))
            elif cmd == "GET_IMAGE":
                if self.encoding == "base64":
                    data, extra = '"%s"' % self.image_b64, ',"encoding":"base64"'
                else:
                    data, extra = self.image_array, ""
                self.send('{"camera":{"data":%s%s,"height":%d,"width":%d},'
                          '"command":"GET_IMAGE"}' % (data, extra, HEIGHT, WIDTH))
            elif cmd == "SET_VELOCITY":
                try:
                    m = [float(req[k]) for k in ("m1", "m2", "m3", "m4")]
                except (KeyError, TypeError, ValueError):
                    self.error("SET_VELOCITY needs numbers m1..m4")
                    return False
                d.target = [s * max(-MAX_SPEED, min(MAX_SPEED, v))
                            for s, v in zip(SPIN, m)]
                d.step(self.ts)
            elif cmd == "ADVANCE_TIME":
                t = req.get("time")
                if not isinstance(t, int) or t < 0 or t % self.ts:
                    self.error("ADVANCE_TIME needs a multiple of %d ms" % self.ts)
                    return False
                d.step(t)
            elif cmd == "GET_DATA_2":
                self.send(dump({"command": cmd,
                                "VELOCITY": math.hypot(d.v[0], d.v[1]),
                                "VELOCITY_X": d.v[0], "VELOCITY_Y": d.v[1]}))
            elif cmd == "GET_DATA_3":
                self.send(dump({"command": cmd,
                                "VELOCITY": math.hypot(d.v[0], d.v[1]),
                                "VELOCITY_Z": d.v[2], "PITCH": d.att[1]}))
            elif cmd == "GET_STATE":
                qw, qx, qy, qz = d.quaternion()
                reply = {"command": cmd, "TIME": time_s, "COORDINATE_X": d.p[0],
                         "COORDINATE_Y": d.p[1], "COORDINATE_Z": d.p[2],
                         "QW": qw, "QX": qx, "QY": qy, "QZ": qz,
                         "VELOCITY_X": d.v[0], "VELOCITY_Y": d.v[1],
                         "VELOCITY_Z": d.v[2], "OMEGA_X": d.rates[0],
                         "OMEGA_Y": d.rates[1], "OMEGA_Z": d.rates[2],
                         "COLLISIONS": 0}
                for i in range(4):
                    reply["W%d" % (i + 1)] = d.w[i]
                self.send(dump(reply))
            elif cmd == "STOP":
                d.target = [0.0] * 4
                t0 = d.t_ms
                while any(w != 0.0 for w in d.w):
                    d.step(self.ts)
                self.send(dump({"command": cmd, "TIME": d.t_ms / 1000.0,
                                "STOP_TIME": d.t_ms - t0}))
                return True
            else:
                self.error("unknown command %r" % cmd)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--socket", default=os.environ.get("COSIM_SOCKET"))
    ap.add_argument("--timestep", type=int, default=32, help="basicTimeStep (ms)")
    ap.add_argument("--start", default="-2.6,0,0.015", help="X,Y,Z (m)")
    ap.add_argument("--yaw", type=float, default=math.pi / 2,
                    help="heading (rad); the thesis's drone faces +y")
    args = ap.parse_args()
    if not args.socket:
        ap.error("--socket PATH is required (or COSIM_SOCKET)")
    if args.timestep < 1:
        ap.error("--timestep must be at least 1 ms")
    try:
        start = [float(c) for c in args.start.split(",")]
        assert len(start) == 3
    except (ValueError, AssertionError):
        ap.error("--start must be X,Y,Z")
    drone = Drone(start, args.yaw)
    # Warm-up of the thesis's controller: motors at +-1 rad/s for 2000 ms.
    drone.target = [s * 1.0 for s in SPIN]
    drone.step(2000)

    # Socket file rules of docs/PROTOCOL.md: a stale socket is removed, a
    # live one is left alone, the new one is for its owner only.
    if os.path.exists(args.socket):
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            probe.connect(args.socket)
            print("world.py: socket %s is in use by a live server" % args.socket,
                  file=sys.stderr)
            return 2
        except OSError:
            os.unlink(args.socket)
        finally:
            probe.close()
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        listener.bind(args.socket)
    finally:
        os.umask(old)
    listener.listen(1)
    conn, _ = listener.accept()
    try:
        ok = Server(conn, drone, args.timestep).serve()
    except (ValueError, OSError) as e:
        print("world.py: %s" % e, file=sys.stderr)
        ok = False
    finally:
        conn.close()
        listener.close()
        if os.path.exists(args.socket):
            os.unlink(args.socket)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
