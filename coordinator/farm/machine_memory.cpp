#include "coordinator/farm/machine_memory.h"

#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <string>

namespace tcfarm {
namespace {

// A limit file's number; nullopt for "max" (no limit), a missing file or anything else.
std::optional<uint64_t> LimitIn(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text.empty() || !std::all_of(text.begin(), text.end(), ::isdigit) || text.size() > 19) {
    return std::nullopt;
  }
  return std::stoull(text);
}

}  // namespace

std::optional<uint64_t> UsableMemoryBytes(const std::filesystem::path& cgroupRoot) {
  const long pages = sysconf(_SC_PHYS_PAGES), pageSize = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || pageSize <= 0) return std::nullopt;
  uint64_t usable = static_cast<uint64_t>(pages) * static_cast<uint64_t>(pageSize);
  for (const auto& file : {cgroupRoot / "memory.max", cgroupRoot / "memory" / "memory.limit_in_bytes"}) {
    if (std::optional<uint64_t> limit = LimitIn(file)) usable = std::min(usable, *limit);
  }
  return usable;
}

}  // namespace tcfarm
