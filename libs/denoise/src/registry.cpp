#include "evpipe/denoise/registry.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <stdexcept>

#include "evpipe/core/filter_chain.hpp"
#include "evpipe/denoise/baf.hpp"
#include "evpipe/denoise/chain.hpp"
#include "evpipe/denoise/curvature.hpp"
#include "evpipe/denoise/dwf.hpp"
#include "evpipe/denoise/hotpixel.hpp"
#include "evpipe/denoise/knoise.hpp"
#include "evpipe/denoise/random_thinning.hpp"
#include "evpipe/denoise/significance.hpp"
#include "evpipe/denoise/stcf.hpp"
#include "evpipe/denoise/ynoise.hpp"

namespace evpipe::denoise {

const std::vector<FilterSpec>& filter_specs() {
  // One line per filter (kept so: one added line per new filter); each filter's header declares its spec.
  // clang-format off
  static const std::vector<FilterSpec> specs = {
      curvature_spec(),  // the paper's filter first
      significance_spec(),  // evpipe's pipeline default
      baf_spec(),
      knoise_spec(),
      ynoise_spec(),
      stcf_spec(),
      dwf_spec(),
      hotpixel_spec(),
      random_spec(),
  };
  // clang-format on
  return specs;
}

const FilterSpec* find_filter(std::string_view name) noexcept {
  for (const auto& s : filter_specs()) {
    if (s.name == name) {
      return &s;
    }
  }
  return nullptr;
}

std::vector<ParamInfo> describe(const FilterSpec& spec) {
  Params p = Params::describe(std::string(spec.name));
  (void)spec.make(p, kDavis346);
  return p.described();
}

namespace {

const FilterSpec& require_filter(std::string_view name) {
  if (const FilterSpec* s = find_filter(name)) {
    return *s;
  }
  std::vector<std::string_view> known;
  for (const auto& s : filter_specs()) {
    known.push_back(s.name);
  }
  throw std::invalid_argument(fmt::format("unknown filter '{}' (known: {})", name, fmt::join(known, ", ")));
}

bool knows(const FilterSpec& spec, std::string_view key) {
  const auto params = describe(spec);
  return std::any_of(params.begin(), params.end(), [&](const ParamInfo& p) { return p.key == key; });
}

std::vector<std::string_view> split_chain(std::string_view spec) {
  auto names = filter_chain_names(spec);
  if (std::any_of(names.begin(), names.end(), [](std::string_view n) { return n.empty(); })) {
    throw std::invalid_argument(fmt::format("filter chain '{}': empty filter name", spec));
  }
  if (names.size() > kMaxChainFilters) {
    throw std::invalid_argument(
        fmt::format("filter chain '{}': {} filters, at most {} (each may hold up to {} MiB "
                    "of per-pixel state)",
                    spec, names.size(), kMaxChainFilters, kMaxFilterStateBytes >> 20));
  }
  return names;
}

}  // namespace

std::unique_ptr<Filter> make_filter(std::string_view name,
                                    const std::vector<std::pair<std::string, std::string>>& settings,
                                    const SensorGeometry& geometry) {
  const FilterSpec& spec = require_filter(name);
  std::map<std::string, std::string, std::less<>> values;
  for (const auto& [key, value] : settings) {
    values[key] = value;
  }
  Params params(std::string(spec.name), std::move(values));
  check_pixel_budget(spec.name, geometry, 0);  // the sensor size; each filter checks its own per-pixel bytes
  std::unique_ptr<Filter> filter;
  try {
    filter = spec.make(params, geometry);
  } catch (const std::bad_alloc&) {
    throw std::invalid_argument(fmt::format("{}: out of memory allocating its state for a {}x{} sensor", spec.name,
                                            geometry.width, geometry.height));
  }
  params.check_all_used();
  return filter;
}

std::unique_ptr<Filter> make_filter_chain(std::string_view spec,
                                          const std::vector<std::pair<std::string, std::string>>& settings,
                                          const SensorGeometry& geometry) {
  const auto names = split_chain(spec);
  std::vector<const FilterSpec*> specs;
  for (const auto n : names) {
    specs.push_back(&require_filter(n));
  }
  std::vector<std::vector<std::pair<std::string, std::string>>> per_stage(specs.size());
  for (const auto& [key, value] : settings) {
    if (key.empty() || value.empty()) {
      throw std::invalid_argument(fmt::format("setting '{}={}': expected KEY=VALUE", key, value));
    }
    const std::size_t dot = key.find('.');
    if (dot != std::string::npos) {
      const std::string_view target = std::string_view(key).substr(0, dot);
      const std::string bare = key.substr(dot + 1);
      bool found = false;
      for (std::size_t i = 0; i < specs.size(); ++i) {
        if (specs[i]->name == target) {
          per_stage[i].emplace_back(bare, value);
          found = true;
        }
      }
      if (!found) {
        throw std::invalid_argument(
            fmt::format("setting '{}': filter '{}' is not in the chain '{}'", key, target, spec));
      }
      continue;
    }
    std::vector<std::size_t> owners;
    for (std::size_t i = 0; i < specs.size(); ++i) {
      if (knows(*specs[i], key)) {
        owners.push_back(i);
      }
    }
    if (owners.empty()) {
      // Let the (single) filter report it with its list of known keys.
      per_stage[specs.size() == 1 ? 0 : specs.size() - 1].emplace_back(key, value);
      if (specs.size() > 1) {
        throw std::invalid_argument(
            fmt::format("setting '{}': no filter of the chain '{}' has this parameter "
                        "(evdenoise --list-filters shows them)",
                        key, spec));
      }
      continue;
    }
    if (owners.size() > 1 && specs[owners.front()]->name != specs[owners.back()]->name) {
      throw std::invalid_argument(
          fmt::format("setting '{}': several filters of the chain '{}' have this parameter; write NAME.{}={}", key,
                      spec, key, value));
    }
    for (const std::size_t i : owners) {
      per_stage[i].emplace_back(key, value);
    }
  }
  std::vector<std::unique_ptr<Filter>> stages;
  for (std::size_t i = 0; i < specs.size(); ++i) {
    stages.push_back(make_filter(specs[i]->name, per_stage[i], geometry));
  }
  if (stages.size() == 1) {
    return std::move(stages.front());
  }
  return std::make_unique<FilterChain>(std::move(stages));
}

}  // namespace evpipe::denoise
