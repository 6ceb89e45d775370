#pragma once
// The project's filters by name: what `evdenoise --filter`, `--list-filters` and the pipeline's config use.
//
//   auto f = make_filter_chain("hotpixel,curvature", {{"curvature.keep_fraction", "0.9"}}, kDavis346);

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/params.hpp"

namespace evpipe::denoise {

struct FilterSpec {
  std::string_view name;
  std::string_view summary;  ///< one line for --list-filters
  /// Reads the options from `params` (throws std::invalid_argument with a message naming the key) and builds
  /// the filter for a sensor of `geometry`. Must ask for every key it knows even when building in describe mode.
  std::function<std::unique_ptr<Filter>(Params& params, const SensorGeometry& geometry)> make;
};

/// Every filter, in --list-filters order.
const std::vector<FilterSpec>& filter_specs();
/// nullptr when unknown.
const FilterSpec* find_filter(std::string_view name) noexcept;
/// The parameters of a filter with their defaults and help (what the factory asks for).
std::vector<ParamInfo> describe(const FilterSpec& spec);

/// One filter with the given KEY=VALUE settings. Throws std::invalid_argument for an unknown filter (listing the
/// known ones), an unknown key or a bad value.
std::unique_ptr<Filter> make_filter(std::string_view name,
                                    const std::vector<std::pair<std::string, std::string>>& settings,
                                    const SensorGeometry& geometry);

/// A comma-separated chain ("hotpixel,curvature"): each event goes through the filters in order and is kept only
/// if every filter keeps it; a later filter sees only what the earlier ones kept. A setting applies to the one
/// filter of the chain that knows its key, or to a named one as `NAME.KEY=VALUE`; a key known to several filters
/// of the chain must be qualified. A chain of one is that filter itself.
std::unique_ptr<Filter> make_filter_chain(std::string_view spec,
                                          const std::vector<std::pair<std::string, std::string>>& settings,
                                          const SensorGeometry& geometry);

}  // namespace evpipe::denoise
