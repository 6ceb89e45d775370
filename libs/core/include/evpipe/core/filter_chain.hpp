#pragma once
// The stage names of a denoise chain as written ("hotpixel,curvature" → hotpixel, curvature). Shared by the
// denoise registry (which rejects an empty name), evdenoise and the run configuration (which does not depend on
// the denoise library).

#include <cstddef>
#include <string_view>
#include <vector>

namespace evpipe {

/// The comma-separated parts of `chain`, empty ones included ("a,,b" → a, "", b; "" → one empty name).
inline std::vector<std::string_view> filter_chain_names(std::string_view chain) {
  std::vector<std::string_view> names;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = chain.find(',', start);
    names.push_back(chain.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) return names;
    start = comma + 1;
  }
}

}  // namespace evpipe
