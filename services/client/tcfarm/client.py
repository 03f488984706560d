"""A small, dependency-free client of the coordinator's /api/v1."""
import base64
import collections
import hashlib
import http.client
import json
import os
import ssl
import time
import urllib.error
import urllib.parse
import urllib.request

FINAL_STATES = ("completed", "failed", "canceled")


class ApiError(Exception):
    """An error answered by the farm, in its one error shape, or a transport failure."""

    def __init__(self, status, code, message, pointer=None):
        self.status, self.code, self.pointer = status, code, pointer
        where = f" at {pointer}" if pointer else ""
        super().__init__(f"{code} ({status}){where}: {message}" if status else message)


# What upload_assets did: every file's hash by the path it was given as, and the hashes it
# had to send (the farm lacked them); an unchanged file is never sent twice.
AssetUpload = collections.namedtuple("AssetUpload", ["hashes", "uploaded"])

_HASH_CHUNK_BYTES = 1 << 20
# A stream that ended is opened again after this long: soon enough to miss nothing a person
# would notice, slow enough not to spin against a farm that closes it at once.
_STREAM_REOPEN_SECONDS = 0.5


def sha256_file(path):
    """The SHA-256 of a file's bytes in lowercase hex, read in pieces (assets may be large)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for piece in iter(lambda: f.read(_HASH_CHUNK_BYTES), b""):
            digest.update(piece)
    return digest.hexdigest()


class Client:
    """token: an API token of the farm (`serve --api-tokens`), sent as
    "Authorization: Bearer TOKEN"; None for a farm without tokens. cacert: a PEM file of
    the certificate authority that signed an https farm's certificate, when the system's
    do not."""

    def __init__(self, url="http://127.0.0.1:8080", timeout=30.0, token=None, cacert=None):
        self.url = url.rstrip("/")
        self.timeout = timeout
        self.token = token or None
        self._tls = ssl.create_default_context(cafile=cacert) if cacert else None

    def _request(self, method, path, body=None, raw=False, data=None, headers=None):
        """body: JSON to send; or data (bytes or a file) with its headers."""
        if data is None:
            data = None if body is None else json.dumps(body).encode()
            headers = {"Content-Type": "application/json"}
        with self._open(method, path, data=data, headers=headers) as response:
            payload = response.read()
        return payload if raw else json.loads(payload)

    def _open(self, method, path, data=None, headers=None, timeout=None):
        """The response, once its headers came; the farm's errors raised as ApiError."""
        headers = dict(headers or {})
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        request = urllib.request.Request(self.url + path, data=data, method=method,
                                         headers=headers)
        try:
            return urllib.request.urlopen(request, timeout=timeout or self.timeout,
                                          context=self._tls)
        except urllib.error.HTTPError as e:
            raise _api_error(e) from None
        except urllib.error.URLError as e:
            hint = ""
            if isinstance(e.reason, ssl.SSLCertVerificationError):
                hint = " (a farm with its own certificate authority: --cacert FILE or TCFARM_CACERT)"
            raise ApiError(0, "unreachable", f"cannot reach {self.url}: {e.reason}{hint}") from None

    def submit(self, scene, **options):
        """Submits a job. options: name, frames={"start","end"}, strategy, bin_width,
        tolerance, priority, verify, view ("standard", "khr-pbr-neutral"), exposure (EV of
        the PNG previews); assets={relative path: sha256} (upload_assets gives the
        hashes); scene_file=a path among the assets, with scene None, for a scene that is a
        file (OBJ, glTF), and **{"import": {"fps", "size", "animation", "camera", "spp"}} for
        how it is imported. Returns the job record."""
        body = {} if scene is None else {"scene": scene}
        body.update({k: v for k, v in options.items() if v is not None})
        return self._request("POST", "/api/v1/jobs", body)

    def check_scene(self, scene, **options):
        """What submit(scene, **options) would import, with nothing stored and no job made:
        {"ok", "complete", "frames", "width", "height", "warnings"} or, when some assets are
        not uploaded yet, {"ok", "complete": False, "missing_assets"}; a scene the farm
        refuses raises the ApiError the submit would. options as submit's, plus
        scene_file_data: the scene file's bytes (sent in base64) when it is not uploaded yet."""
        data = options.pop("scene_file_data", None)
        body = {} if scene is None else {"scene": scene}
        body.update({k: v for k, v in options.items() if v is not None})
        if data is not None:
            body["scene_file_data"] = base64.b64encode(data).decode("ascii")
        return self._request("POST", "/api/v1/scenes/check", body)

    def missing_assets(self, hashes):
        """Which of these SHA-256 hashes the farm does not have."""
        return self._request("POST", "/api/v1/assets/missing", {"hashes": list(hashes)})["missing"]

    def put_asset(self, path, sha256=None):
        """Uploads one file, streamed; returns {"sha256", "size"}."""
        sha256 = sha256 or sha256_file(path)
        with open(path, "rb") as f:
            return self._request("PUT", f"/api/v1/assets/{sha256}", data=f, headers={
                "Content-Type": "application/octet-stream",
                "Content-Length": str(os.fstat(f.fileno()).st_size)})

    def upload_assets(self, paths):
        """Uploads the files the farm does not have yet, asking it first; returns an
        AssetUpload: hashes {path: sha256} for every path, and the hashes uploaded."""
        hashes = {path: sha256_file(path) for path in paths}
        missing = self.missing_assets(sorted(set(hashes.values()))) if hashes else []
        by_hash = {sha256: path for path, sha256 in hashes.items()}
        for sha256 in missing:
            self.put_asset(by_hash[sha256], sha256)
        return AssetUpload(hashes, missing)

    def job(self, job_id):
        return self._request("GET", f"/api/v1/jobs/{int(job_id)}")

    def jobs(self, state=None, limit=None, **filters):
        """The jobs of the first page (newest first), as a list; job_page has the rest."""
        return self.job_page(state=state, limit=limit, **filters)["jobs"]

    def job_page(self, state=None, strategy=None, name=None, limit=None, offset=None):
        """One page of the job list, newest first: {"jobs", "total", "offset", "limit"}.
        state: one state or several (a list, or "a,b"); name: a case-insensitive part of it."""
        if isinstance(state, (list, tuple)):
            state = ",".join(state)
        query = urllib.parse.urlencode([(key, value) for key, value in (
            ("state", state), ("strategy", strategy), ("name", name), ("limit", limit),
            ("offset", offset)) if value not in (None, "")])
        return self._request("GET", "/api/v1/jobs" + (f"?{query}" if query else ""))

    def cancel(self, job_id):
        return self._request("POST", f"/api/v1/jobs/{int(job_id)}/cancel")

    def delete(self, job_id):
        """Deletes a finished job, its frames and the assets no other job uses:
        {"deleted": id, "freed_bytes": n}. A queued or running job is refused (409 job_active)."""
        return self._request("DELETE", f"/api/v1/jobs/{int(job_id)}")

    def retry(self, job_id):
        """Queues a failed or canceled job again (same id; frames already written are kept)."""
        return self._request("POST", f"/api/v1/jobs/{int(job_id)}/retry")

    def update(self, job_id, priority=None, name=None):
        """Changes a job's priority (-100..100, higher first) or name; returns the job."""
        body = {key: value for key, value in (("priority", priority), ("name", name))
                if value is not None}
        return self._request("PATCH", f"/api/v1/jobs/{int(job_id)}", body)

    def frame_states(self, job_id):
        """Each frame's state: {"job", "frames": [{"frame", "state", "traced", "copied"}], "counts"}."""
        return self._request("GET", f"/api/v1/jobs/{int(job_id)}/frames")

    def events(self, job_id, after=None):
        """The job's events, oldest first, after the sequence number `after`."""
        query = "" if after is None else f"?after={int(after)}"
        return self._request("GET", f"/api/v1/jobs/{int(job_id)}/events{query}")["events"]

    def stream_events(self, after=None, read_timeout=None, job=None):
        """The farm's live events, every job's, from GET /api/v1/events (Server-Sent
        Events), as dicts with "seq", "job", "time", "type" and "message". The stream is
        opened at once, so a farm that refuses it raises ApiError here (404 or 405 from a
        farm without it); iterating then yields each event as it comes, for as long as the
        caller goes on. after: the sequence number to start after (None: from now); job:
        only that job's events. A connection that drops, or stays silent for read_timeout
        seconds, is opened again with Last-Event-ID, so no event is missed or repeated."""
        read_timeout = read_timeout or self.timeout
        response = self._open_stream(after, read_timeout, job)

        def events():
            nonlocal response
            last = after
            while True:
                try:
                    for event in _server_sent_events(response):
                        if event.get("seq") is not None:
                            last = event["seq"]
                        yield event
                except (OSError, http.client.HTTPException):
                    pass  # dropped, or silent for longer than read_timeout
                finally:
                    response.close()
                time.sleep(_STREAM_REOPEN_SECONDS)
                response = self._open_stream(last, read_timeout, job)

        return events()

    def _open_stream(self, after, read_timeout, job):
        headers = {"Accept": "text/event-stream"}
        if after is not None:
            headers["Last-Event-ID"] = str(after)
        query = "" if job is None else f"?job={int(job)}"
        return self._open("GET", "/api/v1/events" + query, headers=headers, timeout=read_timeout)

    def workers(self):
        return self._request("GET", "/api/v1/workers")

    def strategies(self):
        """{"strategies": [names, in the farm's order], "default": name}."""
        return self._request("GET", "/api/v1/strategies")

    def distrusted_workers(self):
        """Workers banned for returning wrong values: [{principal, name, why, banned_at}]."""
        return self._request("GET", "/api/v1/workers?distrusted")["distrusted"]

    def lift_ban(self, principal):
        """Lets a banned worker (its principal as distrusted_workers names it) work again."""
        query = urllib.parse.urlencode({"principal": principal})
        return self._request("DELETE", "/api/v1/workers/distrusted?" + query)

    def frame(self, job_id, frame, fmt="png"):
        return self._request("GET", f"/api/v1/jobs/{int(job_id)}/frames/{int(frame)}.{fmt}",
                             raw=True)

    def wait(self, job_id, poll_seconds=0.2, timeout=None, on_progress=None):
        """Polls until the job reaches a final state; returns its record."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            job = self.job(job_id)
            if on_progress:
                on_progress(job)
            if job["state"] in FINAL_STATES:
                return job
            if deadline is not None and time.monotonic() > deadline:
                raise ApiError(0, "timeout", f"job {job_id} still {job['state']} after {timeout} s")
            time.sleep(poll_seconds)


def trace_cost_seconds(stats):
    """What a job's tracing cost: CPU seconds of the tracing threads when every worker
    reported them (waiting for shared cores does not count), else elapsed seconds."""
    return stats.get("trace_cpu_seconds", stats["trace_seconds"])


def _api_error(http_error):
    try:
        error = json.loads(http_error.read())["error"]
        return ApiError(error.get("status", http_error.code), error.get("code", "error"),
                        error.get("message", ""), error.get("pointer"))
    except (ValueError, KeyError, TypeError):
        return ApiError(http_error.code, "http_error", str(http_error))


def _server_sent_events(response):
    """The events of a text/event-stream response (the WHATWG format: "field: value" lines,
    a blank line ends an event, ":" starts a comment), each as its JSON data with the
    stream's `id` as "seq" and `event` as "type" where the data lacks them."""
    fields, data = {}, []
    for raw in response:
        line = raw.decode("utf-8").rstrip("\r\n")
        if not line:
            if data:
                try:
                    event = json.loads("\n".join(data))
                except ValueError:
                    event = {"message": "\n".join(data)}
                if isinstance(event, dict):
                    if "id" in fields and "seq" not in event:
                        event["seq"] = int(fields["id"]) if fields["id"].isdigit() else fields["id"]
                    if "event" in fields and "type" not in event:
                        event["type"] = fields["event"]
                    yield event
            fields, data = {}, []
            continue
        if line.startswith(":"):
            continue  # a comment: the farm's keep-alive
        name, _, value = line.partition(":")
        value = value[1:] if value.startswith(" ") else value
        if name == "data":
            data.append(value)
        elif name in ("id", "event", "retry"):
            fields[name] = value
