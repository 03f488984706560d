// `tcfarm-coordinator serve`: the coordinator daemon. With --local-workers N it is also
// the embedded local farm: it starts N workers on loopback itself.
#pragma once

#include <string>
#include <vector>

namespace tcfarm {

int RunServe(const std::vector<std::string>& args);

}  // namespace tcfarm
