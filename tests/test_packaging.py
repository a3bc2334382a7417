"""The wheel carries what the package needs at run time: every subpackage is listed in
pyproject.toml (setuptools is told them by name) and every shipped config matches a package-data
glob. A subpackage missing here installs as a wheel that fails on import."""

import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SETUPTOOLS = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]


def _source_folder(package: str) -> Path:
    """Where a package's files are in the repository, by the package-dir mapping."""
    parts = package.split(".")
    for length in range(len(parts), 0, -1):
        prefix = ".".join(parts[:length])
        if prefix in SETUPTOOLS["package-dir"]:
            return REPO / SETUPTOOLS["package-dir"][prefix] / Path(*parts[length:])
    return REPO / Path(*parts)


def test_every_subpackage_is_listed():
    listed = set(SETUPTOOLS["packages"])
    for package in listed:
        assert (_source_folder(package) / "__init__.py").is_file(), f"{package} listed but has no __init__.py"
    found = set()
    for package in [p for p in listed if p.count(".") <= 1]:
        root = _source_folder(package)
        for init in root.rglob("__init__.py"):
            relative = init.parent.relative_to(root)
            if "__pycache__" not in relative.parts:
                found.add(".".join([package, *relative.parts]) if relative.parts else package)
    missing = found - listed
    assert not missing, f"subpackages not in pyproject.toml [tool.setuptools] packages: {sorted(missing)}"


def test_every_shipped_config_is_package_data():
    configs = _source_folder("brakegym.configs")
    globs = SETUPTOOLS["package-data"]["brakegym.configs"]
    shipped = {p for p in configs.rglob("*.yaml")}
    carried = {p for pattern in globs for p in configs.glob(pattern)}
    assert shipped == carried, f"configs no glob carries: {sorted(str(p) for p in shipped - carried)}"
