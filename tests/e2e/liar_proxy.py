"""A liar made of a real worker: a man in the middle between a real `tcfarm-worker serve` and
the farm, which forwards every message both ways unchanged (READY, HEARTBEAT, SCENE_GET and
SCENE, ASSET_GET and ASSET, TASK, ERROR, DISCONNECT) except the values of a RESULT, which it
alters by a policy. The farm sees a worker that traces like any other (its scene fetches,
timings, CPU seconds and horizons are the real worker's) and whose pixels are sometimes
wrong: the hardest liar to tell from an honest worker.

The real worker connects without CURVE to a ROUTER this proxy binds on loopback; the proxy
connects to the farm with a DEALER, with its own CURVE key pair where the farm asks for
keys, so that each liar is a principal of its own (proto/wire.md, section 11).

Policies (what a RESULT's values become):
- `grey`: every value 0.5;
- `subtle`: `SUBTLE_PIXELS` pixels a task, spread over it, get +0.25 on red;
- `honest_then_lying`: honest for its first `HONEST_TASKS` tasks (past the farm's probation,
  and on as many jobs as that takes), subtle after;
- `honest_on_checks`: subtle on a task that does not look like a check; on one that does,
  honest but for its colluders' lies, which it sends back as they sent them (it adds none of
  its own). A task looks like a check when its pixel set is scattered (many short spans),
  when its window is 0 on a job whose other tasks had a window (exact, search: a check wants
  no horizons), or when it comes for a frame of the job that a colluder was already given.

Liars that share a `Collusion` collude: each tells the others which values it altered, and
one given those pixels later (a check, a repair) sends the same altered values, so that a
check by a colluder agrees with the lie. Only the coordinator's own referee is beyond them.

Every loop is bounded by a stop flag and a poll timeout; `stop` ends the worker process,
closes the sockets and terms the context."""
import array
import pathlib
import shutil
import signal
import subprocess
import sys
import threading

import msgpack
import zmq

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))
from farm_harness import WORKER  # noqa: E402
from test_asset_fetch import ERROR, RESULT, TASK  # noqa: E402

POLICIES = ("grey", "subtle", "honest_then_lying", "honest_on_checks")
SUBTLE_PIXELS = 3
SUBTLE_RED = 0.25
GREY = 0.5
HONEST_TASKS = 16
# A pixel set of at least this many spans whose mean span is at most SCATTERED_MEAN_SPAN
# pixels is a sample, not a region: a check.
SCATTERED_SPANS = 4
SCATTERED_MEAN_SPAN = 2.0
POLL_MS = 50


def read_key(path):
    """The key in a key file as keygen writes it (lines starting with # are comments)."""
    [key] = [line.strip() for line in pathlib.Path(path).read_text().splitlines()
             if line.strip() and not line.startswith("#")]
    return key


def spans_of(payload):
    values = array.array("I")
    values.frombytes(payload)
    if sys.byteorder != "little":
        values.byteswap()
    return list(zip(values[0::2], values[1::2]))


class Collusion:
    """What colluding liars share: the frames of each job any of them was given, and the
    values any of them altered (by job, frame and pixel)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.frames_given = set()  # (job, frame)
        self.lies = {}  # (job, frame) -> {pixel: (r, g, b)}

    def given(self, job, frame):
        """Records that a colluder was given a task of this frame; says whether one was before."""
        with self.lock:
            seen = (job, frame) in self.frames_given
            self.frames_given.add((job, frame))
            return seen

    def told(self, job, frame):
        with self.lock:
            return dict(self.lies.get((job, frame), {}))

    def tell(self, job, frame, altered):
        with self.lock:
            self.lies.setdefault((job, frame), {}).update(altered)


class LiarProxy:
    """A real worker process behind a proxy that alters its RESULT values by `policy`.

    farm_endpoint: the coordinator's ZeroMQ endpoint. curve: (this liar's secret key file,
    the coordinator's public key file), or None without keys. directory: where the worker's
    log goes. collusion: a Collusion shared with the other liars, or None to lie alone."""

    def __init__(self, farm_endpoint, policy, name, directory, curve=None, collusion=None,
                 threads=1, subtle_pixels=SUBTLE_PIXELS, honest_tasks=HONEST_TASKS):
        assert policy in POLICIES, policy
        self.farm_endpoint, self.policy, self.name = farm_endpoint, policy, name
        self.directory = pathlib.Path(directory)
        self.curve, self.threads = curve, threads
        self.collusion = collusion or Collusion()
        self.subtle_pixels, self.honest_tasks = subtle_pixels, honest_tasks
        self.public_key = zmq.curve_public(read_key(curve[0]).encode()).decode() if curve else None
        self.lock = threading.Lock()
        # Figures, by job id where they are per job.
        self.tasks_answered = 0
        self.tasks_by_job = {}
        self.lies_by_job = {}  # tasks whose values it altered
        self.altered_by_job = {}  # pixels whose values it altered
        self.checks_spared = 0  # tasks that looked like checks: answered with no lie of its own
        self.messages = {"to_farm": 0, "to_worker": 0}
        self.task_shapes = []  # (job, frame, window, spans, pixels), the first few hundred
        self.tasks = {}  # task id -> its TASK header and spans, until answered
        self.windowed_jobs = set()
        self.worker_identity = None
        self.stopping = threading.Event()
        self.context = zmq.Context()
        self.router = self.context.socket(zmq.ROUTER)
        self.router.linger = 0
        self.router.bind("tcp://127.0.0.1:*")
        self.endpoint = self.router.getsockopt(zmq.LAST_ENDPOINT).decode()
        self.dealer = self.context.socket(zmq.DEALER)
        self.dealer.linger = 0
        if curve:
            secret = read_key(curve[0]).encode()
            self.dealer.curve_secretkey = secret
            self.dealer.curve_publickey = zmq.curve_public(secret)
            self.dealer.curve_serverkey = read_key(curve[1]).encode()
        self.dealer.connect(farm_endpoint)
        self.thread = threading.Thread(target=self.run, daemon=True, name=f"proxy-{name}")
        self.worker = None
        self.failure = None

    @property
    def principal(self):
        return "key:" + self.public_key if self.public_key else None

    def start(self):
        self.thread.start()
        self.log = open(self.directory / f"{self.name}.log", "w")
        self.worker = subprocess.Popen(
            [str(WORKER), "serve", "--coordinator", self.endpoint, "--threads", str(self.threads),
             "--name", self.name], stdout=subprocess.DEVNULL, stderr=self.log)
        return self

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def altered(self, job_id):
        with self.lock:
            return self.altered_by_job.get(job_id, 0)

    def figures(self, job_id=None):
        with self.lock:
            if job_id is None:
                return {"tasks": self.tasks_answered, "lies": sum(self.lies_by_job.values()),
                        "altered_pixels": sum(self.altered_by_job.values()), "checks_spared": self.checks_spared}
            return {"tasks": self.tasks_by_job.get(job_id, 0), "lies": self.lies_by_job.get(job_id, 0),
                    "altered_pixels": self.altered_by_job.get(job_id, 0), "checks_spared": self.checks_spared}

    # -- the proxy's loop

    def run(self):
        poller = zmq.Poller()
        poller.register(self.router, zmq.POLLIN)
        poller.register(self.dealer, zmq.POLLIN)
        try:
            while not self.stopping.is_set():
                ready = dict(poller.poll(POLL_MS))
                if self.router in ready:
                    for _ in range(256):  # drain a burst, bounded
                        try:
                            frames = self.router.recv_multipart(zmq.NOBLOCK)
                        except zmq.Again:
                            break
                        self.from_worker(frames)
                if self.dealer in ready:
                    for _ in range(256):
                        try:
                            frames = self.dealer.recv_multipart(zmq.NOBLOCK)
                        except zmq.Again:
                            break
                        self.from_farm(frames)
        except zmq.ContextTerminated:
            pass
        except Exception as failure:  # reported by stop(): a broken proxy must fail its test
            self.failure = failure

    def from_worker(self, frames):
        identity, message = frames[0], frames[1:]
        self.worker_identity = identity
        if len(message) == 4 and len(message[1]) == 1:
            command = message[1][0]
            if command == RESULT:
                message = self.answer(message)
            elif command == ERROR:
                self.tasks.pop(msgpack.unpackb(message[2]).get("task_id"), None)
        self.send(self.dealer, message)
        self.messages["to_farm"] += 1

    def from_farm(self, message):
        if len(message) == 4 and len(message[1]) == 1 and message[1][0] == TASK:
            header = msgpack.unpackb(message[2])
            spans = spans_of(message[3])
            seen_before = self.collusion.given(header["job_id"], header["frame"])
            self.tasks[header["task_id"]] = (header, spans, seen_before)
            if header["window"] > 0:
                self.windowed_jobs.add(header["job_id"])
            if len(self.task_shapes) < 400:
                self.task_shapes.append((header["job_id"], header["frame"], header["window"], len(spans),
                                         sum(e - b for b, e in spans)))
        if self.worker_identity is not None:
            self.send(self.router, [self.worker_identity, *message])
            self.messages["to_worker"] += 1

    @staticmethod
    def send(socket, frames):
        try:
            socket.send_multipart(frames, zmq.NOBLOCK)
        except zmq.Again:
            pass  # as a full queue on a real connection would

    # -- the lie

    def looks_like_check(self, header, spans, seen_before):
        pixels = sum(end - begin for begin, end in spans)
        scattered = len(spans) >= SCATTERED_SPANS and pixels / len(spans) <= SCATTERED_MEAN_SPAN
        unwindowed = header["window"] == 0 and header["job_id"] in self.windowed_jobs
        return scattered or unwindowed or seen_before

    def answer(self, message):
        header = msgpack.unpackb(message[2])
        task = self.tasks.pop(header.get("task_id"), None)
        if task is None:
            return message  # not a task it saw given (a stale reply): the farm ignores it anyway
        task_header, spans, seen_before = task
        job, frame = task_header["job_id"], task_header["frame"]
        with self.lock:
            answered = self.tasks_answered
            self.tasks_answered += 1
            self.tasks_by_job[job] = self.tasks_by_job.get(job, 0) + 1
        if self.policy == "grey":
            lie = "grey"
        elif self.policy == "subtle":
            lie = "subtle"
        elif self.policy == "honest_then_lying":
            lie = "subtle" if answered >= self.honest_tasks else None
        else:
            lie = "echo" if self.looks_like_check(task_header, spans, seen_before) else "subtle"
            if lie == "echo":
                with self.lock:
                    self.checks_spared += 1
        if lie is None:
            return message
        count = header["pixel_count"]
        rgb = array.array("f")
        rgb.frombytes(message[3][:12 * count])
        if sys.byteorder != "little":
            rgb.byteswap()
        pixels = [p for begin, end in spans for p in range(begin, end)]
        if len(pixels) != count:
            return message  # malformed by the worker itself: not this liar's business
        before = rgb.tobytes()
        if lie == "grey":
            for i in range(3 * count):
                rgb[i] = GREY
        else:
            told = self.collusion.told(job, frame)  # a colluder's lies on these pixels: the same
            for i, pixel in enumerate(pixels):
                if pixel in told:
                    rgb[3 * i:3 * i + 3] = array.array("f", told[pixel])
            k = min(self.subtle_pixels, count) if lie == "subtle" else 0
            mine = {}
            for j in range(k):
                i = (2 * j + 1) * count // (2 * k)  # spread over the task
                if pixels[i] in told:
                    continue
                rgb[3 * i] += SUBTLE_RED
                mine[pixels[i]] = tuple(rgb[3 * i:3 * i + 3])
            self.collusion.tell(job, frame, mine)
        after = rgb.tobytes()
        altered = sum(before[12 * i:12 * i + 12] != after[12 * i:12 * i + 12] for i in range(count))
        if altered:
            with self.lock:
                self.lies_by_job[job] = self.lies_by_job.get(job, 0) + 1
                self.altered_by_job[job] = self.altered_by_job.get(job, 0) + altered
        if sys.byteorder != "little":
            rgb.byteswap()
        return [message[0], message[1], message[2], rgb.tobytes() + message[3][12 * count:]]

    # -- the end

    def stop(self):
        """Ends the worker (SIGTERM, then SIGKILL after 10 s), then the proxy's loop, sockets
        and context. Raises what broke the proxy's loop, if anything did."""
        if self.worker and self.worker.poll() is None:
            self.worker.send_signal(signal.SIGTERM)
            try:
                self.worker.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.worker.kill()
                self.worker.wait()
        self.stopping.set()
        if self.thread.is_alive():
            self.thread.join(timeout=10)
        if not self.thread.is_alive():
            self.router.close()
            self.dealer.close()
            self.context.term()
        if getattr(self, "log", None):
            self.log.close()
            self.log = None
        if self.failure:
            raise RuntimeError(f"the proxy of {self.name} failed") from self.failure


def start_colluding_liars(endpoint, keys, directory, count, policy):
    """`count` liars of one Collusion, each with a key of its own added to the farm's
    allow-list (keys: test_worker_auth's `keys`), started and connected to `endpoint`."""
    from test_worker_auth import keygen  # the test files' key maker
    collusion, liars = Collusion(), []
    for index in range(count):
        name = f"liar-{index + 1}"
        secret, public = keygen(WORKER, directory / name, name)
        shutil.copy(public, keys["allowed"] / f"{name}.pub")
        liar = LiarProxy(endpoint, policy, name, directory, curve=(secret, keys["public"]), collusion=collusion)
        assert liar.principal == "key:" + read_key(public)
        liars.append(liar.start())
    return liars
