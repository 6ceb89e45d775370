#include "evpipe/denoise/params.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace evpipe::denoise {

Params::Params(std::string filter_name, std::map<std::string, std::string, std::less<>> values)
    : filter_(std::move(filter_name)), values_(std::move(values)) {}

Params Params::describe(std::string filter_name) {
  Params p(std::move(filter_name), {});
  p.describe_mode_ = true;
  return p;
}

const std::string* Params::raw(std::string_view key, std::string_view default_text, std::string_view help) {
  asked_.emplace(key);
  if (describe_mode_) {
    described_.push_back({std::string(key), std::string(default_text), std::string(help)});
    return nullptr;
  }
  const auto it = values_.find(key);
  return it == values_.end() ? nullptr : &it->second;
}

void Params::fail(std::string_view key, std::string_view why) const {
  const auto it = values_.find(key);
  if (it != values_.end()) {
    throw std::invalid_argument(fmt::format("{}: {}={}: {}", filter_, key, it->second, why));
  }
  throw std::invalid_argument(fmt::format("{}: {}: {}", filter_, key, why));
}

double Params::real(std::string_view key, double default_value, std::string_view help) {
  const std::string* text = raw(key, fmt::format("{}", default_value), help);
  if (text == nullptr) {
    return default_value;
  }
  double v = 0.0;
  const char* end = text->data() + text->size();
  const auto [ptr, ec] = std::from_chars(text->data(), end, v);
  if (ec != std::errc{} || ptr != end || !std::isfinite(v)) {
    fail(key, "not a finite number");
  }
  return v;
}

std::int64_t Params::integer(std::string_view key, std::int64_t default_value, std::string_view help) {
  const std::string* text = raw(key, fmt::format("{}", default_value), help);
  if (text == nullptr) {
    return default_value;
  }
  std::int64_t v = 0;
  const char* end = text->data() + text->size();
  const auto [ptr, ec] = std::from_chars(text->data(), end, v);
  if (ec != std::errc{} || ptr != end) {
    fail(key, "not an integer");
  }
  return v;
}

bool Params::boolean(std::string_view key, bool default_value, std::string_view help) {
  const std::string* text = raw(key, default_value ? "true" : "false", help);
  if (text == nullptr) {
    return default_value;
  }
  if (*text == "true" || *text == "1" || *text == "yes" || *text == "on") {
    return true;
  }
  if (*text == "false" || *text == "0" || *text == "no" || *text == "off") {
    return false;
  }
  fail(key, "not a boolean (true/false)");
}

std::string Params::choice(std::string_view key, std::string_view default_value,
                           std::initializer_list<std::string_view> choices, std::string_view help) {
  const std::string joined = fmt::format("{}", fmt::join(choices, " | "));
  const std::string* text = raw(key, std::string(default_value), fmt::format("{} ({})", help, joined));
  if (text == nullptr) {
    return std::string(default_value);
  }
  for (const auto c : choices) {
    if (*text == c) {
      return *text;
    }
  }
  fail(key, fmt::format("must be one of {}", joined));
}

void Params::require_range(std::string_view key, double value, double lo, double hi, bool lo_open, bool hi_open) const {
  const bool ok_lo = lo_open ? value > lo : value >= lo;
  const bool ok_hi = hi_open ? value < hi : value <= hi;
  if (!ok_lo || !ok_hi) {
    fail(key, fmt::format("must be in {}{}, {}{}", lo_open ? "(" : "[", lo, hi, hi_open ? ")" : "]"));
  }
}

void Params::require_positive(std::string_view key, double value) const {
  if (!(value > 0.0)) {
    fail(key, "must be > 0");
  }
}

void Params::check_all_used() const {
  for (const auto& [key, value] : values_) {
    if (asked_.find(key) == asked_.end()) {
      throw std::invalid_argument(
          fmt::format("{}: unknown parameter '{}' (known: {})", filter_, key, fmt::join(asked_, ", ")));
    }
  }
}

}  // namespace evpipe::denoise
