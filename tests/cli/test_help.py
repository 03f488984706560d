"""Every program and command answers --help (and -h) with its flags, and refuses a bad flag
or value with a non-zero exit and a message naming it."""
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("TCFARM_BUILD", ROOT / "build"))
COORDINATOR = BUILD / "coordinator" / "tcfarm-coordinator"
WORKER = BUILD / "worker" / "tcfarm-worker"

# (program, command words, text the help must show: flags, commands, defaults)
HELP_CASES = [
    (COORDINATOR, [], ["serve", "compare", "analyze", "keygen"]),
    (COORDINATOR, ["serve"], ["--http", "127.0.0.1:8080", "--zmq", "tcp://127.0.0.1:5555", "--store",
                              "--db", "--local-workers", "--worker-threads", "--worker-timeout",
                              "--exr-compression", "--dashboard", "--farm-memory",
                              "--pending-frame-memory", "--import-budget-mib", "--asset-max-file-mib", "MIB=512",
                              "--asset-max-job-mib", "MIB=2048", "--curve-secret", "TCFARM_CURVE_SECRET",
                              "--worker-keys", "TCFARM_WORKER_KEYS", "--insecure-no-auth"]),
    (COORDINATOR, ["keygen"], ["--out", "--name", "--force"]),
    (COORDINATOR, ["compare"], ["REFERENCE_DIR", "TEST_DIR", "--json"]),
    (COORDINATOR, ["analyze"], ["DIR", "--json", "--change-mask"]),
    (WORKER, [], ["serve", "render", "keygen"]),
    (WORKER, ["keygen"], ["--out", "--name", "--force"]),
    (WORKER, ["serve"], ["--coordinator", "tcp://127.0.0.1:5555", "TCFARM_COORDINATOR",
                         "--threads", "--capacity", "--name", "--metrics",
                         "--coordinator-timeout", "--curve-secret", "--coordinator-key",
                         "TCFARM_COORDINATOR_KEY"]),
    (WORKER, ["render"], ["SCENE", "--frames", "--out", "--threads", "--no-exr", "--no-png",
                          "--exr-compression"]),
]


def run(program, *args):
    if not program.exists():
        pytest.fail(f"{program} is missing: build first (bash scripts/build)")
    return subprocess.run([str(program), *map(str, args)], capture_output=True, text=True,
                          timeout=30)


def flag_descriptions(help_text):
    """(flag, description) of each option line of the help. Descriptions start in one column,
    the one of --help's; CLI11 moves the description of a longer flag to the next line."""
    lines = help_text.splitlines()
    column = next(line.index("Print this help") for line in lines if "-h,--help" in line)
    found = []
    for index, line in enumerate(lines):
        if not line.strip().startswith("-"):
            continue
        if len(line) > column and line[column - 1] == " ":
            found.append((line[:column].strip(), line[column:].strip()))
        else:
            following = lines[index + 1] if index + 1 < len(lines) else ""
            found.append((line.strip(), following.strip()))
    return found


@pytest.mark.parametrize("flag", ["--help", "-h"])
@pytest.mark.parametrize("program,words,shown", HELP_CASES,
                         ids=[" ".join([p.name, *w]) for p, w, _ in HELP_CASES])
def test_help_lists_the_flags(program, words, shown, flag):
    result = run(program, *words, flag)
    assert result.returncode == 0, result.stderr
    assert "Usage:" in result.stdout
    for text in shown:
        assert text in result.stdout, f"{text!r} missing from:\n{result.stdout}"
    for name, description in flag_descriptions(result.stdout):
        assert description and not description.startswith("-"), f"{name}: no description"


@pytest.mark.parametrize("program,args,flag", [
    (COORDINATOR, ["serve", "--no-such-flag"], "--no-such-flag"),
    (COORDINATOR, ["serve", "--local-workers", "many"], "--local-workers"),
    (COORDINATOR, ["analyze", "frames", "--no-such-flag"], "--no-such-flag"),
    (WORKER, ["serve", "--no-such-flag"], "--no-such-flag"),
    (WORKER, ["serve", "--threads", "-1"], "--threads"),
    (WORKER, ["render", "scene.json", "--no-such-flag"], "--no-such-flag"),
    (WORKER, ["render", "scene.json", "--threads"], "--threads"),
])
def test_bad_flag_or_value_is_named(program, args, flag):
    result = run(program, *args)
    assert result.returncode == 2, result.stderr
    assert flag in result.stderr
    assert "--help" in result.stderr


def test_unknown_command_is_named():
    for program in (COORDINATOR, WORKER):
        result = run(program, "frobnicate")
        assert result.returncode == 2
        assert "frobnicate" in result.stderr


# The tcfarm client, installed as a user installs it (tests/cli/conftest.py): each command
# and what its help must show.
TCFARM_COMMANDS = {
    (): ["--version", "--url", "--token", "--cacert", "--json", "submit", "list", "status", "watch",
         "wait", "events", "frames", "cancel", "retry", "delete", "priority", "rename", "workers",
         "analyze"],
    ("submit",): ["scene", "--name", "--frames", "--strategy", "--bin-width", "--tolerance",
                  "--priority", "--verify", "--wait", "--fps", "--size", "--animation", "--camera",
                  "--spp", "--light-units", "--view", "--exposure"],
    ("list",): ["--state", "--strategy", "--name", "--limit", "--page", "--offset"],
    ("status",): ["job"],
    ("watch",): ["job", "--read-timeout"],
    ("wait",): ["job"],
    ("events",): ["job", "--follow", "--read-timeout"],
    ("frames",): ["job", "--out", "--format"],
    ("cancel",): ["job"],
    ("retry",): ["job"],
    ("delete",): ["job", "--yes"],
    ("priority",): ["job", "priority", "-100..100"],
    ("rename",): ["job", "name"],
    ("workers",): ["--json"],
    ("analyze",): ["target", "TCFARM_COORDINATOR"],
}


def argparse_items(help_text):
    """(item, description) of each argument and command line of an argparse help: an item line
    is indented, its description follows after two spaces or on the next, deeper line."""
    lines = help_text.splitlines()
    items = []
    for index, line in enumerate(lines):
        indent = len(line) - len(line.lstrip())
        if indent not in (2, 4) or not line.strip() or line.strip() == "COMMAND":
            continue
        name, gap, rest = line.strip().partition("  ")
        following = lines[index + 1] if index + 1 < len(lines) else ""
        if not rest.strip() and len(following) - len(following.lstrip()) > indent + 2:
            rest = following
        items.append((name, rest.strip()))
    return items


@pytest.mark.parametrize("words", list(TCFARM_COMMANDS), ids=lambda w: " ".join(("tcfarm", *w)))
def test_tcfarm_help_describes_every_command_and_flag(installed_tcfarm, words):
    from installed_client import run_installed
    result = run_installed(installed_tcfarm, *words, "--help")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("usage: tcfarm")
    for text in TCFARM_COMMANDS[words]:
        assert text in result.stdout, f"{text!r} missing from:\n{result.stdout}"
    items = argparse_items(result.stdout)
    assert len(items) >= len(TCFARM_COMMANDS[words])
    for name, description in items:
        assert description, f"tcfarm {' '.join(words)}: {name} has no description:\n{result.stdout}"


def test_tcfarm_names_a_bad_flag_or_command(installed_tcfarm):
    from installed_client import run_installed
    for args, named in ((["list", "--no-such-flag"], "--no-such-flag"),
                        (["frobnicate"], "frobnicate"),
                        (["list", "--state", "done"], "'done' is not a job state"),
                        (["priority", "3", "high"], "invalid int value: 'high'")):
        result = run_installed(installed_tcfarm, *args)
        assert result.returncode == 2, (args, result.stderr)
        assert named in result.stderr, (args, result.stderr)
