// The memory this process may use: the machine's, or less where a control group (a
// container's or a pod's memory limit) caps it. Jobs are sized against it, so a
// coordinator in a pod limited to 8 GiB on a 64 GiB node does not accept jobs that would
// have it killed.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

namespace tcfarm {

// min(physical memory, the cgroup v2 `memory.max` or v1 `memory/memory.limit_in_bytes`
// found under cgroupRoot, when it is a number). nullopt when the machine's is unknown.
std::optional<uint64_t> UsableMemoryBytes(const std::filesystem::path& cgroupRoot = "/sys/fs/cgroup");

}  // namespace tcfarm
