"""The documentation site builds in strict mode (every warning an error, every reference checked),
and its API reference documents the package's objects.

This is the build command of ``docs/conf.py``; the module takes about 25 s on a 2-core machine.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx")
pytest.importorskip("myst_parser")

DOCS = Path(__file__).resolve().parent.parent / "docs"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("docs") / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html", str(DOCS), str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, f"strict docs build failed:\n{result.stdout[-5000:]}\n{result.stderr[-10000:]}"
    return out


@pytest.mark.parametrize(
    ("page", "anchor"),
    [
        ("api/simulator.html", "brakegym.simulator.integrator.Simulator"),
        ("api/agents.html", "brakegym.agents.pid.PIDController"),
        ("api/envs.html", "brakegym.envs.env.BrakeEnv"),
        ("api/envs.html", "brakegym.envs.env.BrakeVectorEnv"),
        ("api/config.html", "brakegym.config.library.set_config_path"),
        ("api/package.html", "brakegym.plants.train_plant"),
        ("api/effects.html", "brakegym.effects.load_effects"),
    ],
)
def test_api_pages_document_the_objects(site: Path, page: str, anchor: str) -> None:
    assert f'id="{anchor}"' in (site / page).read_text(encoding="utf-8")


def test_pages_are_in_the_site(site: Path) -> None:
    for page in ("index", "installation", "configs", "simulation", "environments", "diagnosis", "tutorial", "physics"):
        assert (site / f"{page}.html").is_file(), page


def test_every_module_has_its_api_section():
    """A new module shows up in the API reference: each module of the package is an automodule of
    some page of docs/api."""
    import pkgutil

    import brakegym

    documented = "".join(page.read_text() for page in (DOCS / "api").glob("*.md"))
    modules = ["brakegym"] + [
        m.name for m in pkgutil.walk_packages(brakegym.__path__, "brakegym.") if m.name != "brakegym.__main__"
    ]
    missing = [name for name in modules if f".. automodule:: {name}\n" not in documented]
    assert not missing
