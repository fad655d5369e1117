"""crazyflie-cosim from Python: a client of world-server's wire protocol
(:mod:`.protocol`, :mod:`.client`), a launcher of world-server
(:mod:`.server`), readers of runs' outputs (:mod:`.outputs`), the STM32's
velocity controller (:mod:`.controller`) and a Gymnasium environment
(:mod:`.env`, registered as ``crazyflie_cosim/World-v0`` when Gymnasium is
installed)."""

from . import protocol
from .client import Drone, Endpoint, World
from .server import WorldServer, find_world_server

__version__ = "0.1.0"

ENV_ID = "crazyflie_cosim/World-v0"


def _register() -> None:
    try:
        import gymnasium
    except ImportError:
        return
    if ENV_ID not in gymnasium.registry:
        # The string entry point keeps `import crazyflie_cosim` free of the
        # environment's imports until gymnasium.make() needs it.
        gymnasium.register(id=ENV_ID, entry_point="crazyflie_cosim.env:WorldEnv")


_register()

__all__ = ["ENV_ID", "Drone", "Endpoint", "World", "WorldServer", "find_world_server", "protocol"]
