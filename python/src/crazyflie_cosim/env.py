"""A Gymnasium environment over world-server: ``crazyflie_cosim/World-v0``
(DESIGN.md §15).

Each episode starts its own world-server on a private socket with a copy of
the world file whose drones start where the episode's seed puts them
(uniformly within ``start_jitter_m`` of the file's start, yaw within
``start_jitter_yaw``), so the same seed gives the same episode bit for bit
and another seed another one.  One environment step is ``steps_per_action``
basicTimeSteps; each is one ``SET_VELOCITY`` per drone and one ``GET_STATE``
per drone, sent to every drone before any reply is read (one thread drives
every drone, DESIGN.md §15's lockstep).

Spaces (per drone):

- observation ``state``: float64[12] = position (m, world ENU), velocity
  (m/s, world), roll, pitch, yaw (rad, the InertialUnit's Z-Y-X angles),
  body angular rates (rad/s); with ``image=True`` a dict ``{"state",
  "image"}``, the image uint8[320, 320] (grey, row 0 at the top).  The
  bounds are finite (:func:`state_bounds`): the position within
  ``max_distance_m`` (plus the start jitter) of the world file's starts,
  the speed within ``MAX_OBS_SPEED``, the angles within ±π, the rates within
  the Crazyflie gyro's ±2000°/s; a state beyond them (the step that ends an
  episode by leaving, a crash) is clipped to them, as the gyro saturates.
- action ``"motors"``: float64[4] in [0, 1], the four motor speed magnitudes
  as fractions of 600 rad/s (``world-server/src/crazyflie.rs``:
  ``maxVelocity 600``); :func:`motor_action` converts from rad/s.
- action ``"velocity"``: float64[4] in [-1, 1], fractions of world-frame vx,
  vy (±1 m/s), vertical speed vz (±0.5 m/s), yaw rate (±72°/s, ``motion.rs``
  ``MAX_YAW_RATE``), flown by the STM32's controller ported in
  :mod:`.controller`; :func:`velocity_action` converts from m/s and rad/s.

Both action spaces are normalized, as RL libraries want them (Gymnasium's
``check_env``, Stable-Baselines3).

Several drones: observation and action are ``Dict`` spaces keyed by drone
name (world-file order); the reward is the sum over the drones (each
drone's in ``info["rewards"]``) and the episode ends for all at once.

Reward: pluggable (``reward=`` a :class:`Reward`); by default
:class:`GateProgress`.  Termination: a collision with a gate or a box (the
world's ``COLLISIONS`` count rises), every gate passed by every drone, or a
drone farther than ``max_distance_m`` from its start; truncation at
``max_time_s`` of flight.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import ENV_ID
from . import protocol as p
from .client import World
from .controller import VelocityController, euler
from .server import WorldServer, default_world
from .worldfile import DroneStart, WorldFile

#: ``world-server/src/crazyflie.rs`` ``MAX_MOTOR_SPEED`` (the PROTO's
#: ``RotationalMotor { maxVelocity 600 }``), rad/s.
MAX_MOTOR_SPEED = 600.0
#: ``sim-core/src/peripherals/stm32/motion.rs`` ``MAX_YAW_RATE`` (72°/s).
MAX_YAW_RATE = 72.0 * math.pi / 180.0
#: Velocity-mode limits: twice the race's 0.5 m/s per axis (``motion.rs``
#: ``RACE_AXIS_SPEED``) horizontally; the race's 0.2 m/s climb rate
#: (Listing 4.3) times 2.5 vertically.
MAX_HORIZONTAL_SPEED = 1.0
MAX_VERTICAL_SPEED = 0.5
#: What a velocity action of 1 means per component: vx, vy, vz (m/s), yaw rate (rad/s).
VELOCITY_SCALE = np.array([MAX_HORIZONTAL_SPEED, MAX_HORIZONTAL_SPEED, MAX_VERTICAL_SPEED, MAX_YAW_RATE])
#: The observed speed's bound per axis (m/s): far above the drone's (the
#: velocity mode's 1 m/s; a free fall over the episode's distance limit).
MAX_OBS_SPEED = 50.0
#: The observed body rates' bound: the Crazyflie gyro's range (BMI088,
#: ±2000°/s), rad/s.
MAX_OBS_RATE = 2000.0 * math.pi / 180.0
#: The AI deck camera (PROTOCOL.md §5).
IMAGE_SIZE = 320
STATE_SIZE = 12


def motor_action(speeds) -> np.ndarray:
    """A ``"motors"`` action from four motor speeds in rad/s."""
    return np.asarray(speeds, dtype=np.float64).reshape(4) / MAX_MOTOR_SPEED


def velocity_action(vx: float, vy: float, vz: float, yaw_rate: float = 0.0) -> np.ndarray:
    """A ``"velocity"`` action from a world-frame velocity demand (m/s) and a
    yaw rate (rad/s)."""
    return np.array([vx, vy, vz, yaw_rate], dtype=np.float64) / VELOCITY_SCALE


def state_bounds(starts, max_distance_m: float, jitter_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The ``state`` observation's low and high: positions within
    ``max_distance_m + jitter_m`` of every start (an episode ends once a
    drone is farther than ``max_distance_m`` from its jittered start)."""
    reach = max_distance_m + jitter_m
    pos = np.array([d.position for d in starts], dtype=np.float64)
    high = np.concatenate(
        [pos.max(axis=0) + reach, np.full(3, MAX_OBS_SPEED), np.full(3, math.pi), np.full(3, MAX_OBS_RATE)]
    )
    low = np.concatenate(
        [pos.min(axis=0) - reach, np.full(3, -MAX_OBS_SPEED), np.full(3, -math.pi), np.full(3, -MAX_OBS_RATE)]
    )
    return low, high


@dataclass
class DroneStatus:
    """What the environment tracks of one drone during an episode."""

    name: str
    start: tuple[float, float, float]
    state: p.State
    position: tuple[float, float, float]
    next_gate: int = 0
    gates_passed: int = 0
    collisions_at_start: int = 0
    collided: bool = False
    controller: VelocityController | None = field(default=None, repr=False)

    @property
    def collisions(self) -> int:
        return self.state.collisions - self.collisions_at_start


class Reward:
    """A reward: called once per basicTimeStep and drone; returns a float."""

    def reset(self, env: WorldEnv) -> None:
        """A new episode began (``env.status`` holds the starts)."""

    def __call__(self, env: WorldEnv, before: DroneStatus, after: DroneStatus, passed_gate: bool) -> float:
        raise NotImplementedError


class GateProgress(Reward):
    """Progress through the gates in file order: the decrease of the distance
    to the next gate's centre (m), ``gate_bonus`` for passing it,
    ``-collision_penalty`` for a collision.  In a world without gates, the
    decrease of the distance to ``target`` (default: 1 m above the start)."""

    def __init__(self, gate_bonus: float = 10.0, collision_penalty: float = 10.0, target=None):
        self.gate_bonus = gate_bonus
        self.collision_penalty = collision_penalty
        self.target = target

    def _goal(self, env: WorldEnv, s: DroneStatus, gate: int) -> tuple[float, float, float]:
        if env.gates:
            return env.gates[min(gate, len(env.gates) - 1)].centre
        if self.target is not None:
            return tuple(self.target)
        return (s.start[0], s.start[1], s.start[2] + 1.0)

    def __call__(self, env: WorldEnv, before: DroneStatus, after: DroneStatus, passed_gate: bool) -> float:
        goal = self._goal(env, before, before.next_gate)
        r = math.dist(before.position, goal) - math.dist(after.position, goal)
        if passed_gate:
            r += self.gate_bonus
        if after.collided and not before.collided:
            r -= self.collision_penalty
        return r


class WorldEnv(gym.Env):
    """See the module's documentation."""

    # "rgb_array": the first drone's camera (grey in three channels); the
    # frame rate is that of a 32 ms world step.
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 31.25}

    def __init__(
        self,
        world: str | None = None,
        drones: int | list[str] | None = None,
        seed: int | None = None,
        action: str = "motors",
        image: bool = False,
        reward: Reward | None = None,
        max_time_s: float = 30.0,
        steps_per_action: int = 1,
        timestep_ms: int = 32,
        start_jitter_m: float = 0.1,
        start_jitter_yaw: float = 0.1,
        max_distance_m: float = 50.0,
        image_encoding: str = "shm",
        world_server: str | None = None,
        render_mode: str | None = None,
        reply_timeout_s: float | None = 60.0,
    ):
        if action not in ("motors", "velocity"):
            raise ValueError(f'action must be "motors" or "velocity", not {action!r}')
        if steps_per_action < 1:
            raise ValueError("steps_per_action must be >= 1")
        self.world_path = Path(world) if world is not None else default_world()
        self.world_file = WorldFile.load(self.world_path)
        self.starts = self._drones(self.world_file, drones)
        self.names = [d.name for d in self.starts]
        self.gates = self.world_file.gates
        self.action_mode = action
        self.image = image
        self.reward_fn = reward if reward is not None else GateProgress()
        self.max_time_s = max_time_s
        self.steps_per_action = steps_per_action
        self.timestep_ms = timestep_ms
        self.start_jitter_m = start_jitter_m
        self.start_jitter_yaw = start_jitter_yaw
        self.max_distance_m = max_distance_m
        self.image_encoding = image_encoding if image else None
        self.world_server = world_server
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f'render_mode must be None or "rgb_array", not {render_mode!r}')
        self.render_mode = render_mode
        # A world that does not answer within this (wall time) failed: an
        # error instead of a hang (a world step takes microseconds).
        self.reply_timeout_s = reply_timeout_s
        self._seed = seed
        self._dir = Path(tempfile.mkdtemp(prefix="cosim-env-"))
        self._server: WorldServer | None = None
        self._world: World | None = None
        self.status: dict[str, DroneStatus] = {}
        self.episode_time_s = 0.0
        self._images: dict[str, np.ndarray] = {}
        self._images_fresh = False
        #: After an episode's world stopped: its STOP replies' GATES_PASSED.
        self.world_gates_passed: dict[str, int | None] = {}

        self._state_low, self._state_high = state_bounds(self.starts, max_distance_m, start_jitter_m)
        one_obs = self._drone_obs_space()
        low = 0.0 if action == "motors" else -1.0
        if len(self.names) == 1:
            self.observation_space = one_obs
            self.action_space = spaces.Box(low, 1.0, (4,), np.float64)
        else:
            self.observation_space = spaces.Dict({n: self._drone_obs_space() for n in self.names})
            self.action_space = spaces.Dict({n: spaces.Box(low, 1.0, (4,), np.float64) for n in self.names})
        # Made directly (not by gymnasium.make): the spec of the same
        # environment, so that tools that remake it (check_env's render
        # modes) get this one.
        if self.spec is None and ENV_ID in gym.registry:
            self.spec = replace(
                gym.spec(ENV_ID),
                kwargs={
                    "world": str(self.world_path), "drones": drones, "seed": seed, "action": action,
                    "image": image, "reward": reward, "max_time_s": max_time_s,
                    "steps_per_action": steps_per_action, "timestep_ms": timestep_ms,
                    "start_jitter_m": start_jitter_m, "start_jitter_yaw": start_jitter_yaw,
                    "max_distance_m": max_distance_m, "image_encoding": image_encoding,
                    "world_server": world_server, "render_mode": render_mode,
                    "reply_timeout_s": reply_timeout_s,
                },
            )  # fmt: skip

    # -- set-up ----------------------------------------------------------------

    @staticmethod
    def _drones(wf: WorldFile, drones: int | list[str] | None) -> list[DroneStart]:
        """The drones to fly: every drone of the world file (the lockstep
        waits for all of them), or ``drones`` copies of the single start set
        side by side 0.5 m apart across the start heading."""
        existing = wf.drones
        if drones is None:
            return existing
        if isinstance(drones, int):
            if wf.multi:
                if drones != len(existing):
                    raise ValueError(f"the world file has {len(existing)} drones, not {drones}")
                return existing
            if drones < 1:
                raise ValueError("drones must be >= 1")
            if drones == 1:
                return existing
            s = existing[0]
            across = (-math.sin(s.yaw), math.cos(s.yaw))
            out = []
            for i in range(drones):
                k = 0.5 * (i - (drones - 1) / 2)
                pos = (s.position[0] + k * across[0], s.position[1] + k * across[1], s.position[2])
                out.append(DroneStart(f"cf{i + 1}", pos, s.yaw))
            return out
        names = list(drones)
        if sorted(names) != sorted(d.name for d in existing):
            raise ValueError(
                f"drones {names}: every drone of the world file must be flown ({[d.name for d in existing]})"
            )
        return existing

    def _drone_obs_space(self) -> spaces.Space:
        state = spaces.Box(self._state_low, self._state_high, (STATE_SIZE,), np.float64)
        if not self.image:
            return state
        img = spaces.Box(0, 255, (IMAGE_SIZE, IMAGE_SIZE), np.uint8)
        return spaces.Dict({"state": state, "image": img})

    def _episode_world(self) -> Path:
        """The world file of this episode: the starts moved by the seed."""
        carried = {t["name"] for t in self.world_file.data.get("drone", []) if "carried" in t}
        moved = []
        for d in self.starts:
            if d.name in carried:
                moved.append(d)
                continue
            dx, dy = self.np_random.uniform(-self.start_jitter_m, self.start_jitter_m, 2)
            dyaw = self.np_random.uniform(-self.start_jitter_yaw, self.start_jitter_yaw)
            moved.append(
                DroneStart(
                    d.name, (d.position[0] + float(dx), d.position[1] + float(dy), d.position[2]), d.yaw + float(dyaw)
                )
            )
        self.episode_starts = moved
        return self.world_file.with_drones(moved).write(self._dir / "world.toml")

    # -- the Gymnasium API -------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is None and self._seed is not None:
            seed, self._seed = self._seed, None
        super().reset(seed=seed)
        self._shutdown()
        world_file = self._episode_world()
        self._server = WorldServer(world_file, timestep_ms=self.timestep_ms, binary=self.world_server)
        multi = len(self.names) > 1
        try:
            self._world = World.connect(
                self._server.endpoint,
                self.names if multi else None,
                image_encoding=self.image_encoding,
                reply_timeout=self.reply_timeout_s,
            )
        except (OSError, p.ProtocolError) as e:
            self._fail(e)
        states = self._exchange(None, self.image)
        self.status = {}
        for name in self.names:
            st = states[name]
            s = DroneStatus(name, self._pos(st), st, self._pos(st), collisions_at_start=st.collisions)
            if self.action_mode == "velocity":
                s.controller = VelocityController(self.timestep_ms, st.time_s, st.x, st.y, st.z)
            self.status[name] = s
        self.reward_fn.reset(self)
        self.episode_time_s = 0.0
        return self._observation(), self._info()

    def step(self, action):
        if self._world is None:
            raise RuntimeError("step() before reset()")
        actions = self._actions(action)
        rewards = {n: 0.0 for n in self.names}
        terminated = False
        self._images_fresh = False
        for i in range(self.steps_per_action):
            motors = {n: self._motors(n, actions[n]) for n in self.names}
            # The image of the step's last state travels with it.
            states = self._exchange(motors, self.image and i == self.steps_per_action - 1)
            self.episode_time_s += self.timestep_ms / 1000.0
            for n in self.names:
                before = self.status[n]
                after, passed = self._advance(before, states[n])
                rewards[n] += float(self.reward_fn(self, before, after, passed))
                self.status[n] = after
            terminated = self._terminated()
            if terminated:
                break
        truncated = not terminated and self.episode_time_s >= self.max_time_s - 1e-9
        obs = self._observation()
        info = self._info()
        info["rewards"] = rewards
        return obs, float(sum(rewards.values())), terminated, truncated, info

    def render(self):
        """The first drone's camera image as an RGB array (``render_mode
        "rgb_array"``); ``None`` otherwise."""
        if self.render_mode != "rgb_array":
            return None
        if self._world is None:
            raise RuntimeError("render() before reset()")
        try:
            img = self._world.drones[self._world.names[0]].image()
        except (OSError, p.ProtocolError) as e:
            self._fail(e)
        grey = np.frombuffer(img.pixels, np.uint8).reshape(img.height, img.width)
        return np.repeat(grey[:, :, None], 3, axis=2)

    def close(self):
        self._shutdown()
        shutil.rmtree(self._dir, ignore_errors=True)
        super().close()

    # -- the pieces -----------------------------------------------------------------

    @staticmethod
    def _pos(st: p.State) -> tuple[float, float, float]:
        return (st.x, st.y, st.z)

    def _actions(self, action) -> dict[str, np.ndarray]:
        if len(self.names) == 1:
            action = {self.names[0]: action}
        out = {}
        for n in self.names:
            a = np.asarray(action[n], dtype=np.float64).reshape(4)
            if not np.all(np.isfinite(a)):
                raise ValueError(f"action of drone {n} is not finite: {a}")
            box = self.action_space[n] if isinstance(self.action_space, spaces.Dict) else self.action_space
            a = np.clip(a, box.low, box.high)
            # Physical units from here on.
            out[n] = a * MAX_MOTOR_SPEED if self.action_mode == "motors" else a * VELOCITY_SCALE
        return out

    def _motors(self, name: str, a: np.ndarray) -> tuple[float, float, float, float]:
        if self.action_mode == "motors":
            return tuple(min(float(x), MAX_MOTOR_SPEED) for x in a)
        s = self.status[name]
        st = s.state
        roll, pitch, yaw = euler(st.qw, st.qx, st.qy, st.qz)
        m = s.controller.step(
            time_s=st.time_s, x=st.x, y=st.y, z=st.z, roll=roll, pitch=pitch, yaw=yaw,
            # The gyro's z is the body angular rate about z (world-server sensors).
            yaw_rate=st.omega_z,
            vx=float(a[0]), vy=float(a[1]), vz=float(a[2]), desired_yaw_rate=float(a[3]),
        )  # fmt: skip
        # The world refuses negative speeds (PROTOCOL.md §4: magnitudes) and
        # clamps at 600; the Rust STM32 sends what the PID gives, which stays
        # positive near hover; clip as the motor would.
        return tuple(min(max(x, 0.0), MAX_MOTOR_SPEED) for x in m)

    def _advance(self, before: DroneStatus, st: p.State) -> tuple[DroneStatus, bool]:
        pos = self._pos(st)
        passed = False
        next_gate, gates_passed = before.next_gate, before.gates_passed
        if next_gate < len(self.gates) and self.gates[next_gate].crossed(before.position, pos):
            passed = True
            next_gate += 1
            gates_passed += 1
        after = DroneStatus(
            before.name, before.start, st, pos, next_gate, gates_passed, before.collisions_at_start,
            before.collided or st.collisions > before.state.collisions, before.controller,
        )  # fmt: skip
        return after, passed

    def _terminated(self) -> bool:
        for s in self.status.values():
            if s.collided or math.dist(s.position, s.start) > self.max_distance_m:
                return True
        return bool(self.gates) and all(s.next_gate >= len(self.gates) for s in self.status.values())

    def _drone_obs(self, name: str):
        st = self.status[name].state
        roll, pitch, yaw = euler(st.qw, st.qx, st.qy, st.qz)
        state = np.array(
            [st.x, st.y, st.z, st.vx, st.vy, st.vz, roll, pitch, yaw, st.omega_x, st.omega_y, st.omega_z],
            dtype=np.float64,
        )
        # Within the space (the module's documentation): only a state past
        # the episode's end or a crash is changed.
        np.clip(state, self._state_low, self._state_high, out=state)
        if not self.image:
            return state
        return {"state": state, "image": self._images[name]}

    def _exchange(self, motors: dict[str, tuple] | None, with_image: bool) -> dict[str, p.State]:
        """One round trip for every drone, in one write each: SET_VELOCITY
        (unless ``motors`` is None), GET_STATE and, ``with_image``,
        GET_IMAGE.  Returns the states by drone name; keeps the images."""
        keys = dict(zip(self.names, self._world.names))
        requests = {}
        for n in self.names:
            reqs = [p.set_velocity(*motors[n])] if motors is not None else []
            reqs.append(p.get_state())
            if with_image:
                reqs.append(p.get_image())
            requests[keys[n]] = reqs
        try:
            replies = self._world.request(requests)
        except (OSError, p.ProtocolError) as e:
            self._fail(e)
        replies = {n: r if isinstance(r, list) else [r] for n, r in ((n, replies[keys[n]]) for n in self.names)}
        if with_image:
            self._images = {
                n: np.frombuffer(r[1].pixels, np.uint8).reshape(r[1].height, r[1].width).copy()
                for n, r in replies.items()
            }
            self._images_fresh = True
        return {n: r[0] for n, r in replies.items()}

    def _observation(self):
        if self.image and not self._images_fresh:  # an episode that ended mid-step
            keys = dict(zip(self.names, self._world.names))
            try:
                imgs = self._world.request({keys[n]: p.get_image() for n in self.names})
            except (OSError, p.ProtocolError) as e:
                self._fail(e)
            self._images = {
                n: np.frombuffer(imgs[keys[n]].pixels, np.uint8)
                .reshape(imgs[keys[n]].height, imgs[keys[n]].width)
                .copy()
                for n in self.names
            }
            self._images_fresh = True
        if len(self.names) == 1:
            return self._drone_obs(self.names[0])
        return {n: self._drone_obs(n) for n in self.names}

    def _info(self) -> dict[str, Any]:
        return {
            "time_s": next(iter(self.status.values())).state.time_s,
            "gates_passed": {n: s.gates_passed for n, s in self.status.items()},
            "collisions": {n: s.collisions for n, s in self.status.items()},
        }

    def _fail(self, e: Exception):
        """A world that failed: its last words in the error, no process left."""
        if isinstance(e, TimeoutError):
            e = TimeoutError(f"no reply within {self.reply_timeout_s} s (reply_timeout_s)")
        log = self._server.log.strip().splitlines()[-1:] if self._server else []
        self._shutdown(clean=False)
        raise RuntimeError(f"world-server failed: {e}" + (f" ({log[0]})" if log else "")) from e

    def _shutdown(self, clean: bool = True) -> None:
        """End the episode's world: STOP every drone (the world exits 0
        after the last reply), or kill it if that fails."""
        if self._world is not None:
            try:
                if clean:
                    keys = dict(zip(self._world.names, self.names))
                    stops = self._world.stop()
                    # The world's own count (any order; DESIGN.md §10), for
                    # comparison with the in-order count of info["gates_passed"].
                    self.world_gates_passed = {keys[k]: r.gates_passed for k, r in stops.items()}
            except (OSError, p.ProtocolError):
                clean = False
            self._world.close()
            self._world = None
        if self._server is not None:
            if clean:
                self._server.stop(timeout_s=5.0)
            else:
                self._server.kill()
            self._server = None
