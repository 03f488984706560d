"""A small, dependency-free client of the coordinator's /api/v1."""
import collections
import hashlib
import json
import os
import ssl
import time
import urllib.error
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
        headers = dict(headers or {})
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        request = urllib.request.Request(self.url + path, data=data, method=method,
                                         headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=self.timeout, context=self._tls) as response:
                payload = response.read()
        except urllib.error.HTTPError as e:
            raise _api_error(e) from None
        except urllib.error.URLError as e:
            hint = ""
            if isinstance(e.reason, ssl.SSLCertVerificationError):
                hint = " (a farm with its own certificate authority: --cacert FILE or TCFARM_CACERT)"
            raise ApiError(0, "unreachable", f"cannot reach {self.url}: {e.reason}{hint}") from None
        return payload if raw else json.loads(payload)

    def submit(self, scene, **options):
        """Submits a job. options: name, frames={"start","end"}, strategy, bin_width,
        tolerance, priority, verify; assets={relative path: sha256} (upload_assets gives the
        hashes); scene_file=a path among the assets, with scene None, for a scene that is a
        file (OBJ, glTF), and **{"import": {"fps", "size", "animation", "camera", "spp"}} for
        how it is imported. Returns the job record."""
        body = {} if scene is None else {"scene": scene}
        body.update({k: v for k, v in options.items() if v is not None})
        return self._request("POST", "/api/v1/jobs", body)

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

    def jobs(self, state=None, limit=None):
        query = "&".join(f"{k}={v}" for k, v in (("state", state), ("limit", limit)) if v)
        return self._request("GET", "/api/v1/jobs" + (f"?{query}" if query else ""))["jobs"]

    def cancel(self, job_id):
        return self._request("POST", f"/api/v1/jobs/{int(job_id)}/cancel")

    def workers(self):
        return self._request("GET", "/api/v1/workers")

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
