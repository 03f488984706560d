#!/usr/bin/env bash
# Usage: check_exports.sh LIBRARY...
# Fails unless each library's dynamic symbol table defines only tcfarm::draco_codec's
# symbols (draco_codec.map): none of Draco's, nor the tinygltf and stb it carries.
set -euo pipefail
failed=0
for library in "$@"; do
  defined="$(nm -D --defined-only "$library" | awk '{print $3}' | c++filt)"
  [ -n "$defined" ] || { echo "$library: exports nothing"; failed=1; continue; }
  others="$(grep -v '^tcfarm::draco_codec::' <<< "$defined" || true)"
  if [ -n "$others" ]; then
    echo "$library exports more than tcfarm::draco_codec:"
    head -20 <<< "$others"
    failed=1
  else
    echo "$library: $(wc -l <<< "$defined") symbols, all tcfarm::draco_codec"
  fi
done
exit "$failed"
