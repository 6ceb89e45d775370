// libFuzzer target: the aedat31 reader on arbitrary bytes (see fuzz_reader.hpp for what counts as a finding).
#include "fuzz_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return evpipe::fuzz::run_reader(evpipe::io::make_aedat31_reader, data, size);
}
