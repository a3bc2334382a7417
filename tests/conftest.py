from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


def _golden_dir() -> Path:
    # The golden files live in the workspace's shared/ folder beside the checkout (CI clones the
    # repository next to it); a copy inside the repository's own shared/ also works.
    for candidate in (REPO.parent / "shared" / "golden", REPO / "shared" / "golden"):
        if candidate.is_dir():
            return candidate
    pytest.fail("golden reference files not found: expected ../shared/golden beside the repository")


@pytest.fixture(scope="session")
def golden_dir() -> Path:
    return _golden_dir()
