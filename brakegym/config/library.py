"""Finding and reading config files: the search path, and validation with file-field-value errors.

Configs are YAML files in kind folders (``vehicles/emu_8axle.yaml``). They are looked up, first
match wins, in

1. the folders set with :func:`set_config_path` or :func:`config_path` (the command line's
   ``--config-path``),
2. the folders of the environment variable ``BRAKEGYM_CONFIG_PATH`` (separated like ``PATH``),
3. the configs shipped with brakegym (the repository's ``configs/``, inside the installed package
   as ``brakegym.configs``).

So a user's own vehicle, pad material or effect set is found by name beside the shipped ones, and a
user's file of the same name takes the place of a shipped one. Each folder holds kind folders
(``my_configs/vehicles/my_train.yaml``); a config's ``name`` must equal its file's stem.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from .schema import (
    ConfigError,
    DiscThermal,
    Dynamometer,
    DynoCampaign,
    EffectSet,
    FieldCampaign,
    FrictionMaterial,
    Line,
    Pneumatics,
    RailCondition,
    SafetyCase,
    ScatterSetup,
    Vehicle,
    WspValves,
)

CONFIG_PATH_ENV = "BRAKEGYM_CONFIG_PATH"

# Kinds with a schema here, loaded by :func:`load`. ``campaigns`` holds two schemas: a file with a
# ``rig`` is a dynamometer campaign.
KINDS: dict[str, type[BaseModel]] = {
    "materials": FrictionMaterial,
    "discs": DiscThermal,
    "pneumatics": Pneumatics,
    "rigs": Dynamometer,
    "vehicles": Vehicle,
    "setups": ScatterSetup,
    "campaigns": FieldCampaign,
    "effects": EffectSet,
    "safety_cases": SafetyCase,
    "rail_conditions": RailCondition,
    "lines": Line,
    "wsp_valves": WspValves,
}
# Kinds whose schema lives with the code that uses them (brakegym.envs, brakegym.agents,
# brakegym.identification, brakegym.recordings); found on the same search path with :func:`find`.
OTHER_KINDS = ("environments", "agents", "identification", "measurement_chains", "model_forms")
# How messages name one config of a kind.
_ONE_OF_KIND = {kind: kind[:-1] for kind in [*KINDS, "environments"]} | {
    "safety_cases": "safety case",
    "rail_conditions": "rail condition",
    "wsp_valves": "WSP valve set",
    "agents": "agent config",
    "identification": "identification config",
    "measurement_chains": "measurement chain",
    "model_forms": "model form",
}

#: The schema class a config is validated as; :func:`validate` and :func:`load_file` return an
#: instance of it.
Model = TypeVar("Model", bound=BaseModel)

_folders_set: tuple[Path, ...] = ()


def _checked_folders(folders: Iterable[str | Path], source: str) -> tuple[Path, ...]:
    checked = []
    for folder in folders:
        path = Path(folder).expanduser()
        if not path.is_dir():
            raise ConfigError(f"config folder {path} ({source}) does not exist")
        checked.append(path)
    return tuple(checked)


def set_config_path(folders: Sequence[str | Path], source: str = "set_config_path") -> None:
    """Search ``folders``, in order, before ``$BRAKEGYM_CONFIG_PATH`` and the shipped configs, for
    the rest of the process (or until set again; an empty sequence clears them). A folder that
    does not exist is refused, the message naming ``source`` (where the folders came from)."""
    global _folders_set
    _folders_set = _checked_folders(folders, source)


@contextmanager
def config_path(*folders: str | Path) -> Iterator[None]:
    """:func:`set_config_path` for the duration of a ``with`` block, then the folders set before."""
    global _folders_set
    before = _folders_set
    _folders_set = _checked_folders(folders, "config_path") + before
    try:
        yield
    finally:
        _folders_set = before


def shipped_configs() -> Traversable:
    """The configs shipped with brakegym (the ``brakegym.configs`` package's folder)."""
    return resources.files("brakegym.configs")


def search_path() -> list[Traversable]:
    """The folders searched for configs, in order (see the module documentation)."""
    from_environment = [part for part in os.environ.get(CONFIG_PATH_ENV, "").split(os.pathsep) if part]
    return [*_folders_set, *_checked_folders(from_environment, f"${CONFIG_PATH_ENV}"), shipped_configs()]


def _known_kind(kind: str) -> None:
    if kind not in KINDS and kind not in OTHER_KINDS:
        raise ConfigError(f"unknown config kind {kind!r}; kinds are {sorted([*KINDS, *OTHER_KINDS])}")


def available(kind: str) -> list[str]:
    """Names of the configs of one kind on the search path (e.g. ``available("vehicles")``)."""
    _known_kind(kind)
    names = set()
    for folder in search_path():
        kind_folder = folder.joinpath(kind)
        if kind_folder.is_dir():
            names.update(item.name[: -len(".yaml")] for item in kind_folder.iterdir() if item.name.endswith(".yaml"))
    return sorted(names)


def find(kind: str, name: str) -> Traversable:
    """The file of config ``name`` of ``kind``: the first ``<folder>/<kind>/<name>.yaml`` on the
    search path. Unknown names list the known ones."""
    _known_kind(kind)
    folders = search_path()
    for folder in folders:
        candidate = folder.joinpath(kind, f"{name}.yaml")
        if candidate.is_file():
            return candidate
    known = ", ".join(available(kind)) or "none"
    searched = ", ".join(str(folder) for folder in folders)
    raise ConfigError(f"unknown {_ONE_OF_KIND[kind]} {name!r}: no {kind}/{name}.yaml in {searched}; known: {known}")


def describe_validation_error(source: str | Traversable, error: ValidationError) -> str:
    """A pydantic error as brakegym reports bad configs: the source, then one line per problem
    with the field's dotted path and the offending value."""
    lines = [f"{source}: invalid {error.title} config"]
    for item in error.errors():
        field = ".".join(str(part) for part in item["loc"]) or "(top level)"
        value = item.get("input")
        if item["type"] == "missing":
            shown = "(missing)"
        elif isinstance(value, dict):
            shown = "{...}"
        else:
            shown = repr(value)
        lines.append(f"  field '{field}' = {shown}: {item['msg']}")
    return "\n".join(lines)


def read_yaml(path: str | Path | Traversable) -> dict[str, Any]:
    """A YAML file's top-level mapping; errors name the file."""
    path = path if isinstance(path, Traversable) else Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc.strerror})") from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of fields, got {type(data).__name__}")
    return data


def validate(data: dict[str, Any], model: type[Model], source: str | Traversable) -> Model:
    """``data`` validated as ``model``; errors name ``source``, the field and the value."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(describe_validation_error(source, exc)) from None


def load_file(path: str | Path | Traversable, model: type[Model]) -> Model:
    """Parse and validate one YAML file as ``model``; errors name the file, field and value. A
    config with a ``name`` must be named like its file."""
    path = path if isinstance(path, Traversable) else Path(path)
    item = validate(read_yaml(path), model, path)
    stem = path.name.rsplit(".", 1)[0]
    name = getattr(item, "name", None)
    if name is not None and name != stem:
        raise ConfigError(f"{path}: field 'name' = {name!r} must equal the file's stem {stem!r}")
    return item


def load(kind: str, name: str) -> Any:
    """Load config ``name`` of ``kind`` from the search path, validated by its schema."""
    if kind not in KINDS:
        raise ConfigError(f"unknown config kind {kind!r} for load(); kinds are {sorted(KINDS)}")
    path = find(kind, name)
    model: type[BaseModel] = KINDS[kind]
    if kind == "campaigns" and "rig" in read_yaml(path):
        model = DynoCampaign
    return load_file(path, model)
