"""Seed 004's ground-station API (Rocha 2020, "cfist", §3.3 and chapter 4)
on Bitcraze's cflib: it flies the simulator over `udp://` and a real
Crazyflie over `radio://` alike (docs/LAB.md, DESIGN.md §17).

- :class:`KeyboardPilot` (manual piloting; keys from :class:`TerminalKeys`
  or :class:`ScriptedKeys`)
- :class:`Grid` (occupancy-grid mapping) and :class:`TruePlan` (the
  world's plan, to score a map)
- :class:`Autopilot` with ``run(measurements)``, :class:`Follower`,
  :class:`Explorer`
- :class:`Radar` (drone-to-drone detection on the P2P radio)
- :class:`DDS` (the Drone Delivery Service: airway, locations, deliveries)

The design rules of the seed: a pilot or an autopilot never sends a
command — it returns a :class:`Command` for the user to send
(``cf.commander.send_hover_setpoint(*command)``); the modules are context
managers that start and stop what they need (key listeners, log blocks,
the radar's beacon).
"""

from .autopilot import Autopilot, Explorer, Follower
from .command import Command
from .dds import DDS, HOME, Delivery, Status
from .grid import Grid
from .keys import Hold, KeySource, ScriptedKeys, TerminalKeys
from .pilot import KeyboardPilot
from .plan import TruePlan
from .radar import Radar
from .telemetry import Measurements, Pose, Telemetry

__all__ = [
    "Autopilot", "Command", "DDS", "Delivery", "Explorer", "Follower", "Grid", "HOME", "Hold",
    "KeySource", "KeyboardPilot", "Measurements", "Pose", "Radar", "ScriptedKeys", "Status",
    "Telemetry", "TerminalKeys", "TruePlan",
]
