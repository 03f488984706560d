"""deploy/coordinator-entrypoint, the coordinator image's entry point, run here with the
real coordinator binary: it makes the API tokens at first start and keeps them after."""
import os
import re
import stat
import subprocess

import requests

from farm_harness import COORDINATOR, ROOT

ENTRYPOINT = ROOT / "deploy" / "coordinator-entrypoint"


def start(tmp_path, tokens_file):
    env = dict(os.environ, PATH=f"{COORDINATOR.parent}:{os.environ['PATH']}", TCFARM_API_TOKENS=str(tokens_file))
    process = subprocess.Popen([str(ENTRYPOINT), "serve", "--http", "0.0.0.0:0", "--zmq", "tcp://127.0.0.1:*",
                                "--store", str(tmp_path / "store"), "--local-workers", "0"],
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = process.stdout.readline()
    match = re.search(r"http=http://0\.0\.0\.0:(\d+)", line)
    assert match, (line, process.stderr.read() if process.poll() is not None else "")
    return process, f"http://127.0.0.1:{match.group(1)}"


def stop(process):
    process.terminate()
    return process.communicate(timeout=10)[1]


def test_first_start_makes_an_admin_and_a_read_token_and_later_starts_keep_them(tmp_path):
    tokens_file = tmp_path / "tokens" / "api-tokens"
    process, url = start(tmp_path, tokens_file)
    try:
        lines = [line.split() for line in tokens_file.read_text().splitlines() if not line.startswith("#")]
        tokens = dict(lines)
        assert set(tokens) == {"admin", "read"}
        assert all(re.fullmatch(r"[0-9a-f]{64}", t) for t in tokens.values())
        assert tokens["admin"] != tokens["read"]
        assert stat.S_IMODE(tokens_file.stat().st_mode) == 0o600
        read_token = tokens_file.parent / "read-token"
        assert read_token.read_text().strip() == tokens["read"]
        assert requests.get(url + "/api/v1/jobs", timeout=10).status_code == 401
        assert requests.get(url + "/metrics", timeout=10,
                            headers={"Authorization": f"Bearer {tokens['read']}"}).status_code == 200
    finally:
        stderr = stop(process)
    assert "made an admin and a read API token" in stderr
    assert tokens["admin"] not in stderr and tokens["read"] not in stderr

    process, url = start(tmp_path, tokens_file)
    try:
        assert dict(line.split() for line in tokens_file.read_text().splitlines()
                    if not line.startswith("#")) == tokens
        assert requests.get(url + "/api/v1/jobs", timeout=10,
                            headers={"Authorization": f"Bearer {tokens['admin']}"}).status_code == 200
    finally:
        assert "made an admin" not in stop(process)
