"""The configs that ship with brakegym: YAML files in one folder per kind (see
:mod:`brakegym.config`). In the repository this is the top-level ``configs/`` folder; installed, it
is the package ``brakegym.configs``, read with :mod:`importlib.resources`."""
