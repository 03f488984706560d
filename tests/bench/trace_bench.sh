#!/usr/bin/env bash
# Shaded frames per second of the paper's three scenes at 640x480 on all cores.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
"$ROOT/scripts/build" > /dev/null
exec "$ROOT/build/worker/tracer_bench" --benchmark_min_time=2 "$@"
