"""One import budget for the coordinator (--import-budget-mib): eight meshopt decompression
bombs checked at once (POST /api/v1/scenes/check) are each answered 4xx or 503 with
Retry-After, never 500, and the coordinator's peak resident memory grows by no more than the
budget and a fixed margin; a glTF file whose JSON nests deeper than any JSON the farm reads is
refused naming where, at no cost in memory. The coordinator's VmHWM and VmRSS are read from
/proc."""
import base64
import concurrent.futures
import json
import struct
import urllib.error
import urllib.request

import pytest

from farm_harness import LocalFarm, memory_bytes, reset_peak

MIB = 1 << 20
BUDGET_MIB = 512
# What the coordinator may hold beyond the budget and what it held before the bombs: the
# eight requests' bodies as the HTTP server reads them (2 MiB each, outside any import),
# the threads' stacks and malloc's arenas.
MARGIN_MIB = 64
BOMBS = 8


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    with LocalFarm(tmp_path_factory.mktemp("import-budget-farm"), workers=0,
                   coordinator_args=("--import-budget-mib", str(BUDGET_MIB))) as farm:
        yield farm






def meshopt_zeros(count, stride):
    """meshoptimizer's vertex codec (format 0) for `count` vertices of `stride` zero bytes:
    each block of vertices (at most 256, 8 KiB) codes each of its bytes as groups of 16 whose
    2-bit headers say "all zero" and which then hold no data; 32 zero bytes of tail give the
    first vertex. Zeros shrink 64 times at a stride of 12."""
    block = min(8192 // stride // 16 * 16, 256)
    data = bytearray([0xA0])
    for first in range(0, count, block):
        groups = (min(block, count - first) + 15) // 16
        data += bytes((groups + 3) // 4 * stride)
    return bytes(data) + bytes(max(stride, 32))


def glb(document, binary):
    """A GLB file: the JSON chunk (padded with spaces) and the BIN chunk (with zeros)."""
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    binary += bytes(-len(binary) % 4)
    chunks = struct.pack("<I", len(text)) + b"JSON" + text + struct.pack("<I", len(binary)) + b"BIN\0" + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def meshopt_bomb(vertices=3 * 1_400_000):
    """A 1.3 MiB GLB whose one primitive's positions (50 MiB of floats) are meshopt-compressed
    zeros: within the importer's per-file limits (decoded bytes up to 32 times the file's
    buffers, padded to that here), and about 250 MiB of memory to import. Its three indices
    name a vertex past the last, which the importer finds only once it has decoded and read
    every position: refused with 400, after all the memory a bomb takes."""
    compressed = meshopt_zeros(vertices, 12)
    decoded = 12 * vertices
    padded = compressed + bytes(max(0, (decoded - (16 << 20)) // 32 + (64 << 10) - len(compressed)))
    indices = struct.pack("<3I", 0, 1, vertices)
    meshopt = {"buffer": 0, "byteOffset": 0, "byteLength": len(compressed), "byteStride": 12, "count": vertices,
               "mode": "ATTRIBUTES"}
    document = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["EXT_meshopt_compression"],
        "extensionsRequired": ["EXT_meshopt_compression"],
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "buffers": [{"byteLength": len(padded) + len(indices)},
                    {"byteLength": decoded, "extensions": {"EXT_meshopt_compression": {"fallback": True}}}],
        "bufferViews": [{"buffer": 1, "byteLength": decoded, "byteStride": 12,
                         "extensions": {"EXT_meshopt_compression": meshopt}},
                        {"buffer": 0, "byteOffset": len(padded), "byteLength": len(indices)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": vertices,
                       "min": [0, 0, 0], "max": [0, 0, 0]},
                      {"bufferView": 1, "componentType": 5125, "type": "SCALAR", "count": 3}],
    }
    return glb(document, padded + indices)


def check(farm, name, data, timeout=120):
    """POST /api/v1/scenes/check of the file `data` named `name`: (status, headers, JSON answer)."""
    body = json.dumps({"scene_file": name, "scene_file_data": base64.b64encode(data).decode()}).encode()
    request = urllib.request.Request(f"{farm.url}/api/v1/scenes/check", data=body, method="POST",
                                     headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:
            return response.status, response.headers, json.loads(response.read())
    except urllib.error.HTTPError as error:
        return error.code, error.headers, json.loads(error.read())


def test_the_bomb_decodes_within_the_per_file_limits(farm):
    """Alone, the bomb is decoded and read to its last index: refused for that index, not for
    its size, so only the budget stands between eight of them and the coordinator's memory."""
    status, _, answer = check(farm, "bomb.glb", meshopt_bomb())
    assert status == 400, answer
    assert "indices below the vertex count" in answer["error"]["message"], answer
    assert farm.metric("tcfarm_import_reserved_peak_bytes") > 200 * MIB
    assert farm.metric("tcfarm_import_reserved_bytes") == 0


def test_eight_bombs_at_once_stay_within_the_budget_and_are_never_a_500(farm):
    bomb = meshopt_bomb()
    pid = farm.coordinator.pid
    before = reset_peak(pid)
    with concurrent.futures.ThreadPoolExecutor(BOMBS) as pool:
        answers = list(pool.map(lambda i: check(farm, f"bomb{i}.glb", bomb), range(BOMBS)))
    peak = memory_bytes(pid, "VmHWM")
    print(f"{BOMBS} meshopt bombs at once, --import-budget-mib {BUDGET_MIB}: VmRSS before {before / MIB:.0f} MiB, "
          f"VmHWM {peak / MIB:.0f} MiB; statuses {sorted(status for status, _, _ in answers)}")
    for status, headers, answer in answers:
        assert status != 500 and (400 <= status < 500 or status == 503), answer
        assert answer["error"]["status"] == status, answer
        if status == 400:
            assert "indices below the vertex count" in answer["error"]["message"], answer
        if status == 503:
            assert answer["error"]["code"] == "import_busy", answer
            assert headers["Retry-After"] == "2", dict(headers)
            assert "Retry-After" in answer["error"]["message"], answer
    assert peak - before <= (BUDGET_MIB + MARGIN_MIB) * MIB, f"VmHWM {peak / MIB:.0f} MiB"
    assert farm.metric("tcfarm_import_reserved_peak_bytes") <= BUDGET_MIB * MIB
    assert farm.metric("tcfarm_import_reserved_bytes") == 0
    assert farm.metric("tcfarm_import_budget_bytes") == BUDGET_MIB * MIB


def test_a_scene_larger_than_the_whole_budget_is_refused_at_once_with_413(farm):
    status, headers, answer = check(farm, "huge.glb", meshopt_bomb(vertices=3 * 5_000_000))
    assert status == 413, answer
    assert answer["error"]["code"] == "import_too_large", answer
    assert "--import-budget-mib 512" in answer["error"]["message"], answer
    assert "Retry-After" not in headers


def test_a_gltf_nested_a_million_levels_deep_is_refused_where_it_goes_too_deep(farm):
    deep = b'{"asset": {"version": "2.0"}, "extras": ' + b"[" * 1_000_000 + b"]" * 1_000_000 + b"}"
    pointer = "/extras" + "/0" * 127  # the 129th container: the root, extras, then arrays at index 0
    pid = farm.coordinator.pid
    check(farm, "deep.gltf", deep)  # the first request's own allocations (thread, buffers) aside
    before = memory_bytes(pid, "VmRSS")
    for _ in range(20):
        status, _, answer = check(farm, "deep.gltf", deep)
        assert status == 400, answer
        assert answer["error"] == {
            "status": 400, "code": "invalid_scene", "pointer": "/scene_file",
            "message": f"scene{pointer}: deep.gltf: objects and arrays nested deeper than 128 levels; "
                       "expected at most 128 levels"}, answer["error"]["message"][:300]
    grown = memory_bytes(pid, "VmRSS") - before
    print(f"20 glTF files nested 10^6 deep: VmRSS grew {grown / MIB:.1f} MiB")
    assert grown < 32 * MIB
