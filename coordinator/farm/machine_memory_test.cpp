#include "coordinator/farm/machine_memory.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

namespace tcfarm {
namespace {

std::filesystem::path FreshRoot(const char* name) {
  auto root = std::filesystem::temp_directory_path() /
              ("tcfarm_cgroup_" + std::string(name) + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(root);
  std::filesystem::create_directories(root / "memory");
  return root;
}

TEST(MachineMemoryTest, AControlGroupLimitCapsTheMachinesMemory) {
  const std::optional<uint64_t> machine = UsableMemoryBytes(FreshRoot("none"));  // no limit files
  ASSERT_TRUE(machine.has_value());
  EXPECT_GT(*machine, uint64_t{64} << 20);

  auto v2 = FreshRoot("v2");
  std::ofstream(v2 / "memory.max") << "8589934592\n";  // 8 GiB, as a pod's limit
  EXPECT_EQ(UsableMemoryBytes(v2), std::min(*machine, uint64_t{8} << 30));
  std::ofstream(v2 / "memory.max") << "max\n";  // no limit
  EXPECT_EQ(UsableMemoryBytes(v2), machine);

  auto v1 = FreshRoot("v1");
  std::ofstream(v1 / "memory" / "memory.limit_in_bytes") << "1073741824\n";
  EXPECT_EQ(UsableMemoryBytes(v1), std::min(*machine, uint64_t{1} << 30));
  // v1's "no limit" is a huge number: the machine's memory wins.
  std::ofstream(v1 / "memory" / "memory.limit_in_bytes") << "9223372036854771712\n";
  EXPECT_EQ(UsableMemoryBytes(v1), machine);
  for (const char* name : {"none", "v2", "v1"}) {
    std::filesystem::remove_all(std::filesystem::temp_directory_path() /
                                ("tcfarm_cgroup_" + std::string(name) + "_" + std::to_string(getpid())));
  }
}

}  // namespace
}  // namespace tcfarm
