"""API tokens, the secure default and TLS, through the real coordinator binary, its HTTP API
and the tcfarm command line."""
import hashlib
import json
import subprocess
import urllib.error
import urllib.request

import pytest
import requests

from farm_harness import COORDINATOR, LocalFarm, tcfarm_cli
from tcfarm.client import ApiError, Client

ADMIN = "admin-token-0123456789abcdef"
READER = "read-token-0123456789abcdef"
ALICE = "alice-submit-0123456789abcdef"
BOB = "bob-submit-0123456789abcdef"
TOKENS = {ADMIN: "admin", READER: "read", ALICE: "submit", BOB: "submit"}

SCENE = {"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
         "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}],
         "render": {"width": 8, "height": 6, "frames": {"start": 0, "count": 4}}}


def token_id(token):
    return hashlib.sha256(token.encode()).hexdigest()[:12]


def request(url, method="GET", token=None, body=None, context=None):
    """(status, headers, body bytes) of one request, whatever the status."""
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    data = None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
    req = urllib.request.Request(url, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=30, context=context) as response:
            return response.status, response.headers, response.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def error_code(body):
    error = json.loads(body)["error"]
    assert error["message"]
    return error["code"]


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("auth"), workers=0, api_tokens=TOKENS) as farm:
        yield farm


def test_anonymous_requests_get_401_with_the_bearer_challenge(farm):
    for method, path in [("GET", "/api/v1/jobs"), ("GET", "/api/v1/jobs/1"), ("GET", "/api/v1/workers"),
                         ("GET", "/metrics"), ("POST", "/api/v1/jobs"), ("POST", "/api/v1/jobs/1/cancel"),
                         ("GET", "/api/v1/jobs/1/frames/0.png")]:
        status, headers, body = request(farm.url + path, method, body={"scene": SCENE} if method == "POST" else None)
        assert status == 401, (path, body)
        assert headers["WWW-Authenticate"].startswith("Bearer"), path
        assert error_code(body) == "unauthorized"
    status, _, body = request(farm.url + "/api/v1/jobs", token="not-a-token-of-this-farm")
    assert status == 401 and error_code(body) == "unauthorized"
    status, _, body = request(farm.url + "/api/v1/jobs", token=ADMIN.upper())
    assert status == 401


def test_healthz_and_the_dashboards_files_stay_open(farm):
    assert request(farm.url + "/healthz")[0] == 200
    status, _, body = request(farm.url + "/")
    assert status == 200 and b"<html" in body.lower()


def test_a_read_token_reads_but_cannot_submit_or_upload(farm):
    assert request(farm.url + "/api/v1/jobs", token=READER)[0] == 200
    status, _, body = request(farm.url + "/metrics", token=READER)
    assert status == 200 and b"tcfarm_http_requests_refused_total" in body
    status, _, body = request(farm.url + "/api/v1/jobs", "POST", READER, {"scene": SCENE})
    assert status == 403 and error_code(body) == "forbidden"
    assert b"submit" in body and READER.encode() not in body
    content = b"an asset a reader may not store"
    sha = hashlib.sha256(content).hexdigest()
    status, _, body = request(farm.url + f"/api/v1/assets/{sha}", "PUT", READER, content)
    assert status == 403
    assert not (farm.store / "assets" / sha).exists()
    status, _, body = request(farm.url + f"/api/v1/assets/{sha}", "PUT", None, content)
    assert status == 401
    assert not (farm.store / "assets" / sha).exists()
    # A refused body is read and dropped, so the connection stays in step: on one kept-alive
    # connection, a refused upload, then the same bytes from a submit token are stored.
    with requests.Session() as session:
        url = farm.url + f"/api/v1/assets/{sha}"
        big = content * 4096
        big_sha = hashlib.sha256(big).hexdigest()
        refused = session.put(farm.url + f"/api/v1/assets/{big_sha}", data=big,
                              headers={"Authorization": f"Bearer {READER}"}, timeout=30)
        assert refused.status_code == 403
        stored = session.put(url, data=content, headers={"Authorization": f"Bearer {ALICE}"}, timeout=30)
        assert stored.status_code == 201, stored.text
        assert not (farm.store / "assets" / big_sha).exists()


def test_a_submit_token_cancels_its_own_jobs_only_and_admin_cancels_any(farm):
    alice, bob, admin = (Client(farm.url, token=t) for t in (ALICE, BOB, ADMIN))
    alices_job = alice.submit(SCENE)
    assert alices_job["submitted_by"] == token_id(ALICE)
    with pytest.raises(ApiError) as refused:
        bob.cancel(alices_job["id"])
    assert refused.value.status == 403 and refused.value.code == "forbidden"
    assert token_id(ALICE) in str(refused.value) and ALICE not in str(refused.value)
    assert alice.job(alices_job["id"])["state"] == "queued"
    assert alice.cancel(alices_job["id"])["state"] == "canceled"
    bobs_job = bob.submit(SCENE)
    assert admin.cancel(bobs_job["id"])["state"] == "canceled"
    with pytest.raises(ApiError) as refused:
        Client(farm.url, token=READER).cancel(bob.submit(SCENE)["id"])
    assert refused.value.status == 403


def test_tokens_are_never_logged(farm):
    Client(farm.url, token=ALICE).jobs()
    request(farm.url + "/api/v1/jobs", "POST", READER, {"scene": SCENE})
    log = (farm.directory / "coordinator.log").read_text()
    for token in TOKENS:
        assert token not in log


def test_the_cli_takes_a_token_by_flag_or_environment(farm):
    anonymous = tcfarm_cli(farm, "workers", env={"TCFARM_TOKEN": ""})
    assert anonymous.returncode == 1
    assert "unauthorized (401)" in anonymous.stderr
    assert "--token TOKEN or the environment variable TCFARM_TOKEN" in anonymous.stderr
    assert len(anonymous.stderr.strip().splitlines()) == 1
    assert tcfarm_cli(farm, "--token", READER, "workers", env={"TCFARM_TOKEN": ""}).returncode == 0
    assert tcfarm_cli(farm, "workers", env={"TCFARM_TOKEN": READER}).returncode == 0
    # The flag wins over the environment.
    wrong_env = tcfarm_cli(farm, "--token", READER, "workers", env={"TCFARM_TOKEN": "unknown-0123456789abcdef"})
    assert wrong_env.returncode == 0, wrong_env.stderr
    scene_file = farm.directory / "scene.json"
    scene_file.write_text(json.dumps(SCENE))
    refused = tcfarm_cli(farm, "--token", READER, "submit", scene_file)
    assert refused.returncode == 1 and "forbidden (403)" in refused.stderr and "role is too low" in refused.stderr
    submitted = tcfarm_cli(farm, "--json", "submit", scene_file, env={"TCFARM_TOKEN": ALICE})
    assert submitted.returncode == 0, submitted.stderr
    assert json.loads(submitted.stdout)["submitted_by"] == token_id(ALICE)


def serve(*args, timeout=10):
    """Runs `tcfarm-coordinator serve ARGS` expecting it to refuse to start."""
    return subprocess.run([str(COORDINATOR), "serve", "--local-workers", "0", "--zmq", "tcp://127.0.0.1:*",
                           *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_beyond_loopback_without_tokens_refuses_to_start(tmp_path):
    for address in ("0.0.0.0:0", "[::]:0"):
        refused = serve("--http", address, "--store", tmp_path / "store")
        assert refused.returncode == 2, refused.stderr
        assert "beyond loopback" in refused.stderr and "--api-tokens" in refused.stderr
        assert "--insecure-no-auth" in refused.stderr


def test_insecure_no_auth_serves_beyond_loopback_with_a_loud_warning(tmp_path):
    with LocalFarm(tmp_path, workers=0, coordinator_args=("--insecure-no-auth",)) as farm:
        pass  # loopback here; the flag is accepted and the farm answers
    process = subprocess.Popen([str(COORDINATOR), "serve", "--http", "0.0.0.0:0", "--insecure-no-auth",
                                "--local-workers", "0", "--zmq", "tcp://127.0.0.1:*", "--store", tmp_path / "s2"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert "listening http=http://0.0.0.0:" in line
        port = int(line.split("http://0.0.0.0:")[1].split()[0])
        assert request(f"http://127.0.0.1:{port}/api/v1/jobs")[0] == 200
    finally:
        process.terminate()
        _, stderr = process.communicate(timeout=10)
    assert "WARNING: --insecure-no-auth" in stderr and "ANYONE" in stderr
    assert farm.client.url  # the loopback farm started


def test_a_bad_tokens_file_refuses_to_start_naming_file_and_line(tmp_path):
    tokens = tmp_path / "tokens.txt"
    tokens.write_text(f"# farm\nadmin {ADMIN}\nowner {READER}\n")
    refused = serve("--http", "0.0.0.0:0", "--store", tmp_path / "store", "--api-tokens", tokens)
    assert refused.returncode == 2
    assert f"--api-tokens {tokens} line 3: neither field is a role" in refused.stderr
    assert READER not in refused.stderr and ADMIN not in refused.stderr
    missing = serve("--store", tmp_path / "store", "--api-tokens", tmp_path / "none.txt")
    assert missing.returncode == 2 and f"{tmp_path / 'none.txt'}: cannot read it" in missing.stderr


@pytest.fixture(scope="module")
def certificate(tmp_path_factory):
    """A self-signed certificate for 127.0.0.1 and localhost, made by the openssl CLI."""
    folder = tmp_path_factory.mktemp("tls")
    cert, key = folder / "cert.pem", folder / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2",
                    "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
                    "-keyout", str(key), "-out", str(cert)], check=True, capture_output=True, timeout=60)
    return cert, key


def test_tls_serves_https_with_tokens(tmp_path, certificate):
    cert, key = certificate
    with LocalFarm(tmp_path, workers=0, api_tokens=TOKENS,
                   coordinator_args=("--tls-cert", cert, "--tls-key", key)) as farm:
        assert farm.url.startswith("https://127.0.0.1:")
        client = Client(farm.url, token=READER, cacert=str(cert))
        assert client.jobs() == []
        with pytest.raises(ApiError) as untrusted:
            Client(farm.url, token=READER).jobs()  # the system's authorities do not know it
        assert "--cacert" in str(untrusted.value)
        assert tcfarm_cli(farm, "--cacert", cert, "workers").returncode == 0
        via_env = tcfarm_cli(farm, "workers", env={"TCFARM_CACERT": str(cert), "TCFARM_TOKEN": READER})
        assert via_env.returncode == 0, via_env.stderr
        plain = farm.url.replace("https://", "http://")
        with pytest.raises(Exception):
            Client(plain, token=READER, timeout=5).jobs()


def test_tls_files_that_cannot_be_used_refuse_to_start(tmp_path, certificate):
    cert, key = certificate
    store = tmp_path / "store"
    alone = serve("--store", store, "--tls-cert", cert)
    assert alone.returncode == 2 and "expected both --tls-cert FILE and --tls-key FILE" in alone.stderr
    unreadable = serve("--store", store, "--tls-cert", cert, "--tls-key", tmp_path / "nokey.pem")
    assert unreadable.returncode == 2 and f"--tls-key {tmp_path / 'nokey.pem'}: cannot read it" in unreadable.stderr
    not_a_key = tmp_path / "not-a-key.pem"
    not_a_key.write_text("not a key\n")
    mismatched = serve("--http", "127.0.0.1:0", "--store", store, "--tls-cert", cert, "--tls-key", not_a_key)
    assert mismatched.returncode == 1
    assert str(cert) in mismatched.stderr and str(not_a_key) in mismatched.stderr
