"""A small, dependency-free client of the coordinator's /api/v1."""
import json
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


class Client:
    def __init__(self, url="http://127.0.0.1:8080", timeout=30.0):
        self.url = url.rstrip("/")
        self.timeout = timeout

    def _request(self, method, path, body=None, raw=False):
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(self.url + path, data=data, method=method,
                                         headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as response:
                payload = response.read()
        except urllib.error.HTTPError as e:
            raise _api_error(e) from None
        except urllib.error.URLError as e:
            raise ApiError(0, "unreachable", f"cannot reach {self.url}: {e.reason}") from None
        return payload if raw else json.loads(payload)

    def submit(self, scene, **options):
        """Submits a job. options: name, frames={"start","end"}, strategy, bin_width,
        tolerance, priority. Returns the job record."""
        body = {"scene": scene}
        body.update({k: v for k, v in options.items() if v is not None})
        return self._request("POST", "/api/v1/jobs", body)

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
