"""The docs stay true to the repository: README.md and docs/*.md link only to files that
exist, README.md stays one page that starts with the two commands (CI runs the second),
and every `tcfarm-coordinator`, `tcfarm-worker` and `tcfarm` command in their shell blocks
names a subcommand and flags that the program's --help for that subcommand lists."""
import functools
import os
import pathlib
import re
import shlex
import subprocess
import sys

import pytest

from farm_harness import COORDINATOR, ROOT, WORKER

README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
README_MAX_LINES = 150
# What README.md starts with: the title, then the two commands, each with its comment.
README_START = ["# tcfarm", "", "```sh", "bash scripts/demo   #", "bash scripts/test   #", "```"]

SHELL_LANGUAGES = {"sh", "bash", "shell", "console"}
FENCE = re.compile(r"^\s*```\s*(\S*)\s*$")
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
INLINE_CODE = re.compile(r"`[^`]*`")
SCHEME = re.compile(r"^[a-z][a-z0-9+.-]*:", re.IGNORECASE)
SEPARATORS = {"|", "||", "&", "&&", ";", ";;", "(", ")"}
# The client's options that come before its command, with whether each takes a value.
CLIENT_GLOBAL_OPTIONS = {"--url": True, "--token": True, "--cacert": True, "--json": False,
                         "--version": False, "--help": False, "-h": False}


def prose_and_blocks(text):
    """(prose lines outside fenced blocks, [(language, block lines)])."""
    prose, blocks, block, language = [], [], None, None
    for line in text.splitlines():
        fence = FENCE.match(line)
        if fence and block is None:
            block, language = [], fence.group(1).lower()
        elif fence:
            blocks.append((language, block))
            block = None
        elif block is None:
            prose.append(line)
        else:
            block.append(line)
    return prose, blocks


def relative_links(text):
    """The targets of the page's Markdown links that are paths (no scheme, no bare anchor),
    without their anchors. Code, inline or fenced, holds no links."""
    prose, _ = prose_and_blocks(text)
    targets = []
    for line in prose:
        for target in LINK.findall(INLINE_CODE.sub("", line)):
            path = target.split("#", 1)[0]
            if path and not SCHEME.match(target):
                targets.append(path)
    return targets


def missing_links(page, text):
    return [target for target in relative_links(text) if not (page.parent / target).exists()]


def without_comment(line):
    """The line up to a shell comment: a # that starts a word outside quotes."""
    quote = None
    for index, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index]
    return line


def shell_lines(text):
    """Each command line of the page's shell blocks, continuations joined, comments cut."""
    _, blocks = prose_and_blocks(text)
    for language, block in blocks:
        if language not in SHELL_LANGUAGES:
            continue
        pending = ""
        for line in block:
            if line.rstrip().endswith("\\"):
                pending += line.rstrip()[:-1] + " "
                continue
            yield without_comment(pending + line).strip()
            pending = ""


def words(line):
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    lexer.commenters = ""
    try:
        return list(lexer)
    except ValueError:  # unbalanced quotes: plain words are still worth checking
        return line.split()


def simple_commands(line):
    """The line's commands, split at pipes, lists and subshells."""
    command = []
    for word in words(line):
        if word in SEPARATORS:
            if command:
                yield command
            command = []
        else:
            command.append(word)
    if command:
        yield command


def program_of(command):
    """("coordinator" | "worker" | "client", the words after the program) when the command
    runs one of tcfarm's programs, else None. Environment assignments may come first."""
    while command and re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", command[0]):
        command = command[1:]
    if not command:
        return None
    name = pathlib.PurePosixPath(command[0]).name
    if name == "tcfarm-coordinator":
        return "coordinator", command[1:]
    if name == "tcfarm-worker":
        return "worker", command[1:]
    if name == "tcfarm":
        return "client", command[1:]
    if name.startswith("python") and command[1:3] == ["-m", "tcfarm.cli"]:
        return "client", command[3:]
    return None


def parse_invocation(program, arguments):
    """(subcommand or None, the long flags given to it, the flags given before it)."""
    before = []
    index = 0
    while index < len(arguments) and arguments[index].startswith("-"):
        flag = arguments[index].split("=", 1)[0]
        before.append(flag)
        takes_value = program == "client" and CLIENT_GLOBAL_OPTIONS.get(flag, False)
        index += 2 if takes_value and "=" not in arguments[index] else 1
    if index >= len(arguments):
        return None, [], before
    flags = [word.split("=", 1)[0] for word in arguments[index + 1:] if word.startswith("--")]
    return arguments[index], flags, before


def commands_in(text):
    """(line, program, subcommand, flags, flags before the subcommand) of each command of
    tcfarm's programs in the page's shell blocks."""
    found = []
    for line in shell_lines(text):
        for command in simple_commands(line):
            invocation = program_of(command)
            if invocation:
                program, arguments = invocation
                found.append((line, program, *parse_invocation(program, arguments)))
    return found


def program_command(program):
    if program == "coordinator":
        return [str(COORDINATOR)]
    if program == "worker":
        return [str(WORKER)]
    return [sys.executable, "-m", "tcfarm.cli"]


@functools.lru_cache(maxsize=None)
def help_text(program, subcommand=None):
    """The program's --help (of the subcommand), or None when it refuses."""
    if program in ("coordinator", "worker"):
        binary = COORDINATOR if program == "coordinator" else WORKER
        if not binary.exists():
            pytest.fail(f"{binary} is missing: build first (bash scripts/build)")
    environment = dict(os.environ, PYTHONPATH=str(ROOT / "services" / "client"))
    result = subprocess.run([*program_command(program), *([subcommand] if subcommand else []), "--help"],
                            capture_output=True, text=True, timeout=60, env=environment)
    return result.stdout if result.returncode == 0 else None


def lists(help, word):
    return re.search(r"(?<![\w-])" + re.escape(word) + r"(?![\w-])", help) is not None


def command_problems(program, subcommand, flags, before):
    top = help_text(program)
    problems = [f"{flag} is not an option of {program}" for flag in before if not lists(top, flag)]
    if subcommand is None:
        return problems
    listed_at_top = re.search(r"^\s+" + re.escape(subcommand) + r"\s", top, re.MULTILINE)
    sub_help = help_text(program, subcommand) if listed_at_top else None
    if sub_help is None:
        return problems + [f"{subcommand} is not a subcommand of {program}"]
    return problems + [f"{program} {subcommand} has no {flag}" for flag in flags if not lists(sub_help, flag)]


@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_relative_links_lead_to_files(page):
    assert missing_links(page, page.read_text()) == []


def test_readme_is_one_page_that_starts_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; keep the reference in docs/"
    for index, start in enumerate(README_START):
        assert lines[index].startswith(start) if start else lines[index] == "", (index + 1, lines[index])


@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_commands_in_shell_blocks_name_what_the_programs_offer(page):
    problems = [f"{line}: {problem}" for line, *invocation in commands_in(page.read_text())
                for problem in command_problems(*invocation)]
    assert problems == []


def test_the_pages_show_every_program_at_work():
    programs = {program for page in PAGES for _, program, *_ in commands_in(page.read_text())}
    assert programs == {"coordinator", "worker", "client"}


FAULTY_PAGE = """See [the API](missing.md), [a section](#here), [a site](https://example.org/x.md).

```sh
tcfarm --url http://farm:8080 submit scene.json --wait --no-such-flag   # tcfarm nosuch
build/coordinator/tcfarm-coordinator serve --store s --http 0.0.0.0:8080 \\
    --also-no-such-flag
FOO=1 .venv/bin/python -m tcfarm.cli frobnicate 7
kubectl scale deployment/tcfarm-worker --replicas=3 && tcfarm-worker keygen --out k
```

```json
{"tcfarm": "submit --nothing"}
```
"""


def test_the_checks_catch_what_they_look_for(tmp_path):
    assert missing_links(tmp_path / "page.md", FAULTY_PAGE) == ["missing.md"]
    found = [(program, subcommand, flags) for _, program, subcommand, flags, _ in commands_in(FAULTY_PAGE)]
    assert found == [("client", "submit", ["--wait", "--no-such-flag"]),
                     ("coordinator", "serve", ["--store", "--http", "--also-no-such-flag"]),
                     ("client", "frobnicate", []),
                     ("worker", "keygen", ["--out"])]
    problems = [problem for _, *invocation in commands_in(FAULTY_PAGE) for problem in command_problems(*invocation)]
    assert problems == ["client submit has no --no-such-flag", "coordinator serve has no --also-no-such-flag",
                        "frobnicate is not a subcommand of client"]
