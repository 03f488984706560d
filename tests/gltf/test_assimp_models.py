"""Every glTF file of Debian's assimp-testmodels (good ones, and ones broken on purpose)
through `tcfarm-worker render`: each either renders or is refused with a message that says
what is wrong, where (the file and a JSON pointer) and what was expected. A crash, a hang,
memory past a limit, an error without the file or pointer, or a render without a frame
fails the test. The outcome of every file is printed as a table (and kept as sweep.txt in
the test's temporary folder)."""
import concurrent.futures
import pathlib
import re
import resource
import subprocess
import sys

import pytest

# Debian's assimp-testmodels, which scripts/bootstrap installs: glTF 2.0 under glTF2/, and a
# few glTF 1.0 files under glTF/ that must be refused as such.
MODELS = pathlib.Path("/usr/share/assimp/models")
# The package holds 53 glTF files; fewer means the sweep would pass on files it never read.
MIN_FILES = 50
TIMEOUT_S = 60
MEMORY_LIMIT = 4 << 30
WORKERS = 2

RENDERED, REFUSED, BAD = "rendered", "refused", "BAD"


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(args):
    return subprocess.run([str(arg) for arg in args], capture_output=True, text=True, timeout=TIMEOUT_S,
                          preexec_fn=limit_memory)


def error_lines(stderr):
    return [line for line in stderr.splitlines() if line and not line.startswith("warning: ")]


def refusal_problem(path, stderr):
    """Why a refusal's message is unclear, or None: its line must read
    `tcfarm-render: scene[/pointer]: FILE: <problem>; expected <what>`."""
    lines = error_lines(stderr)
    if not lines:
        return "no error message"
    shape = re.compile(r"tcfarm-render: scene(/\S*)?: " + re.escape(path.name) + r": .+; expected .+")
    if not any(shape.fullmatch(line) for line in lines):
        return "no line names the file and a pointer and says what was expected"
    return None


def warnings_said(stderr):
    """Where the render's warnings point (its lines carry no code: `warning: FILE at POINTER: ...`,
    `warning: FILE: ...` for the whole file)."""
    pointers = [(re.match(r"warning: .*? at (\S+): ", line) or [None, "(file)"])[1]
                for line in stderr.splitlines() if line.startswith("warning: ")]
    return f"{len(pointers)} warnings: {' '.join(pointers)}" if pointers else ""


def sweep_one(binary, path, out):
    """(outcome, what to show of it) for one file."""
    try:
        result = run([binary, "render", path, "--size", "32x24", "--frames", "0:0", "--threads", "1",
                      "--no-png", "--out", out])
    except subprocess.TimeoutExpired:
        return BAD, f"no answer within {TIMEOUT_S} s"
    first_error = next(iter(error_lines(result.stderr)), "")
    if result.returncode < 0:
        return BAD, f"killed by signal {-result.returncode}: {first_error}"
    if result.returncode == 0:
        frame = out / "frame_0000.exr"
        if not frame.exists() or frame.stat().st_size == 0:
            return BAD, "exit 0 without a frame"
        return RENDERED, warnings_said(result.stderr)
    if result.returncode in (1, 2):
        problem = refusal_problem(path, result.stderr)
        return (BAD, f"{problem}: {first_error}") if problem else (REFUSED, first_error)
    return BAD, f"exit {result.returncode}: {first_error}"


def gltf_files():
    return sorted(path for path in MODELS.rglob("*") if path.suffix.lower() in (".gltf", ".glb"))


def test_every_assimp_gltf_model_renders_or_is_refused_clearly(worker_binary, tmp_path):
    if not (MODELS / "glTF2").is_dir():
        pytest.fail(f"{MODELS / 'glTF2'} is missing: install Debian's assimp-testmodels (scripts/bootstrap does)")
    files = gltf_files()
    assert len(files) >= MIN_FILES, f"only {len(files)} glTF files under {MODELS}"
    with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
        outcomes = list(pool.map(lambda item: sweep_one(worker_binary, item[1], tmp_path / f"out{item[0]}"),
                                 enumerate(files)))
    rows = [(str(path.relative_to(MODELS)), outcome, detail) for path, (outcome, detail) in zip(files, outcomes)]
    width = max(len(name) for name, _, _ in rows)
    table = "\n".join(f"{name:<{width}}  {outcome:<8}  {detail}" for name, outcome, detail in rows)
    counts = {kind: sum(1 for _, outcome, _ in rows if outcome == kind) for kind in (RENDERED, REFUSED, BAD)}
    summary = ", ".join(f"{count} {kind}" for kind, count in counts.items())
    (tmp_path / "sweep.txt").write_text(f"{table}\n{summary}\n")
    print(f"\n{table}\n{summary}")
    bad = [f"{name}: {detail}" for name, outcome, detail in rows if outcome == BAD]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("behaviour,outcome", [
    ('mkdir -p "$out" && echo x > "$out/frame_0000.exr"', RENDERED),
    ('echo "tcfarm-render: scene/nodes/0: $name: a loop; expected a tree" >&2; exit 1', REFUSED),
    ('echo "tcfarm-render: [json.exception.parse_error.101] syntax error" >&2; exit 1', BAD),
    ('echo "tcfarm-render: scene: $name: no pointer and no expectation" >&2; exit 1', BAD),
    ("exit 0", BAD),
    ("kill -SEGV $$", BAD),
    ('sleep 5; mkdir -p "$out" && echo x > "$out/frame_0000.exr"', BAD),
], ids=["rendered", "refused", "raw-error", "unclear", "no-frame", "crash", "hang"])
def test_the_sweep_tells_bad_outcomes(tmp_path, monkeypatch, behaviour, outcome):
    """The classification on a stand-in for the renderer that behaves as each case says."""
    monkeypatch.setattr(sys.modules[__name__], "TIMEOUT_S", 1)
    binary = tmp_path / "fake-render"
    binary.write_text(f'#!/bin/bash\nname=$(basename "$2"); out="${{@: -1}}"\n{behaviour}\n')
    binary.chmod(0o755)
    model = tmp_path / "model.gltf"
    model.write_text("{}")
    assert sweep_one(binary, model, tmp_path / "out")[0] == outcome
