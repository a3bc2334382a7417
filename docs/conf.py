"""Sphinx configuration of brakegym's documentation.

Build it strictly (every warning an error, every cross-reference checked), as ``tests/test_docs.py``
does::

    python -m sphinx -W --keep-going -n -b html docs out/docs

Nothing is fetched at build time: no intersphinx, and a theme that ships its files (furo, from the
``dev`` extra; Sphinx's own alabaster where furo is not installed).
"""

from __future__ import annotations

import importlib
import inspect
import re
from typing import Any

import brakegym

project = "brakegym"
author = "The brakegym developers"
copyright = "2026, The brakegym developers"
release = brakegym.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
]

source_suffix = {".md": "markdown"}
root_doc = "index"
# demo_table.md is what ``brakegym demo --out docs`` writes; simulation.md includes it.
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "demo_table.md"]

myst_heading_anchors = 3

# Docstrings: numpy style; type hints in the signature.
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_member_order = "bysource"
# Each object documented once, in the module that defines it: a package's page shows what the
# package itself defines, not the names it re-exports (those links resolve to the defining module,
# see _resolve_reexport below).
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
add_module_names = False

# Every reference must resolve, except those to names outside brakegym (no intersphinx: nothing may
# be fetched at build time, so these stay plain text).
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|numpy\.typing|npt|numba)(\..*)?"),
    (r"py:.*", r"(pandas|pd)(\..*)?"),
    (r"py:.*", r"(gymnasium|gym)(\..*)?"),
    (r"py:.*", r"(pydantic|pydantic_core|annotated_types)(\..*)?"),
    (r"py:.*", r"scipy(\..*)?"),
    (r"py:.*", r"(stable_baselines3|sb3)(\..*)?"),
    (r"py:.*", r"torch(\..*)?"),
    (r"py:.*", r"matplotlib(\..*)?"),
    (r"py:.*", r"(typing|types|collections\.abc|argparse|pathlib|importlib|abc)(\..*)?"),
    # The standard library's names as annotations show them unqualified.
    (r"py:class", r"Path|Traversable"),
    # What a type annotation shows that is no name: the literals of Annotated[float, Gt(gt=0.1)],
    # and pieces of the quoted annotations of signatures that could not be evaluated.
    (r"py:class", r"-?[0-9][0-9.e+-]*"),
    (r"py:class", r"'.*|.*'"),
]

html_theme = "furo"
try:
    import furo  # noqa: F401
except ImportError:  # the builtin theme works offline too
    html_theme = "alabaster"
html_title = f"brakegym {release}"


# --- Markdown pipe tables in docstrings ------------------------------------------------------------
# Some module docstrings hold a table written as in Markdown (readable in help()); turn it into a
# reStructuredText list-table for the documentation.
_TABLE_ROW = re.compile(r"^(\s*)\|(.*)\|\s*$")
_TABLE_RULE = re.compile(r"^\s*\|(\s*:?-{3,}:?\s*\|)+\s*$")


def _pipe_tables_to_list_tables(lines: list[str]) -> None:
    out: list[str] = []
    i = 0
    while i < len(lines):
        header = _TABLE_ROW.match(lines[i])
        if header and i + 1 < len(lines) and _TABLE_RULE.match(lines[i + 1]):
            indent = header.group(1)
            rows = [header.group(2)]
            i += 2
            while i < len(lines) and (row := _TABLE_ROW.match(lines[i])):
                rows.append(row.group(2))
                i += 1
            if out and out[-1].strip():
                out.append("")
            out += [f"{indent}.. list-table::", f"{indent}   :header-rows: 1", ""]
            for row in rows:
                cells = [cell.strip() for cell in row.split("|")]
                out.append(f"{indent}   * - {cells[0]}".rstrip())
                out += [f"{indent}     - {cell}".rstrip() for cell in cells[1:]]
            if i < len(lines) and lines[i].strip():
                out.append("")
            continue
        out.append(lines[i])
        i += 1
    lines[:] = out


def _process_docstring(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    _pipe_tables_to_list_tables(lines)


# --- pydantic's machinery ---------------------------------------------------------------------------
# The config schemas are pydantic models; their fields are documented, pydantic's own attributes are
# not (older Sphinx versions list them, and fail on some).
def _skip_pydantic_internals(app: Any, what: str, name: str, obj: Any, skip: bool, options: Any) -> bool | None:
    if what == "class" and (name == "model_config" or name.startswith(("__pydantic", "model_"))):
        return True
    return None


# --- References through re-exports -----------------------------------------------------------------
def _defining_name(target: str) -> str | None:
    """The name under which a brakegym object is documented (its defining module), when ``target``
    names it through a package that re-exports it (``brakegym.config.ConfigError`` is
    ``brakegym.config.schema.ConfigError``); None if ``target`` is no such object."""
    if not target.startswith("brakegym."):
        return None
    parts = target.split(".")
    for split in range(len(parts) - 1, 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        try:
            for attribute in parts[split:]:
                obj = getattr(obj, attribute)
        except AttributeError:
            return None
        if inspect.ismodule(obj):
            return obj.__name__ if obj.__name__ != target else None
        owner, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if owner and qualname and owner.startswith("brakegym") and f"{owner}.{qualname}" != target:
            return f"{owner}.{qualname}"
        return None
    return None


def _resolve_reexport(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a reference to a brakegym object written with the name a package re-exports it
    under, absolute or relative to the current module (``:class:`ConfigError``` in
    ``brakegym.config``), to where it is documented."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip(".~")
    module = node.get("py:module")
    candidates = [target] + ([f"{module}.{target}"] if module else [])
    for candidate in candidates:
        name = _defining_name(candidate)
        if name is None:
            continue
        domain = env.get_domain("py")
        for role, refnode in domain.resolve_any_xref(env, node["refdoc"], app.builder, name, node, contnode):
            if role.startswith("py:"):
                return refnode
    return None


def setup(app: Any) -> dict[str, Any]:
    app.connect("autodoc-process-docstring", _process_docstring, priority=400)
    app.connect("autodoc-skip-member", _skip_pydantic_internals)
    app.connect("missing-reference", _resolve_reexport)
    return {"parallel_read_safe": True}
