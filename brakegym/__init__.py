"""brakegym: railway friction brakes after Ehret, Hohmann & Heckmann (2022).

Dynamic, stochastic coefficient of friction per disc, two-capacity disc temperatures, the
dynamometer rig and a 16-disc multiple-unit train, integrated in batches; Gymnasium environments
of the braking train (``brakegym/StationStop-v0``, ``brakegym/DecelTracking-v0``,
``brakegym/EmergencyStop-v0``), registered on import.
"""

__version__ = "0.1.0"

# Gymnasium 1.x no longer registers through entry points; registering here makes both
# ``import brakegym; gymnasium.make("brakegym/...")`` and
# ``gymnasium.make("brakegym:brakegym/...")`` work. Entry points are strings so that importing
# brakegym does not import the environments.
ENVIRONMENT_IDS = {
    "brakegym/StationStop-v0": "StationStop",
    "brakegym/DecelTracking-v0": "DecelTracking",
    "brakegym/EmergencyStop-v0": "EmergencyStop",
}


def _register_environments() -> None:
    import gymnasium

    for env_id, stem in ENVIRONMENT_IDS.items():
        if env_id not in gymnasium.registry:  # idempotent: re-imports and reloads change nothing
            gymnasium.register(
                id=env_id,
                entry_point=f"brakegym.envs:{stem}Env",
                vector_entry_point=f"brakegym.envs:{stem}VectorEnv",
            )


_register_environments()
