// libFuzzer target: the run-configuration parser (libs/config) on arbitrary bytes (issue 17). A finding is any
// exception other than ConfigError (a YAML exception escaping made evpipe abort), a crash, a hang, a leak, UB, or a
// broken invariant: an accepted configuration passes validate() and its printed form (to_yaml(), logged at start)
// loads again to the same configuration.
#include <cstddef>
#include <cstdint>
#include <string>

#include "evpipe/config/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  evpipe::config::RunConfig config;
  try {
    config = evpipe::config::parse_config(text, "fuzz.yaml");
  } catch (const evpipe::config::ConfigError&) {
    return 0;  // refused with a message: what a bad config must give
  }
  config.validate();  // throws (an uncaught exception: a finding) if the parser let an invalid value through
  const std::string printed = config.to_yaml();
  const auto again = evpipe::config::parse_config(printed, "printed.yaml");
  if (again.to_yaml() != printed) __builtin_trap();
  return 0;
}
