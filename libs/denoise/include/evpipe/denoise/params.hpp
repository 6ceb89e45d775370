#pragma once
// KEY=VALUE filter parameters (`evdenoise --set KEY=VALUE`), read with validation.
//
// A filter's factory asks for each key with its default and a one-line help text; the same code path serves
// `--list-filters` (Params in describe mode records what was asked) so the list can never drift from the
// parser. Every error is a std::invalid_argument whose message names the filter, the key and the value:
//   "curvature: keep_fraction=1.5: must be in (0, 1]".

#include <cstdint>
#include <initializer_list>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace evpipe::denoise {

/// One parameter as `--list-filters` shows it.
struct ParamInfo {
  std::string key;
  std::string default_value;
  std::string help;
};

class Params {
 public:
  /// Values given by the user for the filter `filter_name`.
  Params(std::string filter_name, std::map<std::string, std::string, std::less<>> values);
  /// Describe mode: every get returns its default and is recorded in described().
  static Params describe(std::string filter_name);

  [[nodiscard]] double real(std::string_view key, double default_value, std::string_view help);
  [[nodiscard]] std::int64_t integer(std::string_view key, std::int64_t default_value, std::string_view help);
  [[nodiscard]] bool boolean(std::string_view key, bool default_value, std::string_view help);
  /// One of `choices` (the first is not implied to be the default).
  [[nodiscard]] std::string choice(std::string_view key, std::string_view default_value,
                                   std::initializer_list<std::string_view> choices, std::string_view help);

  /// Throws "<filter>: <key>=<value>: <why>" (the value as the user wrote it, or the default).
  [[noreturn]] void fail(std::string_view key, std::string_view why) const;
  /// Range checks that call fail() with a uniform message.
  void require_range(std::string_view key, double value, double lo, double hi, bool lo_open = false,
                     bool hi_open = false) const;
  void require_positive(std::string_view key, double value) const;

  /// Throws for keys the user gave that no get asked for, listing the known keys.
  void check_all_used() const;

  [[nodiscard]] const std::string& filter_name() const noexcept { return filter_; }
  [[nodiscard]] const std::vector<ParamInfo>& described() const noexcept { return described_; }
  [[nodiscard]] bool has(std::string_view key) const { return values_.find(key) != values_.end(); }

 private:
  const std::string* raw(std::string_view key, std::string_view default_text, std::string_view help);

  std::string filter_;
  std::map<std::string, std::string, std::less<>> values_;
  std::set<std::string, std::less<>> asked_;
  std::vector<ParamInfo> described_;
  bool describe_mode_ = false;
};

}  // namespace evpipe::denoise
