"""The environments, one module each: a :class:`~brakegym.envs.task.BrakeTask` subclass with its
config model. Adding an environment is adding a module here and its default config
``configs/environments/<name>.yaml``; :mod:`brakegym.envs.registry` finds and registers it."""
