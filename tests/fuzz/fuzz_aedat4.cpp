// libFuzzer target: the aedat4 reader on arbitrary bytes (see fuzz_reader.hpp for what counts as a finding).
#include "fuzz_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return evpipe::fuzz::run_reader(evpipe::io::make_aedat4_reader, data, size);
}
