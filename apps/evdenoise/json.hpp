#pragma once
// A minimal JSON writer for `evdenoise --metrics`: one object, top-level members one per line, nested values
// inline. Non-finite numbers and empty optionals are written as null.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace evdenoise {

class JsonWriter {
 public:
  JsonWriter& begin_object();
  JsonWriter& end_object();
  JsonWriter& begin_array();
  JsonWriter& end_array();
  /// The member name of the next value (inside an object).
  JsonWriter& key(std::string_view k);
  JsonWriter& value(std::string_view s);
  JsonWriter& value(const char* s) { return value(std::string_view(s)); }
  JsonWriter& value(double v);
  JsonWriter& value(std::uint64_t v);
  JsonWriter& value(std::int64_t v);
  JsonWriter& value(bool v);
  JsonWriter& value(const std::optional<double>& v);
  JsonWriter& null();
  /// A number when `text` is a finite JSON number as written, otherwise a string.
  JsonWriter& number_or_string(std::string_view text);

  [[nodiscard]] const std::string& str() const noexcept { return out_; }

 private:
  void before_value();
  std::string out_;
  std::vector<bool> first_;  // per open container: no member written yet
  bool after_key_ = false;
};

}  // namespace evdenoise
