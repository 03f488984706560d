"""Running the tcfarm command that tests/cli/conftest.py installs (fixture installed_tcfarm)."""
import os
import subprocess


def run_installed(command, *args, env=None, cwd=None, stdin=None, timeout=300):
    """Runs the installed command with this environment (less anything that would find the
    checkout's client instead) plus env."""
    environment = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    environment.update(env or {})
    return subprocess.run([str(command), *map(str, args)], capture_output=True, text=True,
                          env=environment, cwd=cwd, input=stdin, timeout=timeout)
