#include "evpipe/config/run_config.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>
#include <yaml-cpp/yaml.h>

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include "evpipe/core/event.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/core/filter_chain.hpp"

namespace evpipe::config {

namespace {

using Type = KeyInfo::Type;

/// One key: what it accepts (KeyInfo) and where it lives in RunConfig. Integers of any width go through int64.
struct Key {
  KeyInfo info;
  std::function<std::int64_t(const RunConfig&)> get_int;
  std::function<void(RunConfig&, std::int64_t)> set_int;
  std::function<const std::string&(const RunConfig&)> get_str;
  std::function<void(RunConfig&, std::string)> set_str;
  std::function<void(RunConfig&, bool)> set_bool;
  std::function<double(const RunConfig&)> get_real;
  std::function<void(RunConfig&, double)> set_real;
};

template <typename S>
Key real_key(std::string path, S RunConfig::*section, double S::*field, double lo, double hi) {
  Key k;
  k.info.path = std::move(path);
  k.info.type = KeyInfo::Type::real;
  k.info.min_real = lo;
  k.info.max_real = hi;
  k.get_real = [section, field](const RunConfig& c) { return c.*section.*field; };
  k.set_real = [section, field](RunConfig& c, double v) { c.*section.*field = v; };
  return k;
}

template <typename S, typename T>
Key int_key(std::string path, S RunConfig::*section, T S::*field, std::int64_t lo, std::int64_t hi,
            std::string reason = {}, std::int64_t multiple_of = 1) {
  Key k;
  k.info.path = std::move(path);
  k.info.type = Type::integer;
  k.info.min = lo;
  k.info.max = hi;
  k.info.multiple_of = multiple_of;
  k.info.reason = std::move(reason);
  k.get_int = [section, field](const RunConfig& c) { return static_cast<std::int64_t>(c.*section.*field); };
  k.set_int = [section, field](RunConfig& c, std::int64_t v) { c.*section.*field = static_cast<T>(v); };
  return k;
}

template <typename S>
Key str_key(std::string path, S RunConfig::*section, std::string S::*field, bool non_empty = false,
            std::size_t max_length = 4096, std::vector<std::string> choices = {}) {
  Key k;
  k.info.path = std::move(path);
  k.info.type = choices.empty() ? Type::string : Type::choice;
  k.info.non_empty = non_empty;
  k.info.max_length = max_length;
  k.info.choices = std::move(choices);
  k.get_str = [section, field](const RunConfig& c) -> const std::string& { return c.*section.*field; };
  k.set_str = [section, field](RunConfig& c, std::string v) { c.*section.*field = std::move(v); };
  return k;
}

template <typename S>
Key bool_key(std::string path, S RunConfig::*section, bool S::*field) {
  Key k;
  k.info.path = std::move(path);
  k.info.type = Type::boolean;
  k.set_bool = [section, field](RunConfig& c, bool v) { c.*section.*field = v; };
  return k;
}

Key special_key(std::string path, Type type, std::int64_t lo = 0, std::int64_t hi = 0) {
  Key k;
  k.info.path = std::move(path);
  k.info.type = type;
  k.info.min = lo;
  k.info.max = hi;
  return k;
}

constexpr std::int64_t kFpgaStepUs = 250;
constexpr std::int64_t kFpgaMaxUs = 4095 * kFpgaStepUs;
constexpr std::size_t kLcmChannelMax = 63;  // LCM_MAX_CHANNEL_NAME_LENGTH

const std::vector<Key>& keys() {
  static const std::vector<Key> table = [] {
    using R = RunConfig;
    std::vector<Key> t;
    t.push_back(str_key("log.level", &R::log, &LogConfig::level, true, 16,
                        {"trace", "debug", "info", "warn", "error", "critical", "off"}));
    t.push_back(str_key("source.replay", &R::source, &SourceConfig::replay));
    t.push_back(special_key("source.speed", Type::speed));
    t.push_back(int_key("source.batch_events", &R::source, &SourceConfig::batch_events, 1, 1'000'000,
                        "at most pipeline.source_queue_events; 1000000 events = 16 MB per batch"));
    t.push_back(bool_key("source.drop_out_of_order", &R::source, &SourceConfig::drop_out_of_order));
    t.push_back(int_key("source.discontinuity_us", &R::source, &SourceConfig::discontinuity_us, 1, 3'600'000'000,
                        "a backward jump of up to an hour"));
    const std::string sensor = fmt::format("the largest sensor evpipe accepts is {0}x{0}", evpipe::kMaxSensorSide);
    t.push_back(
        int_key("source.default_width", &R::source, &SourceConfig::default_width, 1, evpipe::kMaxSensorSide, sensor));
    t.push_back(
        int_key("source.default_height", &R::source, &SourceConfig::default_height, 1, evpipe::kMaxSensorSide, sensor));
    t.push_back(bool_key("source.aedat2_flip_y", &R::source, &SourceConfig::aedat2_flip_y));
    t.push_back(bool_key("source.aedat2_flip_x", &R::source, &SourceConfig::aedat2_flip_x));
    t.push_back(str_key("device.serial", &R::device, &DeviceConfig::serial, false, 256));
    t.push_back(bool_key("device.ba_filter", &R::device, &DeviceConfig::ba_filter));
    const std::string fpga = "the FPGA counts 250 us steps in 12 bits";
    t.push_back(int_key("device.ba_filter_time_us", &R::device, &DeviceConfig::ba_filter_time_us, 0, kFpgaMaxUs, fpga,
                        kFpgaStepUs));
    t.push_back(bool_key("device.refractory", &R::device, &DeviceConfig::refractory));
    t.push_back(int_key("device.refractory_time_us", &R::device, &DeviceConfig::refractory_time_us, 0, kFpgaMaxUs, fpga,
                        kFpgaStepUs));
    t.push_back(
        int_key("device.container_interval_us", &R::device, &DeviceConfig::container_interval_us, 100, 1'000'000));
    t.push_back(int_key("device.reconnect_interval_ms", &R::device, &DeviceConfig::reconnect_interval_ms, 10, 600'000,
                        "retry an unplugged camera at least every 10 minutes"));
    t.push_back(int_key("window.length_us", &R::window, &WindowConfig::length_us, kMinHopUs, 1'000'000,
                        "1 ms to 1 s; a window holds up to 12 M events (200 MB) per second of length at the "
                        "DAVIS346's peak rate"));
    t.push_back(int_key("window.hop_us", &R::window, &WindowConfig::hop_us, kMinHopUs, 1'000'000,
                        fmt::format("at most window.length_us and at least window.length_us / {}: at most 1000 "
                                    "windows per second and each event in at most {} windows",
                                    kMaxWindowOverlap, kMaxWindowOverlap)));
    t.push_back(int_key("window.max_empty_span_us", &R::window, &WindowConfig::max_empty_span_us, 0, 3'600'000'000,
                        "0 (no empty windows) to 1 h: a standstill longer than this publishes again only with the "
                        "next kept event"));
    t.push_back(str_key("denoise.filter", &R::denoise, &DenoiseConfig::filter, true, 256));
    t.push_back(special_key("denoise.params", Type::params));
    t.push_back(special_key("denoise.threads", Type::threads, 1, 64));
    t.push_back(str_key("pose.camera", &R::pose, &PoseFilesConfig::camera));
    t.push_back(str_key("pose.model", &R::pose, &PoseFilesConfig::model));
    t.push_back(str_key("pose.prior", &R::pose, &PoseFilesConfig::prior));
    t.push_back(str_key("pose.poses_out", &R::pose, &PoseFilesConfig::poses_out));
    t.push_back(str_key("pose.ground_truth", &R::pose, &PoseFilesConfig::ground_truth));
    t.push_back(int_key("pose.lost_after_windows", &R::pose, &PoseFilesConfig::lost_after_windows, 1, 10'000));
    t.push_back(str_key("pose.init_worker", &R::pose, &PoseFilesConfig::init_worker, true, 8, {"auto", "on", "off"}));
    t.push_back(int_key("pose.init_worker_nice", &R::pose, &PoseFilesConfig::init_worker_nice, 0, 19,
                        "nice increments are 0-19"));
    t.push_back(bool_key("pose.fuse_windows", &R::pose, &PoseFilesConfig::fuse_windows));
    t.push_back(bool_key("pose.require_redundancy", &R::pose, &PoseFilesConfig::require_redundancy));
    t.push_back(str_key("pose.direct_alignment", &R::pose, &PoseFilesConfig::direct_alignment, true, 8,
                        {"auto", "on", "off", "true", "false"}));
    t.push_back(
        real_key("pose.max_acceleration_m_s2", &R::pose, &PoseFilesConfig::max_acceleration_m_s2, 0.001, 1000.0));
    t.push_back(real_key("pose.max_angular_acceleration_deg_s2", &R::pose,
                         &PoseFilesConfig::max_angular_acceleration_deg_s2, 0.01, 100'000.0));
    t.push_back(bool_key("lcm.enabled", &R::lcm, &LcmConfig::enabled));
    t.push_back(str_key("lcm.url", &R::lcm, &LcmConfig::url, false, 1024));
    t.push_back(str_key("lcm.pose_channel", &R::lcm, &LcmConfig::pose_channel, true, kLcmChannelMax));
    t.push_back(str_key("lcm.stats_channel", &R::lcm, &LcmConfig::stats_channel, true, kLcmChannelMax));
    t.push_back(int_key("lcm.stats_period_ms", &R::lcm, &LcmConfig::stats_period_ms, 10, 1000,
                        "interfaces.md: at least once a second"));
    t.push_back(bool_key("lcm.preview", &R::lcm, &LcmConfig::preview));
    t.push_back(real_key("lcm.preview_hz", &R::lcm, &LcmConfig::preview_hz, 0.1, 30.0));
    t.push_back(str_key("lcm.preview_channel", &R::lcm, &LcmConfig::preview_channel, true, kLcmChannelMax));
    t.push_back(
        int_key("pipeline.source_queue_packets", &R::pipeline, &PipelineConfig::source_queue_packets, 2, 65536));
    t.push_back(int_key("pipeline.source_queue_events", &R::pipeline, &PipelineConfig::source_queue_events, 1000,
                        100'000'000, "100000000 events = 1.6 GB"));
    t.push_back(int_key("pipeline.pose_queue_windows", &R::pipeline, &PipelineConfig::pose_queue_windows, 1, 1024));
    t.push_back(int_key("pipeline.publish_queue", &R::pipeline, &PipelineConfig::publish_queue, 1, 65536));
    return t;
  }();
  return table;
}

const Key* find_key(std::string_view path) {
  for (const auto& k : keys())
    if (k.info.path == path) return &k;
  return nullptr;
}

/// A key's complaint: path and reason; the caller adds the file and line.
struct Problem {
  std::string key;
  std::string why;
};

std::string range_text(const KeyInfo& k) {
  return k.multiple_of > 1 ? fmt::format("a multiple of {} in [{}, {}]", k.multiple_of, k.min, k.max)
                           : fmt::format("in [{}, {}]", k.min, k.max);
}

std::string with_reason(std::string why, const KeyInfo& k) {
  return k.reason.empty() ? why : fmt::format("{} ({})", why, k.reason);
}

std::optional<std::string> check_int(const KeyInfo& k, std::int64_t v) {
  if (v < k.min || v > k.max || v % k.multiple_of != 0)
    return with_reason(fmt::format("must be {}, got {}", range_text(k), v), k);
  return std::nullopt;
}

/// Valid UTF-8 with no control character but tab: what a path, URL or channel name holds, and what the effective
/// configuration prints and loads again unchanged (fuzz_config: invalid UTF-8 came back altered from to_yaml()).
bool printable_utf8(std::string_view v) {
  for (std::size_t i = 0; i < v.size();) {
    const auto c = static_cast<unsigned char>(v[i]);
    if (c < 0x80) {
      if ((c < 0x20 && c != '\t') || c == 0x7F) return false;
      ++i;
      continue;
    }
    std::size_t n = 0;
    std::uint32_t cp = 0;
    if ((c & 0xE0U) == 0xC0U) {
      n = 1;
      cp = c & 0x1FU;
    } else if ((c & 0xF0U) == 0xE0U) {
      n = 2;
      cp = c & 0x0FU;
    } else if ((c & 0xF8U) == 0xF0U) {
      n = 3;
      cp = c & 0x07U;
    } else {
      return false;
    }
    if (i + n >= v.size()) return false;
    for (std::size_t k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(v[i + k]);
      if ((d & 0xC0U) != 0x80U) return false;
      cp = (cp << 6U) | (d & 0x3FU);
    }
    static constexpr std::uint32_t kMinOf[] = {0, 0x80, 0x800, 0x10000};
    if (cp < kMinOf[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF) || cp < 0xA0) return false;
    i += n + 1;
  }
  return true;
}

std::optional<std::string> check_str(const KeyInfo& k, const std::string& v) {
  if (k.non_empty && v.empty()) return std::string("must not be empty");
  if (!k.choices.empty()) {
    if (std::find(k.choices.begin(), k.choices.end(), v) != k.choices.end()) return std::nullopt;
    std::string list;
    for (const auto& c : k.choices) list += (list.empty() ? "" : ", ") + c;
    return fmt::format("must be one of {}, got '{}'", list, v.substr(0, 64));
  }
  if (v.find('\0') != std::string::npos) return std::string("must not contain a NUL character");
  if (v.size() > k.max_length) return fmt::format("must be at most {} bytes long, got {}", k.max_length, v.size());
  if (!printable_utf8(v)) return std::string("must be UTF-8 text without control characters");
  return std::nullopt;
}

/// Strict decimal integer (an optional sign, digits); anything else, or out of int64, is an error.
std::optional<std::int64_t> parse_int(const std::string& text, bool& out_of_range) {
  out_of_range = false;
  std::string_view s = text;
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return std::nullopt;
  std::int64_t v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec == std::errc::result_out_of_range) {
    out_of_range = true;
    return std::nullopt;
  }
  if (ec != std::errc{} || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<bool> parse_bool(const std::string& text) {
  // YAML 1.2 core schema spellings, plus the 1.1 ones yaml-cpp accepts.
  static const char* yes[] = {"true", "True", "TRUE", "yes", "Yes", "YES", "on", "On", "ON", "y", "Y"};
  static const char* no[] = {"false", "False", "FALSE", "no", "No", "NO", "off", "Off", "OFF", "n", "N"};
  for (const char* y : yes)
    if (text == y) return true;
  for (const char* n : no)
    if (text == n) return false;
  return std::nullopt;
}

std::optional<double> parse_number(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text.front())) != 0) return std::nullopt;
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) return std::nullopt;
    return v;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::string real_error(const KeyInfo& k, const std::string& got) {
  return fmt::format("must be a number in [{}, {}], got '{}'", k.min_real, k.max_real, got);
}

std::string speed_error(const std::string& got) {
  return fmt::format("must be 'max' or a number in [{}, {}], got '{}'", kMinSpeed, kMaxSpeed, got);
}

/// How a node that is not the expected scalar is named in errors.
std::string node_kind(const YAML::Node& n) {
  if (!n.IsDefined()) return "nothing";
  if (n.IsNull()) return "null (no value)";
  if (n.IsSequence()) return "a sequence";
  if (n.IsMap()) return "a map";
  return fmt::format("'{}'", n.Scalar());
}

/// The file being parsed: errors name it and the line of the offending node.
struct Doc {
  const std::string& name;

  [[noreturn]] void fail(const YAML::Node& at, const std::string& key, const std::string& why) const {
    const auto mark = at.Mark();
    if (mark.is_null()) throw ConfigError(fmt::format("{}: {}: {}", name, key, why));
    throw ConfigError(fmt::format("{}: line {}: {}: {}", name, mark.line + 1, key, why));
  }

  /// The text of a scalar node; any other node type is an error naming what it is.
  /// `at` is the node whose line errors name: the key (an aliased value's own mark is its anchor's line).
  std::string scalar(const YAML::Node& n, const YAML::Node& at, const std::string& key, const char* expected) const {
    if (!n.IsScalar()) fail(at, key, fmt::format("expected {}, got {}", expected, node_kind(n)));
    return n.Scalar();
  }

  /// A map key: a plain scalar name (a sequence or map as a key, `? [a, b]`, is an error).
  std::string key_name(const YAML::Node& k, const std::string& prefix) const {
    const std::string where = prefix.empty() ? "<top level>" : prefix;
    if (!k.IsScalar()) fail(k, where, fmt::format("a key must be a plain name, got {}", node_kind(k)));
    return k.Scalar();
  }
};

/// Iterates a map's entries with scalar, unique keys.
template <typename F>
void for_each_entry(const Doc& doc, const YAML::Node& map, const std::string& prefix, F&& f) {
  std::map<std::string, int> seen;  // name → line
  for (const auto& kv : map) {
    const std::string name = doc.key_name(kv.first, prefix);
    const std::string key = prefix.empty() ? name : prefix + "." + name;
    const int line = kv.first.Mark().line + 1;
    if (const auto [it, fresh] = seen.emplace(name, line); !fresh)
      doc.fail(kv.first, key, fmt::format("duplicate key (first on line {})", it->second));
    f(name, key, kv.second, kv.first);
  }
}

void set_value(const Doc& doc, const Key& k, const YAML::Node& n, const YAML::Node& at, RunConfig& c) {
  const auto& info = k.info;
  const std::string& key = info.path;
  switch (info.type) {
    case Type::string:
    case Type::choice: {
      std::string expected = "a string";
      if (info.type == Type::choice) {
        expected = "one of";
        for (const auto& choice : info.choices) expected += (expected.size() > 6 ? ", " : " ") + choice;
      }
      auto v = doc.scalar(n, at, key, expected.c_str());
      if (const auto why = check_str(info, v)) doc.fail(at, key, *why);
      k.set_str(c, std::move(v));
      return;
    }
    case Type::boolean: {
      const auto v = parse_bool(doc.scalar(n, at, key, "true or false"));
      if (!v) doc.fail(at, key, fmt::format("expected true or false, got '{}'", n.Scalar()));
      k.set_bool(c, *v);
      return;
    }
    case Type::integer: {
      const auto text = doc.scalar(n, at, key, "an integer");
      bool out_of_range = false;
      const auto v = parse_int(text, out_of_range);
      if (out_of_range) doc.fail(at, key, with_reason(fmt::format("must be {}, got {}", range_text(info), text), info));
      if (!v) doc.fail(at, key, fmt::format("expected an integer, got '{}'", text));
      if (const auto why = check_int(info, *v)) doc.fail(at, key, *why);
      k.set_int(c, *v);
      return;
    }
    case Type::real: {
      const auto text = doc.scalar(n, at, key, "a number");
      const auto v = parse_number(text);
      if (!v || !(*v >= info.min_real && *v <= info.max_real)) doc.fail(at, key, real_error(info, text));
      k.set_real(c, *v);
      return;
    }
    case Type::speed: {
      const auto text = doc.scalar(n, at, key, "a number or 'max'");
      if (text == "max") {
        c.source.speed = std::nullopt;
        return;
      }
      const auto v = parse_number(text);
      if (!v || *v < kMinSpeed || *v > kMaxSpeed) doc.fail(at, key, speed_error(text));
      c.source.speed = *v;
      return;
    }
    case Type::threads: {
      const auto text = doc.scalar(n, at, key, "a number or 'auto'");
      if (text == "auto") {
        c.denoise.threads = 0;
        return;
      }
      bool out_of_range = false;
      const auto v = parse_int(text, out_of_range);
      if (!v && !out_of_range) doc.fail(at, key, fmt::format("expected a number or 'auto', got '{}'", text));
      if (!v || *v < info.min || *v > info.max)
        doc.fail(at, key, fmt::format("must be 'auto' or in [{}, {}], got {}", info.min, info.max, text));
      c.denoise.threads = static_cast<int>(*v);
      return;
    }
    case Type::params: {
      if (n.IsNull()) return;
      if (!n.IsMap()) doc.fail(at, key, fmt::format("expected a map of KEY: value, got {}", node_kind(n)));
      for_each_entry(
          doc, n, key,
          [&](const std::string& name, const std::string& path, const YAML::Node& value, const YAML::Node& name_node) {
            if (name.empty() || name.size() > 256 || !printable_utf8(name))
              doc.fail(name_node, path,
                       "a parameter name must be 1-256 bytes of UTF-8 text without control characters");
            auto text = doc.scalar(value, name_node, path, "a scalar value");
            if (text.size() > 4096 || !printable_utf8(text))
              doc.fail(name_node, path, "must be at most 4096 bytes of UTF-8 text without control characters");
            c.denoise.params.emplace_back(name, std::move(text));
          });
      return;
    }
  }
}

/// The checks of validate(): the first problem, if any.
std::optional<Problem> find_problem(const RunConfig& c) {
  for (const auto& k : keys()) {
    const auto& info = k.info;
    std::optional<std::string> why;
    switch (info.type) {
      case Type::string:
      case Type::choice:
        why = check_str(info, k.get_str(c));
        break;
      case Type::integer:
        why = check_int(info, k.get_int(c));
        break;
      case Type::real:
        if (const double v = k.get_real(c); !(v >= info.min_real && v <= info.max_real))
          why = real_error(info, fmt::format("{}", v));
        break;
      case Type::speed:
        if (c.source.speed && !(*c.source.speed >= kMinSpeed && *c.source.speed <= kMaxSpeed))
          why = speed_error(fmt::format("{}", *c.source.speed));
        break;
      case Type::threads:
        if (c.denoise.threads != 0 && (c.denoise.threads < info.min || c.denoise.threads > info.max))
          why = fmt::format("must be 'auto' or in [{}, {}], got {}", info.min, info.max, c.denoise.threads);
        break;
      case Type::boolean:
      case Type::params:
        break;
    }
    if (why) return Problem{info.path, *why};
  }
  // Consistency between keys (each within its own range by now, so no sum or quotient below can overflow).
  const auto& w = c.window;
  if (w.hop_us > w.length_us)
    return Problem{"window.hop_us",
                   fmt::format("must be at most window.length_us = {}, got {}", w.length_us, w.hop_us)};
  if (w.hop_us * kMaxWindowOverlap < w.length_us)
    return Problem{"window.hop_us",
                   fmt::format("must be at least window.length_us / {} = {} (each event in at most {} windows), got {}",
                               kMaxWindowOverlap, (w.length_us + kMaxWindowOverlap - 1) / kMaxWindowOverlap,
                               kMaxWindowOverlap, w.hop_us)};
  if (c.source.batch_events > c.pipeline.source_queue_events)
    return Problem{"source.batch_events",
                   fmt::format("must be at most pipeline.source_queue_events = {} (a batch must fit the queue's event "
                               "bound), got {}",
                               c.pipeline.source_queue_events, c.source.batch_events)};
  return std::nullopt;
}

/// Where a second YAML document with content starts, if any (a config is one document: a second one would be
/// ignored silently). Not YAML::LoadAll: yaml-cpp 0.7's loops for ever on some malformed input (found by
/// fuzz_config); the parser is asked for at most two documents here.
class ContentSeen : public YAML::EventHandler {
 public:
  std::optional<YAML::Mark> first;
  void OnDocumentStart(const YAML::Mark& /*mark*/) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t /*anchor*/) override { see(mark); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t /*anchor*/) override { see(mark); }
  void OnScalar(const YAML::Mark& mark, const std::string& /*tag*/, YAML::anchor_t /*anchor*/,
                const std::string& /*value*/) override {
    see(mark);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string& /*tag*/, YAML::anchor_t /*anchor*/,
                       YAML::EmitterStyle::value /*style*/) override {
    see(mark);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& mark, const std::string& /*tag*/, YAML::anchor_t /*anchor*/,
                  YAML::EmitterStyle::value /*style*/) override {
    see(mark);
  }
  void OnMapEnd() override {}

 private:
  void see(const YAML::Mark& mark) {
    if (!first) first = mark;
  }
};

std::optional<YAML::Mark> second_document(const std::string& text) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  ContentSeen skip;
  if (!parser.HandleNextDocument(skip)) return std::nullopt;
  ContentSeen next;
  if (!parser.HandleNextDocument(next)) return std::nullopt;
  return next.first;
}

}  // namespace

const std::vector<KeyInfo>& config_keys() {
  static const std::vector<KeyInfo> infos = [] {
    std::vector<KeyInfo> out;
    for (const auto& k : keys()) out.push_back(k.info);
    return out;
  }();
  return infos;
}

std::optional<double> parse_speed(const std::string& text, const std::string& where) {
  if (text == "max") return std::nullopt;
  const auto v = parse_number(text);
  if (!v || *v < kMinSpeed || *v > kMaxSpeed) throw ConfigError(fmt::format("{}: speed {}", where, speed_error(text)));
  return v;
}

RunConfig parse_config(const std::string& yaml_text, const std::string& name) {
  const Doc doc{name};
  YAML::Node root;
  std::optional<YAML::Mark> second;
  try {
    root = YAML::Load(yaml_text);
    second = second_document(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(
        fmt::format("{}: line {}, column {}: YAML syntax error: {}", name, e.mark.line + 1, e.mark.column + 1, e.msg));
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: YAML error: {}", name, e.what()));
  }
  RunConfig c;
  if (second)
    throw ConfigError(
        fmt::format("{}: line {}: <document>: one YAML document expected, found a second one", name, second->line + 1));
  if (!root || root.IsNull()) return c;
  if (!root.IsMap()) doc.fail(root, "<top level>", fmt::format("expected a map of sections, got {}", node_kind(root)));

  static const char* sections[] = {"log", "source", "device", "window", "denoise", "pose", "lcm", "pipeline"};
  std::map<std::string, int> lines;  // key path → line, for the consistency errors of validate()
  try {
    for_each_entry(
        doc, root, "",
        [&](const std::string& section, const std::string& /*path*/, const YAML::Node& node,
            const YAML::Node& key_node) {
          if (std::find_if(std::begin(sections), std::end(sections), [&](const char* s) { return section == s; }) ==
              std::end(sections))
            doc.fail(key_node, section,
                     "unknown section (known: log, source, device, window, denoise, pose, lcm, pipeline)");
          if (node.IsNull()) return;  // an empty section: its defaults
          if (!node.IsMap())
            doc.fail(key_node, section, fmt::format("expected a map of keys, got {}", node_kind(node)));
          for_each_entry(doc, node, section,
                         [&](const std::string& /*name*/, const std::string& path, const YAML::Node& value,
                             const YAML::Node& value_key) {
                           const Key* k = find_key(path);
                           if (k == nullptr) {
                             std::string known;
                             for (const auto& other : keys())
                               if (other.info.path.rfind(section + ".", 0) == 0)
                                 known += (known.empty() ? "" : ", ") + other.info.path.substr(section.size() + 1);
                             doc.fail(value_key, path,
                                      fmt::format("unknown key (known keys in '{}': {})", section, known));
                           }
                           lines[path] = value_key.Mark().line + 1;
                           set_value(doc, *k, value, value_key, c);
                         });
        });
  } catch (const YAML::Exception& e) {  // a safety net: every node access above is type-checked first
    throw ConfigError(fmt::format("{}: line {}: {}", name, e.mark.line + 1, e.msg));
  }
  if (const auto p = find_problem(c)) {
    const auto it = lines.find(p->key);
    if (it != lines.end()) throw ConfigError(fmt::format("{}: line {}: {}: {}", name, it->second, p->key, p->why));
    throw ConfigError(fmt::format("{}: {}: {}", name, p->key, p->why));
  }
  return c;
}

RunConfig load_config(const std::string& path) {
  std::string text;
  try {
    text = read_small_file(path, kMaxConfigBytes, "a run configuration");  // regular files only, never blocks
  } catch (const FileError& e) {
    throw ConfigError(e.what());
  }
  return parse_config(text, path);
}

std::vector<std::pair<std::string, std::string>> DenoiseConfig::pipeline_params() const {
  auto out = params;
  const auto names = filter_chain_names(filter);
  const bool single = names.size() == 1;
  // significance: the pipeline reads no scores, so the look-ahead may drop what its bound rejects without the full
  // walk (exact_scores: false; the same decisions), unless the user set it.
  if (std::find(names.begin(), names.end(), "significance") != names.end()) {
    const bool set = std::any_of(params.begin(), params.end(), [](const auto& kv) {
      return kv.first == "exact_scores" || kv.first == "significance.exact_scores";
    });
    if (!set) out.emplace_back(single ? "exact_scores" : "significance.exact_scores", "false");
  }
  if (std::find(names.begin(), names.end(), "curvature") == names.end()) return out;
  // The user's value of `key`, bare or as curvature.KEY (a bare key counts in a chain too: only curvature has these
  // keys, so the chain gives them to it); nullptr when unset.
  const auto user_value = [&](std::string_view key) -> const std::string* {
    for (const auto& [k, v] : params)
      if (k == key || k == "curvature." + std::string(key)) return &v;
    return nullptr;
  };
  const auto add = [&](std::string_view key, std::string value) {
    out.emplace_back(single ? std::string(key) : "curvature." + std::string(key), std::move(value));
  };
  // Why these differ from the paper's Table 1 setting (evdenoise's defaults): docs/algorithms.md.
  if (user_value("singular") == nullptr) add("singular", "keep");
  // A threshold of the user's stands as given. Otherwise adaptive is on unless turned off, and capped at the paper's
  // 5 unless the user set a cap (so `{adaptive: true}` alone is capped too, and `{adaptive_max_threshold: 7}` alone
  // is adaptive with that cap).
  if (user_value("density_threshold") == nullptr) {
    const std::string* adaptive = user_value("adaptive");
    const bool adaptive_off =
        adaptive != nullptr && (*adaptive == "false" || *adaptive == "0" || *adaptive == "no" || *adaptive == "off");
    if (adaptive == nullptr) add("adaptive", "true");
    if (!adaptive_off && user_value("adaptive_max_threshold") == nullptr) add("adaptive_max_threshold", "5");
  }
  return out;
}

void RunConfig::validate() const {
  if (const auto p = find_problem(*this)) throw ConfigError(fmt::format("{}: {}", p->key, p->why));
}

std::string RunConfig::to_yaml() const {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "log" << YAML::Value << YAML::BeginMap << YAML::Key << "level" << YAML::Value << log.level
      << YAML::EndMap;
  out << YAML::Key << "source" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "replay" << YAML::Value << source.replay;
  out << YAML::Key << "speed" << YAML::Value << (source.speed ? fmt::format("{}", *source.speed) : "max");
  out << YAML::Key << "batch_events" << YAML::Value << source.batch_events;
  out << YAML::Key << "drop_out_of_order" << YAML::Value << source.drop_out_of_order;
  out << YAML::Key << "discontinuity_us" << YAML::Value << source.discontinuity_us;
  out << YAML::Key << "default_width" << YAML::Value << source.default_width;
  out << YAML::Key << "default_height" << YAML::Value << source.default_height;
  out << YAML::Key << "aedat2_flip_y" << YAML::Value << source.aedat2_flip_y;
  out << YAML::Key << "aedat2_flip_x" << YAML::Value << source.aedat2_flip_x;
  out << YAML::EndMap;
  out << YAML::Key << "device" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "serial" << YAML::Value << device.serial;
  out << YAML::Key << "ba_filter" << YAML::Value << device.ba_filter;
  out << YAML::Key << "ba_filter_time_us" << YAML::Value << device.ba_filter_time_us;
  out << YAML::Key << "refractory" << YAML::Value << device.refractory;
  out << YAML::Key << "refractory_time_us" << YAML::Value << device.refractory_time_us;
  out << YAML::Key << "container_interval_us" << YAML::Value << device.container_interval_us;
  out << YAML::Key << "reconnect_interval_ms" << YAML::Value << device.reconnect_interval_ms;
  out << YAML::EndMap;
  out << YAML::Key << "window" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "length_us" << YAML::Value << window.length_us;
  out << YAML::Key << "hop_us" << YAML::Value << window.hop_us;
  out << YAML::Key << "max_empty_span_us" << YAML::Value << window.max_empty_span_us;
  out << YAML::EndMap;
  out << YAML::Key << "denoise" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "filter" << YAML::Value << denoise.filter;
  out << YAML::Key << "params" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : denoise.params) out << YAML::Key << key << YAML::Value << value;
  out << YAML::EndMap;
  out << YAML::Key << "threads" << YAML::Value << (denoise.threads == 0 ? "auto" : std::to_string(denoise.threads));
  out << YAML::EndMap;
  out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "camera" << YAML::Value << pose.camera;
  out << YAML::Key << "model" << YAML::Value << pose.model;
  out << YAML::Key << "prior" << YAML::Value << pose.prior;
  out << YAML::Key << "poses_out" << YAML::Value << pose.poses_out;
  out << YAML::Key << "ground_truth" << YAML::Value << pose.ground_truth;
  out << YAML::Key << "lost_after_windows" << YAML::Value << pose.lost_after_windows;
  out << YAML::Key << "init_worker" << YAML::Value << pose.init_worker;
  out << YAML::Key << "init_worker_nice" << YAML::Value << pose.init_worker_nice;
  out << YAML::Key << "fuse_windows" << YAML::Value << pose.fuse_windows;
  out << YAML::Key << "require_redundancy" << YAML::Value << pose.require_redundancy;
  out << YAML::Key << "direct_alignment" << YAML::Value << pose.direct_alignment;
  out << YAML::Key << "max_acceleration_m_s2" << YAML::Value << pose.max_acceleration_m_s2;
  out << YAML::Key << "max_angular_acceleration_deg_s2" << YAML::Value << pose.max_angular_acceleration_deg_s2;
  out << YAML::EndMap;
  out << YAML::Key << "lcm" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "enabled" << YAML::Value << lcm.enabled;
  out << YAML::Key << "url" << YAML::Value << lcm.url;
  out << YAML::Key << "pose_channel" << YAML::Value << lcm.pose_channel;
  out << YAML::Key << "stats_channel" << YAML::Value << lcm.stats_channel;
  out << YAML::Key << "stats_period_ms" << YAML::Value << lcm.stats_period_ms;
  out << YAML::Key << "preview" << YAML::Value << lcm.preview;
  out << YAML::Key << "preview_hz" << YAML::Value << lcm.preview_hz;
  out << YAML::Key << "preview_channel" << YAML::Value << lcm.preview_channel;
  out << YAML::EndMap;
  out << YAML::Key << "pipeline" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "source_queue_packets" << YAML::Value << pipeline.source_queue_packets;
  out << YAML::Key << "source_queue_events" << YAML::Value << pipeline.source_queue_events;
  out << YAML::Key << "pose_queue_windows" << YAML::Value << pipeline.pose_queue_windows;
  out << YAML::Key << "publish_queue" << YAML::Value << pipeline.publish_queue;
  out << YAML::EndMap;
  out << YAML::EndMap;
  return out.c_str();
}

}  // namespace evpipe::config
