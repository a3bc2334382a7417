"""brakegym: railway friction brakes after Ehret, Hohmann & Heckmann (2022).

Dynamic, stochastic coefficient of friction per disc, two-capacity disc temperatures, the
dynamometer rig and a 16-disc multiple-unit train, integrated in batches; Gymnasium environments
of the braking train (``brakegym/StationStop-v0``, ``brakegym/DecelTracking-v0``,
``brakegym/EmergencyStop-v0``, one module each in :mod:`brakegym.envs.tasks`), registered on
import.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("brakegym")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"


def _register_environments() -> None:
    # Gymnasium 1.x no longer registers through entry points; registering here makes both
    # ``import brakegym; gymnasium.make("brakegym/...")`` and
    # ``gymnasium.make("brakegym:brakegym/...")`` work. The registry imports only the light task
    # modules, not the simulator.
    from .envs.registry import register_environments

    register_environments()


_register_environments()
