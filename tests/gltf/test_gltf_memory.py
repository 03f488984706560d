"""Hostile glTF files through `tcfarm-worker render --print-scene` (the importer the
coordinator runs at submit): accessors claiming far more elements than their buffer views
hold are refused naming the accessor, and a large data URI is decoded in memory bounded by
a small multiple of the file's size. Each run's peak resident memory is read from the
kernel's accounting of that one process (wait4's ru_maxrss) and printed with its time."""
import base64
import json
import os
import struct
import subprocess
import sys
import time

import pytest

MIB = 1 << 20


# The kernel counts into a process's peak what the process it was forked from held before
# exec (and pytest holds the generated files): a small interpreter forks the importer
# afresh and reports that child's own peak from wait4.
MEASURE = """
import os, subprocess, sys
child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)
_, status, usage = os.wait4(child.pid, 0)
print(os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024)
"""


def run_measured(binary, path):
    """(exit status, stderr, peak RSS in bytes, seconds) of `render PATH --print-scene`."""
    start = time.monotonic()
    result = subprocess.run([sys.executable, "-c", MEASURE, str(binary), "render", str(path), "--print-scene"],
                            capture_output=True, text=True, timeout=600)
    seconds = time.monotonic() - start
    status, peak = map(int, result.stdout.split())
    print(f"{path.name}: {path.stat().st_size} bytes, peak RSS {peak / MIB:.1f} MiB, {seconds:.2f} s")
    return status, result.stderr, peak, seconds


def data_uri(data):
    return "data:application/octet-stream;base64," + base64.b64encode(data).decode()


def animated_node(buffer_uri_data, times_count=3):
    """The probe's file: key times and translations over a 36-byte view of buffer 0."""
    return {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"name": "mover"}],
        "buffers": [{"byteLength": len(buffer_uri_data), "uri": data_uri(buffer_uri_data)}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "type": "SCALAR", "count": times_count},
                      {"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": 3}],
        "animations": [{"samplers": [{"input": 0, "output": 1}],
                        "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]}],
    }


KEYS = struct.pack("<9f", 0, 1, 2, 0, 0, 0, 1, 1, 1)


@pytest.fixture(scope="module")
def baseline(worker_binary, tmp_path_factory):
    """The peak RSS of importing the 36-byte probe file as it should be."""
    path = tmp_path_factory.mktemp("base") / "small.gltf"
    path.write_text(json.dumps(animated_node(KEYS)))
    status, stderr, peak, _ = run_measured(worker_binary, path)
    assert status == 0, stderr
    return peak


@pytest.mark.parametrize("count", [2 ** 28, 2 ** 30, 2 ** 31])
def test_counts_past_the_view_are_refused_without_allocating(worker_binary, baseline, tmp_path, count):
    path = tmp_path / f"count_{count}.gltf"
    path.write_text(json.dumps(animated_node(KEYS, times_count=count)))
    status, stderr, peak, _ = run_measured(worker_binary, path)
    assert status != 0
    assert f"accessors/0/count: {path.name}: {count} elements; expected at most 60000000 elements" in stderr
    assert peak < baseline + 16 * MIB, f"peak {peak} bytes against {baseline} for a {path.stat().st_size}-byte file"


def test_large_data_uri_costs_a_small_multiple_of_the_file(worker_binary, baseline, tmp_path):
    # 48 MiB of buffer, 64 MiB of base64: the animation uses its first 36 bytes.
    path = tmp_path / "large_uri.gltf"
    path.write_text(json.dumps(animated_node(KEYS + bytes(48 * MIB))))
    size = path.stat().st_size
    status, stderr, peak, _ = run_measured(worker_binary, path)
    assert status == 0, stderr
    # The file's text, and its URI's bytes (3/4 of it) decoded once.
    assert peak < baseline + 2 * size, f"peak {peak} bytes against {baseline} for a {size}-byte file"


def test_bad_base64_in_a_large_uri_is_refused_without_echoing_it(worker_binary, baseline, tmp_path):
    gltf = animated_node(KEYS + bytes(8 * MIB))
    gltf["buffers"][0]["uri"] = gltf["buffers"][0]["uri"][:-8] + "!" + gltf["buffers"][0]["uri"][-7:]
    path = tmp_path / "bad_uri.gltf"
    path.write_text(json.dumps(gltf))
    status, stderr, peak, _ = run_measured(worker_binary, path)
    assert status != 0
    assert "character \"!\" in a data URI's base64; expected a data URI of base64" in stderr
    assert len(stderr) < 4096
    assert peak < baseline + 2 * path.stat().st_size


def test_one_accessor_named_by_many_meshes_is_refused(worker_binary, baseline, tmp_path):
    # 1.2 MB of positions, named by 400 meshes: 960 MB of values if each read were allowed.
    triangles = 100000 // 3
    positions = b"".join(struct.pack("<3f", i % 3 == 1, i % 3 == 2, i * 1e-3) for i in range(3 * triangles))
    meshes = 400
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(meshes))}],
        "nodes": [{"mesh": m} for m in range(meshes)],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]} for _ in range(meshes)],
        "buffers": [{"byteLength": len(positions), "uri": data_uri(positions)}],
        "bufferViews": [{"buffer": 0, "byteLength": len(positions)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": 3 * triangles}],
    }
    path = tmp_path / "shared_accessor.gltf"
    path.write_text(json.dumps(gltf))
    status, stderr, peak, _ = run_measured(worker_binary, path)
    assert status != 0
    assert "accessors/0: shared_accessor.gltf: reading it brings the values read" in stderr
    assert peak < baseline + 16 * len(positions) + 64 * MIB


@pytest.mark.parametrize("count", [2 ** 28, 2 ** 31])
def test_the_farm_answers_a_hostile_count_with_a_400_naming_the_accessor(count, tmp_path):
    """Through the farm as a user submits it: a clear 400 at submit, not a 500 or a stall."""
    from farm_harness import LocalFarm, tcfarm_cli
    path = tmp_path / f"count_{count}.gltf"
    path.write_text(json.dumps(animated_node(KEYS, times_count=count)))
    (tmp_path / "farm").mkdir()
    with LocalFarm(tmp_path / "farm", workers=0) as farm:
        result = tcfarm_cli(farm, "submit", path)
        print(result.stderr.strip())
        assert result.returncode != 0
        assert "(400)" in result.stderr and "accessors/0/count" in result.stderr, result.stderr
        assert farm.client.jobs() == []  # nothing queued
