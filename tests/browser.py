"""Headless Chromium driven over the Chrome DevTools Protocol, for tests that use a page as a
person does: open it, click its buttons, type into its fields, choose files, wait for what
it shows, and take screenshots. Debian's chromium, no browser download; the protocol's
WebSocket through websocket-client (tests/requirements.txt).

    with Browser(tmp_path, width=420) as page:
        page.goto(url)
        page.click("#action-retry")
        page.wait_for("document.querySelector('#jobs tbody tr') !== null")
"""
import base64
import json
import pathlib
import shutil
import subprocess
import time
import urllib.request

import pytest

websocket = pytest.importorskip("websocket", reason="websocket-client: run scripts/bootstrap")

# What a wait gives the page before a test fails: a live farm, a page polling it.
DEFAULT_TIMEOUT_S = 30


def chromium_binary():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.fail("no chromium: run scripts/bootstrap (installs Debian's chromium)")


class PageError(AssertionError):
    """What the page did wrong: an uncaught exception in it, or a wait that timed out."""


class Browser:
    def __init__(self, profile, width=1280, height=900, webgl=False):
        """webgl: WebGL2 in software (SwiftShader through ANGLE), for pages that render
        with it; otherwise the GPU is off."""
        self.width, self.height = width, height
        self.profile = pathlib.Path(profile)
        self.profile.mkdir(parents=True, exist_ok=True)
        graphics = (["--use-angle=swiftshader", "--enable-unsafe-swiftshader"] if webgl
                    else ["--disable-gpu"])
        self.process = subprocess.Popen(
            [chromium_binary(), "--headless", "--no-sandbox", *graphics,
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--no-first-run", "--no-default-browser-check", f"--user-data-dir={profile}",
             f"--window-size={width},{height}", "--remote-debugging-port=0",
             "--remote-allow-origins=*", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=open(self.profile / "chromium.log", "w"))
        try:
            port = self._devtools_port()
            page = next(target for target in self._targets(port) if target["type"] == "page")
            self.socket = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60,
                                                      suppress_origin=True)
        except Exception:
            self.close()
            raise
        self.next_id = 0
        self.events = []       # protocol events not yet looked at
        self.exceptions = []   # uncaught exceptions the page threw
        self.console = []      # (level, text) of console messages
        for domain in ("Page", "Runtime", "DOM"):
            self.send(f"{domain}.enable")
        self.send("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    def _devtools_port(self, timeout=30):
        """Chromium writes the port it chose into the profile's DevToolsActivePort."""
        deadline = time.monotonic() + timeout
        active = self.profile / "DevToolsActivePort"
        while time.monotonic() < deadline:
            if active.exists():
                first = active.read_text().split("\n", 1)[0].strip()
                if first.isdigit():
                    return int(first)
            if self.process.poll() is not None:
                break
            time.sleep(0.05)
        log = (self.profile / "chromium.log").read_text()[-2000:]
        raise RuntimeError(f"chromium did not open its DevTools port:\n{log}")

    @staticmethod
    def _targets(port):
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as response:
            return json.loads(response.read())

    # --- the protocol ---------------------------------------------------------------------

    def send(self, method, **params):
        self.next_id += 1
        ident = self.next_id
        self.socket.send(json.dumps({"id": ident, "method": method, "params": params}))
        while True:
            message = self._receive()
            if message.get("id") == ident:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})

    def _receive(self):
        message = json.loads(self.socket.recv())
        if "method" in message:
            params = message.get("params", {})
            if message["method"] == "Runtime.exceptionThrown":
                details = params.get("exceptionDetails", {})
                self.exceptions.append(details.get("exception", {}).get("description")
                                       or details.get("text"))
            elif message["method"] == "Runtime.consoleAPICalled":
                text = " ".join(str(arg.get("value", arg.get("description", ""))) for arg in params.get("args", []))
                self.console.append((params.get("type"), text))
            self.events.append(message)
        return message

    def _wait_for_event(self, method, timeout=DEFAULT_TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while True:
            for index, event in enumerate(self.events):
                if event["method"] == method:
                    return self.events.pop(index)
            if time.monotonic() > deadline:
                raise PageError(f"no {method} in {timeout} s")
            self.socket.settimeout(max(0.05, deadline - time.monotonic()))
            try:
                self._receive()
            except websocket.WebSocketTimeoutException:
                pass
            finally:
                self.socket.settimeout(60)

    # --- what a test does -----------------------------------------------------------------

    def goto(self, url):
        self.events = [event for event in self.events if event["method"] != "Page.loadEventFired"]
        self.send("Page.navigate", url=url)
        self._wait_for_event("Page.loadEventFired")

    def reload(self):
        self.events = [event for event in self.events if event["method"] != "Page.loadEventFired"]
        self.send("Page.reload", ignoreCache=True)
        self._wait_for_event("Page.loadEventFired")

    def evaluate(self, expression):
        """The value of a JavaScript expression in the page (promises awaited)."""
        result = self.send("Runtime.evaluate", expression=expression, awaitPromise=True,
                           returnByValue=True)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            raise PageError(f"{expression!r} threw: "
                            f"{details.get('exception', {}).get('description') or details.get('text')}")
        return result["result"].get("value")

    def wait_for(self, expression, timeout=DEFAULT_TIMEOUT_S, what=None):
        """Waits until the expression is truthy in the page; returns its value."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                value, error = self.evaluate(expression), ""
            except PageError as e:  # a page being loaded has not got there yet
                value, error = None, f" (last: {e})"
            if value:
                return value
            if time.monotonic() > deadline:
                raise PageError(f"{what or expression} did not happen in {timeout} s{error}")
            self.pump(0.05)

    def pump(self, seconds):
        """Lets the page run for a while, taking the protocol's events as they come."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.socket.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                self._receive()
            except websocket.WebSocketTimeoutException:
                pass
        self.socket.settimeout(60)

    def text(self, selector):
        return self.evaluate(f"(document.querySelector({json.dumps(selector)}) || {{}}).textContent")

    def click(self, selector, attempts=3):
        """A mouse click at the middle of the element, as a person makes it: the element must
        be on screen, enabled and not covered by another one. A page that moved between
        finding the element and the click (a list that grew above it) is clicked again."""
        for _ in range(attempts):
            x, y = self._click_point(selector)
            self.send("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y)
            for kind in ("mousePressed", "mouseReleased"):
                self.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)
            # true: it got the click; undefined: a new document, which the click opened.
            if self.evaluate("window.__clickedTarget") is not False:
                return
            self.pump(0.1)
        raise PageError(f"the clicks at {selector} went elsewhere: the page kept moving")

    def _click_point(self, selector, timeout=DEFAULT_TIMEOUT_S):
        """Where to click the element, once it stays put for 100 ms."""
        deadline = time.monotonic() + timeout
        last = None
        while True:
            point = self.evaluate(f"""(() => {{
                const node = document.querySelector({json.dumps(selector)});
                if (!node) return "missing";
                node.scrollIntoView({{block: "center", inline: "center"}});
                const box = node.getBoundingClientRect();
                if (box.width === 0 || box.height === 0) return "hidden";
                if (node.disabled) return "disabled";
                const x = box.left + box.width / 2, y = box.top + box.height / 2;
                const top = document.elementFromPoint(x, y);
                if (top !== node && !node.contains(top)) return "covered by " + (top ? top.outerHTML.slice(0, 80) : "nothing");
                window.__clickedTarget = false;
                node.addEventListener("click", () => {{ window.__clickedTarget = true; }}, {{once: true, capture: true}});
                return [x, y];
            }})()""")
            if not isinstance(point, list):
                raise PageError(f"cannot click {selector}: {point}")
            if point == last:
                return point
            if time.monotonic() > deadline:
                raise PageError(f"{selector} kept moving for {timeout} s")
            last = point
            self.pump(0.1)

    def type(self, selector, text, clear=True):
        """Focuses the field by a click and types into it (replacing what it held)."""
        self.click(selector)
        if clear:
            self.evaluate(f"document.querySelector({json.dumps(selector)}).select()")
            self.send("Input.dispatchKeyEvent", type="keyDown", key="Backspace", code="Backspace",
                      windowsVirtualKeyCode=8)
            self.send("Input.dispatchKeyEvent", type="keyUp", key="Backspace", code="Backspace",
                      windowsVirtualKeyCode=8)
        if text:
            self.send("Input.insertText", text=str(text))

    def choose(self, selector, value):
        """Picks an option of a <select>, as the keyboard or the list would, with its events."""
        found = self.evaluate(f"""(() => {{
            const select = document.querySelector({json.dumps(selector)});
            if (!select || ![...select.options].some((o) => o.value === {json.dumps(value)})) return false;
            select.focus();
            select.value = {json.dumps(value)};
            select.dispatchEvent(new Event("input", {{bubbles: true}}));
            select.dispatchEvent(new Event("change", {{bubbles: true}}));
            return true;
        }})()""")
        if not found:
            raise PageError(f"{selector} has no option {value!r}")

    def set_files(self, selector, paths):
        """Chooses files in an <input type=file>, as the file dialog would."""
        document = self.send("DOM.getDocument", depth=0)
        node = self.send("DOM.querySelector", nodeId=document["root"]["nodeId"], selector=selector)
        if not node.get("nodeId"):
            raise PageError(f"no {selector}")
        self.send("DOM.setFileInputFiles", nodeId=node["nodeId"], files=[str(p) for p in paths])

    def screenshot(self, path, full_page=True):
        """A PNG of the page: the whole of it, or what the window shows."""
        params = {"format": "png"}
        if full_page:
            metrics = self.send("Page.getLayoutMetrics")
            size = metrics.get("cssContentSize") or metrics["contentSize"]
            params.update(captureBeyondViewport=True, clip={
                "x": 0, "y": 0, "width": max(self.width, size["width"]), "height": size["height"],
                "scale": 1})
        data = self.send("Page.captureScreenshot", **params)["data"]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self):
        try:
            if getattr(self, "socket", None):
                self.socket.close()
        finally:
            if self.process.poll() is None:
                self.process.terminate()
                try:
                    self.process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
