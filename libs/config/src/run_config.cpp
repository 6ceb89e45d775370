#include "evpipe/config/run_config.hpp"

#include <yaml-cpp/yaml.h>

#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>

#include "evpipe/core/file.hpp"
#include "evpipe/core/filter_chain.hpp"

namespace evpipe::config {

namespace {

[[noreturn]] void fail(const std::string& file, const std::string& key, const std::string& why) {
  throw ConfigError(fmt::format("{}: {}: {}", file, key, why));
}

template <typename T>
T scalar(const YAML::Node& n, const std::string& file, const std::string& key, const char* type_name) {
  if (!n.IsScalar()) fail(file, key, fmt::format("expected {}, got a {}", type_name, n.IsMap() ? "map" : "list"));
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    fail(file, key, fmt::format("expected {}, got '{}'", type_name, n.Scalar()));
  }
}

using Setter = std::function<void(const YAML::Node&, const std::string& key)>;

/// Applies a map of known keys to one YAML section; unknown keys are errors.
void apply_section(const YAML::Node& section, const std::string& file, const std::string& prefix,
                   const std::map<std::string, Setter>& keys) {
  if (!section) return;
  if (section.IsNull()) return;
  if (!section.IsMap()) fail(file, prefix, "expected a map of keys");
  for (const auto& kv : section) {
    const auto name = kv.first.as<std::string>();
    const std::string key = prefix + "." + name;
    auto it = keys.find(name);
    if (it == keys.end()) {
      std::string known;
      for (const auto& [k, _] : keys) known += (known.empty() ? "" : ", ") + k;
      fail(file, key, fmt::format("unknown key (known keys in '{}': {})", prefix, known));
    }
    it->second(kv.second, key);
  }
}

}  // namespace

std::optional<double> parse_speed(const std::string& text, const std::string& where) {
  if (text == "max") return std::nullopt;
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v) || v <= 0) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    throw ConfigError(fmt::format("{}: speed must be a positive number or 'max', got '{}'", where, text));
  }
}

RunConfig parse_config(const std::string& yaml_text, const std::string& name) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(
        fmt::format("{}: line {}, column {}: YAML syntax error: {}", name, e.mark.line + 1, e.mark.column + 1, e.msg));
  }
  RunConfig c;
  if (!root || root.IsNull()) return c;
  if (!root.IsMap()) fail(name, "<top level>", "expected a map of sections");

  auto str = [&](std::string& dst) {
    return
        [&dst, &name](const YAML::Node& n, const std::string& k) { dst = scalar<std::string>(n, name, k, "a string"); };
  };
  auto i64 = [&](std::int64_t& dst) {
    return [&dst, &name](const YAML::Node& n, const std::string& k) {
      dst = scalar<std::int64_t>(n, name, k, "an integer");
    };
  };
  auto integer = [&](int& dst) {
    return [&dst, &name](const YAML::Node& n, const std::string& k) { dst = scalar<int>(n, name, k, "an integer"); };
  };
  auto boolean = [&](bool& dst) {
    return
        [&dst, &name](const YAML::Node& n, const std::string& k) { dst = scalar<bool>(n, name, k, "true or false"); };
  };

  for (const auto& kv : root) {
    const auto section = kv.first.as<std::string>();
    const auto& node = kv.second;
    if (section == "log") {
      apply_section(node, name, section, {{"level", str(c.log.level)}});
    } else if (section == "source") {
      apply_section(node, name, section,
                    {{"replay", str(c.source.replay)},
                     {"speed",
                      [&](const YAML::Node& n, const std::string& k) {
                        c.source.speed =
                            parse_speed(scalar<std::string>(n, name, k, "a number or 'max'"), name + ": " + k);
                      }},
                     {"batch_events", i64(c.source.batch_events)},
                     {"drop_out_of_order", boolean(c.source.drop_out_of_order)},
                     {"discontinuity_us", i64(c.source.discontinuity_us)},
                     {"default_width", integer(c.source.default_width)},
                     {"default_height", integer(c.source.default_height)},
                     {"aedat2_flip_y", boolean(c.source.aedat2_flip_y)},
                     {"aedat2_flip_x", boolean(c.source.aedat2_flip_x)}});
    } else if (section == "device") {
      apply_section(node, name, section,
                    {{"serial", str(c.device.serial)},
                     {"ba_filter", boolean(c.device.ba_filter)},
                     {"ba_filter_time_us", i64(c.device.ba_filter_time_us)},
                     {"refractory", boolean(c.device.refractory)},
                     {"refractory_time_us", i64(c.device.refractory_time_us)},
                     {"container_interval_us", i64(c.device.container_interval_us)},
                     {"reconnect_interval_ms", i64(c.device.reconnect_interval_ms)}});
    } else if (section == "window") {
      apply_section(node, name, section, {{"length_us", i64(c.window.length_us)}, {"hop_us", i64(c.window.hop_us)}});
    } else if (section == "denoise") {
      apply_section(node, name, section,
                    {{"filter", str(c.denoise.filter)},
                     {"threads",
                      [&](const YAML::Node& n, const std::string& k) {
                        if (scalar<std::string>(n, name, k, "a number or 'auto'") == "auto") {
                          c.denoise.threads = 0;
                          return;
                        }
                        c.denoise.threads = scalar<int>(n, name, k, "a number or 'auto'");
                        if (c.denoise.threads < 1 || c.denoise.threads > 64)
                          fail(name, k, fmt::format("must be 'auto' or in [1, 64], got {}", c.denoise.threads));
                      }},
                     {"params", [&](const YAML::Node& n, const std::string& k) {
                        if (n.IsNull()) return;
                        if (!n.IsMap()) fail(name, k, "expected a map of KEY: value");
                        for (const auto& p : n) {
                          const auto key = p.first.as<std::string>();
                          c.denoise.params.emplace_back(key,
                                                        scalar<std::string>(p.second, name, k + "." + key, "a value"));
                        }
                      }}});
    } else if (section == "pose") {
      apply_section(node, name, section,
                    {{"camera", str(c.pose.camera)},
                     {"model", str(c.pose.model)},
                     {"prior", str(c.pose.prior)},
                     {"poses_out", str(c.pose.poses_out)},
                     {"ground_truth", str(c.pose.ground_truth)},
                     {"lost_after_windows", integer(c.pose.lost_after_windows)},
                     {"init_worker", str(c.pose.init_worker)},
                     {"init_worker_nice", integer(c.pose.init_worker_nice)}});
    } else if (section == "lcm") {
      apply_section(
          node, name, section,
          {{"enabled", boolean(c.lcm.enabled)},
           {"url", str(c.lcm.url)},
           {"pose_channel", str(c.lcm.pose_channel)},
           {"stats_channel", str(c.lcm.stats_channel)},
           {"stats_period_ms", i64(c.lcm.stats_period_ms)},
           {"preview", boolean(c.lcm.preview)},
           {"preview_hz", [&](const YAML::Node& n,
                              const std::string& k) { c.lcm.preview_hz = scalar<double>(n, name, k, "a number"); }},
           {"preview_channel", str(c.lcm.preview_channel)}});
    } else if (section == "pipeline") {
      apply_section(node, name, section,
                    {{"source_queue_packets", i64(c.pipeline.source_queue_packets)},
                     {"source_queue_events", i64(c.pipeline.source_queue_events)},
                     {"pose_queue_windows", i64(c.pipeline.pose_queue_windows)},
                     {"publish_queue", i64(c.pipeline.publish_queue)}});
    } else {
      fail(name, section, "unknown section (known: log, source, device, window, denoise, pose, lcm, pipeline)");
    }
  }
  try {
    c.validate();
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{}: {}", name, e.what()));
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
  if (std::find(names.begin(), names.end(), "curvature") == names.end()) return out;
  const bool single = names.size() == 1;
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
  auto check = [](bool ok, const char* key, const std::string& why) {
    if (!ok) throw ConfigError(fmt::format("{}: {}", key, why));
  };
  static const char* levels[] = {"trace", "debug", "info", "warn", "error", "critical", "off"};
  bool level_ok = false;
  for (const char* l : levels) level_ok = level_ok || log.level == l;
  check(level_ok, "log.level",
        fmt::format("'{}' is not one of trace, debug, info, warn, error, critical, off", log.level));
  check(!source.speed || *source.speed > 0, "source.speed", "must be > 0 or 'max'");
  check(source.batch_events >= 1 && source.batch_events <= 10'000'000, "source.batch_events",
        fmt::format("must be in [1, 10000000], got {}", source.batch_events));
  check(source.discontinuity_us > 0, "source.discontinuity_us", "must be > 0");
  check(source.default_width > 0 && source.default_width <= 32768, "source.default_width", "must be in [1, 32768]");
  check(source.default_height > 0 && source.default_height <= 32768, "source.default_height", "must be in [1, 32768]");
  for (const auto& [key, value] : {std::pair{"device.ba_filter_time_us", device.ba_filter_time_us},
                                   std::pair{"device.refractory_time_us", device.refractory_time_us}})
    check(
        value >= 0 && value <= 4095 * 250 && value % 250 == 0, key,
        fmt::format("must be a multiple of 250 in [0, {}] (the FPGA counts 250 us steps), got {}", 4095 * 250, value));
  check(device.container_interval_us >= 100 && device.container_interval_us <= 1'000'000,
        "device.container_interval_us", "must be in [100, 1000000]");
  check(device.reconnect_interval_ms >= 10, "device.reconnect_interval_ms", "must be >= 10");
  check(window.length_us > 0, "window.length_us", fmt::format("must be > 0, got {}", window.length_us));
  check(window.hop_us > 0 && window.hop_us <= window.length_us, "window.hop_us",
        fmt::format("must be in [1, window.length_us = {}], got {}", window.length_us, window.hop_us));
  check(!denoise.filter.empty(), "denoise.filter", "must name a filter or chain, or be 'none'");
  check(denoise.threads >= 0 && denoise.threads <= 64, "denoise.threads",
        fmt::format("must be 'auto' or in [1, 64], got {}", denoise.threads));
  check(pose.lost_after_windows >= 1, "pose.lost_after_windows",
        fmt::format("must be >= 1, got {}", pose.lost_after_windows));
  check(pose.init_worker == "auto" || pose.init_worker == "on" || pose.init_worker == "off", "pose.init_worker",
        fmt::format("must be auto, on or off, got '{}'", pose.init_worker));
  check(pose.init_worker_nice >= 0 && pose.init_worker_nice <= 19, "pose.init_worker_nice",
        fmt::format("must be in [0, 19], got {}", pose.init_worker_nice));
  check(!lcm.pose_channel.empty(), "lcm.pose_channel", "must not be empty");
  check(!lcm.stats_channel.empty(), "lcm.stats_channel", "must not be empty");
  check(lcm.preview_hz >= 0.1 && lcm.preview_hz <= 30, "lcm.preview_hz",
        fmt::format("must be in [0.1, 30], got {}", lcm.preview_hz));
  check(!lcm.preview_channel.empty(), "lcm.preview_channel", "must not be empty");
  check(lcm.stats_period_ms >= 10 && lcm.stats_period_ms <= 1000, "lcm.stats_period_ms",
        fmt::format("must be in [10, 1000] (interfaces.md: at least once a second), got {}", lcm.stats_period_ms));
  check(pipeline.source_queue_packets >= 2 && pipeline.source_queue_packets <= 65536, "pipeline.source_queue_packets",
        fmt::format("must be in [2, 65536], got {}", pipeline.source_queue_packets));
  check(pipeline.source_queue_events >= 1000 && pipeline.source_queue_events <= 100'000'000,
        "pipeline.source_queue_events",
        fmt::format("must be in [1000, 100000000], got {}", pipeline.source_queue_events));
  check(pipeline.pose_queue_windows >= 1 && pipeline.pose_queue_windows <= 1024, "pipeline.pose_queue_windows",
        fmt::format("must be in [1, 1024], got {}", pipeline.pose_queue_windows));
  check(pipeline.publish_queue >= 1 && pipeline.publish_queue <= 65536, "pipeline.publish_queue",
        fmt::format("must be in [1, 65536], got {}", pipeline.publish_queue));
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
