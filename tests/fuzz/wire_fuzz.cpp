// libFuzzer harness: wire::Decode over the four parts cut from the input (fuzz_input.h).
// The daemons catch only WireError around Decode, so any other exception escaping here is
// a crash of a coordinator or worker loop, and the harness lets it abort.
#include <cstddef>
#include <cstdint>
#include <variant>

#include "fuzz_input.h"
#include "proto/wire/wire.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = tcfarm::fuzz::SplitIntoParts(data, size, tcfarm::wire::kPartCount);
  try {
    const tcfarm::wire::Message message = tcfarm::wire::Decode(parts);
    // A decoded message must encode again: the receiver may forward or log it.
    std::visit([](const auto& decoded) { (void)tcfarm::wire::Encode(decoded); }, message);
  } catch (const tcfarm::wire::WireError&) {
  }
  return 0;
}
