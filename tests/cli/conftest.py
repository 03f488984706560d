"""The tcfarm command as a user has it: the client installed by a plain `pip install` into a
fresh virtual environment, outside this checkout, run through its console script."""
import shutil
import subprocess
import sys

import pytest

from farm_harness import ROOT
from installed_client import run_installed


@pytest.fixture(scope="session")
def installed_tcfarm(tmp_path_factory):
    """The path of the installed `tcfarm` command."""
    place = tmp_path_factory.mktemp("installed-client")
    source = place / "client"
    # A copy, so the install's build files stay out of the checkout.
    shutil.copytree(ROOT / "services" / "client", source,
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    venv = place / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    result = subprocess.run([str(venv / "bin" / "pip"), "install", "-q", "--disable-pip-version-check",
                             str(source)], capture_output=True, text=True, timeout=300)
    if result.returncode != 0:
        pytest.fail(f"pip install services/client failed:\n{result.stderr[-3000:]}")
    return venv / "bin" / "tcfarm"


@pytest.fixture
def tcfarm(installed_tcfarm):
    """tcfarm(farm, ARGS..., env=, cwd=, stdin=): the installed command against that farm."""
    def run(farm, *args, **options):
        return run_installed(installed_tcfarm, "--url", farm.url, *args, **options)
    return run
