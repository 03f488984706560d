import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
BUILD = pathlib.Path(os.environ.get("TCFARM_BUILD", ROOT / "build"))


@pytest.fixture(scope="session")
def worker_binary():
    path = BUILD / "worker" / "tcfarm-worker"
    if not path.exists():
        pytest.fail(f"{path} is missing: build first (bash scripts/build)")
    return path


@pytest.fixture(scope="session")
def scenes_dir():
    return ROOT / "tests" / "scenes"
