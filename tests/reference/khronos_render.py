"""Reference renders of glTF files by the Khronos glTF Sample Renderer, the engine of the
Khronos glTF Sample Viewer (npm @khronosgroup/gltf-viewer, pinned in package.json here),
run in Debian's headless Chromium with WebGL2 in software (SwiftShader).

The renderer is set up to shade the way the tracer's glTF comparison needs: the file's
KHR_lights_punctual lights (or one given directional light) taken as they are, no
image-based lighting (a black environment), no tone mapping, exposure 1. What comes back is
the linear radiance of each pixel as a float, not the canvas's 8-bit gamma-2.2 values.

    python3 tests/reference/khronos_render.py FILE.gltf --size 256x192 --out out.png

    from khronos_render import KhronosRenderer, render
    pixels = render("scene.gltf", 256, 192)          # float32 H x W x 3, linear, top row first
    with KhronosRenderer() as renderer:              # one browser for many renders
        pixels, alpha = renderer.render_rgba("scene.gltf", 256, 192)

Needs `npm ci --prefix tests/reference` (scripts/bootstrap runs it) and chromium.
"""
import argparse
import base64
import functools
import http.server
import json
import pathlib
import sys
import tempfile
import threading
import time
import urllib.parse

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # tests/: browser.py
sys.path.insert(0, str(HERE.parent / "gltf"))  # tests/gltf: make_gltf.py

from browser import Browser  # noqa: E402
from make_gltf import png_bytes  # noqa: E402

MODULE = "node_modules/@khronosgroup/gltf-viewer/dist/gltf-viewer.module.js"

# Changes to the renderer's module as it is served, each (what, by what, how many times, why).
# Each must match exactly as often as said, so that a new version of the package that moved
# them fails here rather than rendering something else.
MODULE_PATCHES = [
    # Loading an environment prefilters it for image-based lighting even with that off; at
    # the stock sample counts and sizes that takes minutes in software. The environment is
    # black, so the smallest sizes give the same (black) result.
    ("this.textureSize = 256;", "this.textureSize = 32;", 1, "IBL cube map size"),
    ("this.ggxSampleCount = 1024;", "this.ggxSampleCount = 1;", 1, "IBL GGX samples"),
    ("this.lambertianSampleCount = 2048;", "this.lambertianSampleCount = 1;", 1, "IBL Lambert samples"),
    ("this.sheenSamplCount = 64;", "this.sheenSamplCount = 1;", 1, "IBL sheen samples"),
    ("this.lutResolution = 1024;", "this.lutResolution = 16;", 1, "IBL BRDF lookup table size"),
    # The passes to the screen end in toneMap(), which (with ToneMaps.NONE) encodes with
    # x^(1/2.2) for the 8-bit canvas; alpha BLEND then blends those encoded values. With
    # LINEAR_OUTPUT, the renderer's own switch (its transmission pass uses it), the shader
    # writes linear radiance and blending happens in linear, as in the tracer.
    ("renderpassConfiguration.linearOutput = false;", "renderpassConfiguration.linearOutput = true;", 3,
     "linear output on the screen passes"),
]

RENDER_TIMEOUT_S = 300


@functools.lru_cache(maxsize=1)
def patched_module():
    text = (HERE / MODULE).read_text()
    for old, new, count, why in MODULE_PATCHES:
        found = text.count(old)
        if found != count:
            raise RuntimeError(f"{MODULE}: {why}: {old!r} occurs {found} times, not {count}: "
                               f"a different version of the renderer?")
        text = text.replace(old, new)
    return text.encode()


def black_hdr(width=16, height=8):
    """A Radiance .hdr panorama, all black (uncompressed scanlines of zero RGBE)."""
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n".encode()
    return header + bytes(4 * width * height)


# Files the page asks for that the package does not ship and no render looks at: the
# environment (black) and the sheen lookup table (used only by KHR_materials_sheen).
GENERATED = {
    "/generated/black.hdr": (black_hdr(), "application/octet-stream"),
    "/generated/lut_sheen_E.png": (png_bytes([[(0, 0, 0)]]), "image/png"),
}


class _Handler(http.server.BaseHTTPRequestHandler):
    """/reference/...: this folder (the page, the renderer); /asset/N/...: the folder of the
    N-th asset rendered; /generated/...: GENERATED."""
    server_version = "tcfarm-reference"

    def do_GET(self):
        path = urllib.parse.unquote(urllib.parse.urlsplit(self.path).path)
        if path in GENERATED:
            return self._send(*GENERATED[path])
        if path == "/reference/" + MODULE:
            return self._send(patched_module(), "text/javascript")
        file = self._resolve(path)
        if file is None or not file.is_file():
            return self.send_error(404)
        return self._send(file.read_bytes(), self._content_type(file))

    def _resolve(self, path):
        parts = path.lstrip("/").split("/")
        if parts[0] == "reference":
            root, rest = HERE, parts[1:]
        elif parts[0] == "asset" and len(parts) > 2 and parts[1].isdigit() and \
                int(parts[1]) < len(self.server.asset_roots):
            root, rest = self.server.asset_roots[int(parts[1])], parts[2:]
        else:
            return None
        file = (root / "/".join(rest)).resolve()
        return file if file.is_relative_to(root) else None

    @staticmethod
    def _content_type(file):
        return {".html": "text/html", ".js": "text/javascript", ".wasm": "application/wasm",
                ".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
                ".gltf": "model/gltf+json", ".glb": "model/gltf-binary"}.get(
            file.suffix.lower(), "application/octet-stream")

    def _send(self, body, content_type):
        self.send_response(200)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


class KhronosRenderer:
    """A local server and one headless Chromium with the renderer's page loaded, for as many
    renders as asked; close() (or the with block) ends both."""

    def __init__(self, profile=None):
        if not (HERE / MODULE).exists():
            raise RuntimeError(f"no {MODULE}: run `npm ci --prefix tests/reference` (scripts/bootstrap)")
        self._temp = None
        if profile is None:
            self._temp = tempfile.TemporaryDirectory(prefix="khronos-chromium-")
            profile = self._temp.name
        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
        self.server.asset_roots = []
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        self.base = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.browser = None
        try:
            self.browser = Browser(profile, width=320, height=240, webgl=True)
            self.browser.goto(f"{self.base}/reference/khronos_page.html")
            self.browser.wait_for("window.rendererReady === true", timeout=60,
                                  what="the renderer's module loading")
        except Exception:
            self.close()
            raise

    def render_rgba(self, gltf_path, width, height, camera=None, light=None):
        """(linear RGB float32 H x W x 3, alpha H x W), top row first. camera: {eye, target,
        yfov} instead of the file's first camera node; light: {direction, color, intensity},
        one directional light used when the file has none."""
        gltf_path = pathlib.Path(gltf_path).resolve()
        self.server.asset_roots.append(gltf_path.parent)
        url = f"/asset/{len(self.server.asset_roots) - 1}/{urllib.parse.quote(gltf_path.name)}"
        options = {"environment": "/generated/black.hdr", "sheenLut": "/generated/lut_sheen_E.png",
                   "camera": camera, "light": light}
        self.browser.socket.settimeout(RENDER_TIMEOUT_S)
        try:
            result = self.browser.send(
                "Runtime.evaluate", awaitPromise=True, returnByValue=True, expression=
                f"window.renderGltf({json.dumps(url)}, {int(width)}, {int(height)}, {json.dumps(options)})")
        finally:
            self.browser.socket.settimeout(60)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            raise RuntimeError(f"the renderer failed on {gltf_path}: "
                               f"{details.get('exception', {}).get('description') or details.get('text')}")
        if self.browser.exceptions:
            raise RuntimeError(f"the page threw while rendering {gltf_path}: {self.browser.exceptions}")
        errors = [text for level, text in self.browser.console if level == "error"]
        if errors:
            raise RuntimeError(f"the renderer reported errors on {gltf_path}: {errors}")
        value = result["result"]["value"]
        rgba = np.frombuffer(base64.b64decode(value["rgba"]), dtype=np.float32)
        rgba = rgba.reshape(height, width, 4)[::-1]  # WebGL reads the bottom row first
        return np.ascontiguousarray(rgba[..., :3]), np.ascontiguousarray(rgba[..., 3])

    def render(self, gltf_path, width, height, **kwargs):
        return self.render_rgba(gltf_path, width, height, **kwargs)[0]

    def close(self):
        if self.browser is not None:
            self.browser.close()
            self.browser = None
        self.server.shutdown()
        self.server.server_close()
        if self._temp is not None:
            self._temp.cleanup()
            self._temp = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def srgb_bytes(linear):
    """8-bit sRGB codes of linear values (clamped to [0, 1]), for looking at."""
    x = np.clip(linear, 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)


def write_png(path, linear):
    from PIL import Image
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(srgb_bytes(linear), "RGB").save(path)
    return path


def render(gltf_path, width, height, png_path=None, **kwargs):
    """Linear float32 H x W x 3 of one render (a browser started and ended for it); also
    writes an sRGB PNG of it to png_path (default: beside the file, NAME.khronos.png)."""
    with KhronosRenderer() as renderer:
        pixels = renderer.render(gltf_path, width, height, **kwargs)
    gltf_path = pathlib.Path(gltf_path)
    write_png(png_path or gltf_path.with_suffix(".khronos.png"), pixels)
    return pixels


def parse_size(text):
    width, _, height = text.lower().partition("x")
    return int(width), int(height)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("gltf", nargs="+", type=pathlib.Path)
    parser.add_argument("--size", type=parse_size, default=(256, 192), help="WxH (default 256x192)")
    parser.add_argument("--out", type=pathlib.Path,
                        help="PNG to write (one file) or folder (several); default beside each file")
    args = parser.parse_args(argv)
    width, height = args.size
    with KhronosRenderer() as renderer:
        for path in args.gltf:
            start = time.monotonic()
            pixels = renderer.render(path, width, height)
            seconds = time.monotonic() - start
            if args.out is None:
                png = path.with_suffix(".khronos.png")
            elif len(args.gltf) == 1 and args.out.suffix == ".png":
                png = args.out
            else:
                png = args.out / (path.stem + ".khronos.png")
            write_png(png, pixels)
            print(f"{path}: {seconds:.1f} s, mean linear RGB {pixels.reshape(-1, 3).mean(0).round(4)} -> {png}")


if __name__ == "__main__":
    main()
