from pathlib import Path

import pytest

GOLDEN = Path(__file__).resolve().parent / "golden"


@pytest.fixture(scope="session")
def golden_dir() -> Path:
    """The golden reference values (``tests/golden/PROVENANCE.md`` says where they come from)."""
    return GOLDEN
