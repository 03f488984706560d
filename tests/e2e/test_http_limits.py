"""What the HTTP API takes before it knows who is asking, through the real coordinator binary
with API tokens: a large body, whatever the method, is never read whole (its resident memory
is read from /proc before and after), an endless request line is cut off, keep-alive requests
are answered at once, and the Authorization header counts byte for byte."""
import socket
import threading
import time
import urllib.parse

import pytest

from farm_harness import LocalFarm, memory_bytes, reset_peak

ADMIN = "limits-admin-0123456789abcdef"
BODY_BYTES = 600 << 20  # what each client offers; the coordinator must not take it all
SEND_SECONDS = 20       # and each client gives up sending after this long
# The coordinator's peak resident memory may grow by this much over all the anonymous
# requests together: a body read whole would add its 600 MiB.
ANONYMOUS_GROWTH_BOUND = 96 << 20
# An admin's chunked submission is read up to the 64 MiB body limit (a string that may hold
# twice that while it grows), then refused.
ADMIN_GROWTH_BOUND = 200 << 20
METHODS = ["GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS", "PRI", "FOO"]


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("limits"), workers=0, api_tokens={ADMIN: "admin"}) as farm:
        yield farm


def address(farm):
    parsed = urllib.parse.urlsplit(farm.url)
    return parsed.hostname, parsed.port






def offer_body(farm, head, chunked=False):
    """Sends `head`, then up to BODY_BYTES of zeros (in chunks when chunked) until the server
    closes or SEND_SECONDS pass. Returns (the server's first status line, bytes sent)."""
    sock = socket.create_connection(address(farm), timeout=10)
    answer = bytearray()

    def read_answer():
        try:
            while data := sock.recv(65536):
                answer.extend(data)
        except OSError:
            pass

    reader = threading.Thread(target=read_answer, daemon=True)
    reader.start()
    block = bytes(1 << 20)
    if chunked:
        block = b"%x\r\n" % len(block) + block + b"\r\n"
    sent, deadline = 0, time.monotonic() + SEND_SECONDS
    try:
        sock.sendall(head)
        while sent < BODY_BYTES and time.monotonic() < deadline:
            sock.sendall(block)
            sent += len(block)
    except OSError:
        pass  # the server closed the connection: what we expect
    reader.join(10)
    sock.close()
    return bytes(answer).split(b"\r\n", 1)[0].decode(errors="replace"), sent


def test_no_method_reads_an_anonymous_large_body(farm):
    pid = farm.coordinator.pid
    before = reset_peak(pid)
    results = []
    for method in METHODS:
        # With a Content-Length: refused on the head alone.
        head = f"{method} /api/v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Length: {BODY_BYTES}\r\n\r\n".encode()
        results.append((method, "length", *offer_body(farm, head)))
        # Without one (a client that streams until it stops): refused on the head too.
        head = f"{method} /healthz HTTP/1.1\r\nHost: x\r\n\r\n".encode()
        results.append((method, "none", *offer_body(farm, head)))
    head = b"POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"
    results.append(("POST", "chunked", *offer_body(farm, head, chunked=True)))
    # Not even a request line: bytes without a newline.
    results.append(("-", "no request line", *offer_body(farm, b"")))
    growth = memory_bytes(pid, "VmHWM") - before
    for method, framing, status, sent in results:
        print(f"{method:8} {framing:16} {status or '(closed)':40} sent {sent >> 20} MiB")
    print(f"peak resident memory grew {growth / 2**20:.1f} MiB")
    assert growth < ANONYMOUS_GROWTH_BOUND
    statuses = {(method, framing): status for method, framing, status, _ in results}
    for method in METHODS:
        expected = "501 Not Implemented" if method in ("PRI", "FOO") else "413 Payload Too Large"
        assert statuses[(method, "length")] == f"HTTP/1.1 {expected}", method
    assert statuses[("PRI", "none")] == "HTTP/1.1 501 Not Implemented"
    assert statuses[("FOO", "none")] == "HTTP/1.1 501 Not Implemented"
    assert statuses[("POST", "chunked")] == "HTTP/1.1 401 Unauthorized"
    # Every client was cut off long before it had sent its body.
    assert all(sent < BODY_BYTES for *_, sent in results), results


def test_an_admins_chunked_body_is_read_only_to_the_limit(farm):
    pid = farm.coordinator.pid
    before = reset_peak(pid)
    head = (f"POST /api/v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {ADMIN}\r\n"
            "Transfer-Encoding: chunked\r\n\r\n").encode()
    status, sent = offer_body(farm, head, chunked=True)
    growth = memory_bytes(pid, "VmHWM") - before
    print(f"admin chunked: {status}, sent {sent >> 20} MiB, peak resident memory grew {growth / 2**20:.1f} MiB")
    assert status == "HTTP/1.1 413 Payload Too Large"
    assert sent < BODY_BYTES
    assert growth < ADMIN_GROWTH_BOUND


def exchange(farm, request):
    """The status line the coordinator answers a raw request with."""
    with socket.create_connection(address(farm), timeout=10) as sock:
        sock.sendall(request)
        answer = b""
        while b"\r\n" not in answer and (data := sock.recv(4096)):
            answer += data
    return answer.split(b"\r\n", 1)[0].decode()


def test_the_authorization_header_counts_byte_for_byte(farm):
    def status_with(value):
        return exchange(farm, b"GET /api/v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: " + value +
                        b"\r\nConnection: close\r\n\r\n")

    token = ADMIN.encode()
    assert status_with(b"Bearer " + token) == "HTTP/1.1 200 OK"
    assert token[:1] == b"l"
    for near in [b"Bearer " + token + b"%00junk", b"Bearer %6C" + token[1:], b"Bearer " + token + b"junk",
                 b"Bearer " + token + b"\0junk", b"Bearer " + token + b"%20"]:
        assert status_with(near) == "HTTP/1.1 401 Unauthorized", near


def test_keep_alive_requests_are_answered_on_one_connection(farm):
    with socket.create_connection(address(farm), timeout=10) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        reader = sock.makefile("rb")
        for i in range(5):
            started = time.perf_counter()
            sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
            status = reader.readline()
            length = 0
            while (line := reader.readline()) != b"\r\n":
                if line.lower().startswith(b"content-length:"):
                    length = int(line.split(b":")[1])
            reader.read(length)
            print(f"keep-alive request {i}: {(time.perf_counter() - started) * 1000:.2f} ms")
            assert status.startswith(b"HTTP/1.1 200"), status
