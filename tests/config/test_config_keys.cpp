// The validation layer walked key by key (issue 17): every key of config_keys() at its bounds and one past them,
// with every wrong YAML node type (scalar of the wrong kind, sequence, map, null, an alias to a map), with a
// sequence or map as a key, and duplicated. Every error must be a ConfigError naming the file, the line and the key.

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "evpipe/config/run_config.hpp"

using evpipe::config::config_keys;
using evpipe::config::ConfigError;
using evpipe::config::KeyInfo;
using evpipe::config::parse_config;
using evpipe::config::RunConfig;

namespace {

std::string error_of(const std::string& yaml) {
  try {
    parse_config(yaml, "t.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("UNEXPECTED EXCEPTION: ") + e.what();
  }
  return "";
}

std::string section_of(const std::string& path) {
  return path.substr(0, path.find('.'));
}
std::string name_of(const std::string& path) {
  return path.substr(path.find('.') + 1);
}

/// Other keys that must move with `path` = `value` so that only `path` is judged (hop <= length, batch <= queue).
std::string companions(const std::string& path, std::int64_t value) {
  if (path == "window.length_us") return "window:\n  hop_us: " + std::to_string(value) + "\n";
  if (path == "window.hop_us")
    return "window:\n  length_us: " + std::to_string(std::max<std::int64_t>(value, 30000)) + "\n";
  if (path == "pipeline.source_queue_events") return "source:\n  batch_events: 1\n";
  return "";
}

/// `path: value` as a YAML document, the key on line 2 (after a comment line), plus its companions.
std::string doc_with(const std::string& path, const std::string& value, const std::string& extra = "") {
  return "# walked\n" + section_of(path) + ":\n  " + name_of(path) + ": " + value + "\n" + extra;
}

/// `path: value` merged with companions in the same section (YAML forbids a section twice: it is a duplicate key).
std::string int_doc(const std::string& path, std::int64_t value) {
  const std::string extra = companions(path, value);
  std::string doc = "# walked\n" + section_of(path) + ":\n  " + name_of(path) + ": " + std::to_string(value) + "\n";
  if (extra.empty()) return doc;
  if (section_of(path) == extra.substr(0, extra.find(':'))) return doc + extra.substr(extra.find('\n') + 1);
  return doc + extra;
}

void expect_error(const std::string& yaml, const std::string& path, int line, const std::string& what = "") {
  const auto err = error_of(yaml);
  const std::string head = "t.yaml: line " + std::to_string(line) + ": " + path + ": ";
  EXPECT_EQ(err.rfind(head, 0), 0U) << "yaml:\n" << yaml << "error: " << err;
  if (!what.empty()) {
    EXPECT_NE(err.find(what), std::string::npos) << "yaml:\n" << yaml << "error: " << err;
  }
}

void expect_ok(const std::string& yaml) {
  EXPECT_EQ(error_of(yaml), "") << "yaml:\n" << yaml;
}

}  // namespace

TEST(ConfigKeys, EveryKeyOfTheEffectiveConfigurationIsInTheTableAndBack) {
  // to_yaml() prints every field; the table must name the same keys (a field added without a table entry would
  // skip validation).
  std::set<std::string> printed;
  std::istringstream in(RunConfig{}.to_yaml());
  std::string line, section;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const auto colon = line.find(':');
    if (line[0] != ' ') {
      section = line.substr(0, colon);
    } else if (line.rfind("    ", 0) != 0) {
      printed.insert(section + "." + line.substr(2, colon - 2));
    }
  }
  std::set<std::string> table;
  for (const auto& k : config_keys()) EXPECT_TRUE(table.insert(k.path).second) << "twice: " << k.path;
  EXPECT_EQ(printed, table);
}

TEST(ConfigKeys, IntegersAtTheirBoundsAndOnePast) {
  int walked = 0;
  for (const auto& k : config_keys()) {
    if (k.type != KeyInfo::Type::integer) continue;
    ++walked;
    SCOPED_TRACE(k.path);
    expect_ok(int_doc(k.path, k.min));
    expect_ok(int_doc(k.path, k.max));
    expect_error(int_doc(k.path, k.min - 1), k.path, 3, "must be ");
    expect_error(int_doc(k.path, k.max + 1), k.path, 3, "must be ");
    if (k.multiple_of > 1) expect_error(int_doc(k.path, k.min + 1), k.path, 3, "a multiple of");
    // The ends of int64 and past them: a range error, never a wrap-around or an exception of another kind.
    expect_error(doc_with(k.path, "9223372036854775807"), k.path, 3, "must be ");
    expect_error(doc_with(k.path, "-9223372036854775808"), k.path, 3, "must be ");
    expect_error(doc_with(k.path, "9223372036854775808"), k.path, 3, "must be ");
    expect_error(doc_with(k.path, "99999999999999999999999"), k.path, 3, "must be ");
    for (const char* bad : {"abc", "1.5", "1e3", "0x10", "true", "''", "' 5'", ".inf", ".nan"})
      expect_error(doc_with(k.path, bad), k.path, 3, "expected an integer");
  }
  EXPECT_EQ(walked, 18);  // every integer key (a new one is walked too: update the count)
}

TEST(ConfigKeys, IntegerValuesAreStored) {
  for (const auto& k : config_keys()) {
    if (k.type != KeyInfo::Type::integer) continue;
    SCOPED_TRACE(k.path);
    const auto c = parse_config(int_doc(k.path, k.max));
    EXPECT_NE(c.to_yaml().find(name_of(k.path) + ": " + std::to_string(k.max)), std::string::npos) << c.to_yaml();
  }
}

TEST(ConfigKeys, StringsChoicesAndBooleans) {
  for (const auto& k : config_keys()) {
    SCOPED_TRACE(k.path);
    switch (k.type) {
      case KeyInfo::Type::string:
        expect_ok(doc_with(k.path, "'" + std::string(k.max_length, 'a') + "'"));
        expect_error(doc_with(k.path, "'" + std::string(k.max_length + 1, 'a') + "'"), k.path, 3, "at most");
        expect_error(doc_with(k.path, "\"a\\0b\""), k.path, 3, "NUL");
        if (k.non_empty) expect_error(doc_with(k.path, "''"), k.path, 3, "must not be empty");
        if (!k.non_empty) expect_ok(doc_with(k.path, "''"));
        break;
      case KeyInfo::Type::choice:
        for (const auto& c : k.choices) expect_ok(doc_with(k.path, c));
        expect_error(doc_with(k.path, "nosuch"), k.path, 3, "must be one of");
        expect_error(doc_with(k.path, "''"), k.path, 3, "must not be empty");
        break;
      case KeyInfo::Type::boolean:
        for (const char* v : {"true", "false", "yes", "no", "on", "off"}) expect_ok(doc_with(k.path, v));
        for (const char* v : {"1", "maybe", "''", "truee"})
          expect_error(doc_with(k.path, v), k.path, 3, "true or false");
        break;
      case KeyInfo::Type::real:
        expect_ok(doc_with(k.path, std::to_string(k.min_real)));
        expect_ok(doc_with(k.path, std::to_string(k.max_real)));
        for (const std::string& v :
             std::vector<std::string>{std::to_string(k.min_real * 0.99), std::to_string(k.max_real * 1.01),
                                      std::string(".nan"), ".inf", "nan", "abc", "''", "1e999"})
          expect_error(doc_with(k.path, v), k.path, 3, "must be a number in");
        break;
      default:
        break;
    }
  }
}

TEST(ConfigKeys, EveryKeyRefusesEveryWrongNodeType) {
  for (const auto& k : config_keys()) {
    SCOPED_TRACE(k.path);
    expect_error(doc_with(k.path, "[1, 2]"), k.path, 3, "a sequence");
    expect_error(doc_with(k.path, "[]"), k.path, 3, "a sequence");
    expect_error(doc_with(k.path, "\n    - 1"), k.path, 3, "a sequence");  // the key's line
    if (k.type != KeyInfo::Type::params) {
      expect_error(doc_with(k.path, "{a: 1}"), k.path, 3, "a map");
      expect_error(doc_with(k.path, ""), k.path, 3, "null");
      expect_error(doc_with(k.path, "~"), k.path, 3, "null");
      expect_error(doc_with(k.path, "null"), k.path, 3, "null");
    } else {
      expect_error(doc_with(k.path, "{a: [1]}"), k.path + ".a", 3, "a sequence");
      expect_error(doc_with(k.path, "{a: {b: 1}}"), k.path + ".a", 3, "a map");
      expect_error(doc_with(k.path, "{a: }"), k.path + ".a", 3, "null");
      expect_error(doc_with(k.path, "{? [a, b] : 1}"), k.path, 3, "a key must be a plain name");
      expect_error(doc_with(k.path, "{a: 1, a: 2}"), k.path + ".a", 3, "duplicate key");
      expect_ok(doc_with(k.path, ""));  // an empty params: none
    }
    // An alias to a map (the anchor on another section): the alias's node type is what counts, the line is the key's.
    const std::string anchor =
        section_of(k.path) == "pipeline" ? "log: &m {level: info}\n" : "pipeline: &m {publish_queue: 64}\n";
    const std::string alias_doc = anchor + section_of(k.path) + ":\n  " + name_of(k.path) + ": *m\n";
    if (k.type != KeyInfo::Type::params) {
      expect_error(alias_doc, k.path, 3, "a map");
    } else {
      expect_ok(alias_doc);  // a map of scalars is what params takes (the filter registry judges its keys)
    }
    // A sequence or a map as the key itself, and the key twice.
    expect_error(section_of(k.path) + ":\n  ? [a, b]\n  : 1\n", section_of(k.path), 2, "a key must be a plain name");
    expect_error(section_of(k.path) + ":\n  ? {a: b}\n  : 1\n", section_of(k.path), 2, "a key must be a plain name");
  }
}

TEST(ConfigKeys, KeysThatAreNotNamesAtTheTopLevel) {
  expect_error("? [a, b]\n: 1\n", "<top level>", 1, "a key must be a plain name, got a sequence");
  expect_error("? {a: 1}\n: 1\n", "<top level>", 1, "a key must be a plain name, got a map");
  expect_error("log: {level: info}\nlog: {level: warn}\n", "log", 2, "duplicate key (first on line 1)");
  expect_error("window:\n  length_us: 30000\n  length_us: 40000\n", "window.length_us", 3, "duplicate key");
  expect_error("[1, 2]\n", "<top level>", 1, "expected a map of sections, got a sequence");
  expect_error("just text\n", "<top level>", 1, "expected a map of sections, got 'just text'");
  expect_error("log: [1]\n", "log", 1, "expected a map of keys, got a sequence");
  expect_error("log: info\n", "log", 1, "expected a map of keys, got 'info'");
  expect_error("log: {level: info}\n---\nlog: {level: warn}\n", "<document>", 3, "one YAML document");
  expect_ok("log:\n");  // an empty section: its defaults
  expect_ok("---\n");
  expect_ok("# only a comment\n");
}

TEST(ConfigKeys, AnAliasToAScalarIsItsValue) {
  const auto c = parse_config("lcm: {pose_channel: &c SAME, stats_channel: *c}\n");
  EXPECT_EQ(c.lcm.pose_channel, "SAME");
  EXPECT_EQ(c.lcm.stats_channel, "SAME");
  EXPECT_EQ(parse_config("window: {length_us: &w 20000, hop_us: *w}\n").window.hop_us, 20000);
}

TEST(ConfigKeys, SpeedRange) {
  using evpipe::config::parse_speed;
  EXPECT_EQ(parse_speed("0.01", "--speed"), 0.01);
  EXPECT_EQ(parse_speed("1000", "--speed"), 1000.0);
  EXPECT_EQ(parse_speed("max", "--speed"), std::nullopt);
  // Issue 17 row 12: 1e-300 turned pacing off silently.
  for (const char* bad : {"1e-300", "0.0099", "1000.1", "0", "-1", "nan", "inf", "1e309", "", " 1", "1x", "MAX"}) {
    SCOPED_TRACE(bad);
    EXPECT_THROW(parse_speed(bad, "--speed"), ConfigError);
    expect_error(doc_with("source.speed", std::string("'") + bad + "'"), "source.speed", 3,
                 "must be 'max' or a number");
  }
  expect_ok(doc_with("source.speed", "max"));
  expect_ok(doc_with("source.speed", "0.25"));
  RunConfig c;
  c.source.speed = 1e-300;  // set past the parser (the command line's path): validate() catches it too
  EXPECT_THROW(c.validate(), ConfigError);
}

TEST(ConfigKeys, ThreadsRange) {
  for (const auto& k : config_keys()) {
    if (k.type != KeyInfo::Type::threads) continue;
    expect_ok(doc_with(k.path, std::to_string(k.min)));
    expect_ok(doc_with(k.path, std::to_string(k.max)));
    expect_ok(doc_with(k.path, "auto"));
    expect_error(doc_with(k.path, std::to_string(k.min - 1)), k.path, 3, "must be 'auto' or in");
    expect_error(doc_with(k.path, std::to_string(k.max + 1)), k.path, 3, "must be 'auto' or in");
    expect_error(doc_with(k.path, "99999999999999999999"), k.path, 3, "must be 'auto' or in");
    expect_error(doc_with(k.path, "many"), k.path, 3, "expected a number or 'auto'");
  }
}

// Issue 17 row 2: a window of INT64_MAX passed validation and made the slicer's t0 + w overflow.
TEST(ConfigKeys, WindowLengthAndHopAreBoundedAndConsistent) {
  expect_error("window: {length_us: 9223372036854775807}\n", "window.length_us", 1, "must be in [1000, 1000000]");
  // Also seen: hop_us: 1 made a 3 s replay take over a minute.
  expect_error("window: {hop_us: 1}\n", "window.hop_us", 1, "must be in [1000, 1000000]");
  expect_error("window: {length_us: 10000, hop_us: 20000}\n", "window.hop_us", 1, "at most window.length_us = 10000");
  expect_error("window: {length_us: 1000000, hop_us: 31249}\n", "window.hop_us", 1,
               "at least window.length_us / 32 = 31250");
  expect_ok("window: {length_us: 1000000, hop_us: 31250}\n");
  // A cross-key error with neither key in the file (set past the parser) names the key without a line.
  RunConfig c;
  c.window.length_us = 1000;
  EXPECT_THROW(c.validate(), ConfigError);
}

// Also seen: a batch larger than the source queue's event bound bypassed it (946 MB RSS).
TEST(ConfigKeys, BatchMustFitTheSourceQueuesEventBound) {
  expect_error("source: {batch_events: 5000}\npipeline: {source_queue_events: 4000}\n", "source.batch_events", 1,
               "at most pipeline.source_queue_events = 4000");
  expect_ok("source: {batch_events: 4000}\npipeline: {source_queue_events: 4000}\n");
  expect_error("source: {batch_events: 1000001}\n", "source.batch_events", 1, "must be in [1, 1000000]");
}

// Issue 17 row 3: sizes up to 32768 were accepted; the filters then allocated per-pixel state for 2^30 pixels.
TEST(ConfigKeys, DefaultSensorSizeIsBounded) {
  expect_error("source: {default_width: 32768}\n", "source.default_width", 1, "must be in [1, 2048]");
  expect_error("source: {default_height: 2049}\n", "source.default_height", 1, "largest sensor");
  expect_ok("source: {default_width: 2048, default_height: 2048}\n");
}

// Issue 17 row 1: a sequence or map as a key threw YAML::TypedBadConversion out of parse_config (abort, exit 134).
TEST(ConfigKeys, SequenceOrMapKeysAreConfigErrors) {
  for (const char* yaml :
       {"? [a, b]\n: 1\n", "window:\n  ? [a, b]\n  : 1\n", "denoise:\n  params:\n    ? [a, b]\n    : 1\n",
        "denoise: {params: {? {x: 1} : 2}}\n", "{[a]: 1}\n"}) {
    SCOPED_TRACE(yaml);
    const auto err = error_of(yaml);
    EXPECT_NE(err.find("a key must be a plain name"), std::string::npos) << err;
    EXPECT_EQ(err.rfind("t.yaml: line ", 0), 0U) << err;
  }
}

// Found by fuzz_config: invalid UTF-8 in a string came back altered from the printed configuration (to_yaml()).
TEST(ConfigKeys, StringsAreUtf8TextWithoutControlCharacters) {
  expect_error(std::string("lcm: {stats_channel: EV") + "\xF0\xFF" + " x}\n", "lcm.stats_channel", 1,
               "UTF-8 text without control");
  expect_error("pose: {camera: \"a\\x1bb\"}\n", "pose.camera", 1, "UTF-8 text without control");
  expect_error("denoise: {params: {radius: \"3\\x01\"}}\n", "denoise.params.radius", 1, "UTF-8 text");
  expect_ok("pose: {camera: \"/srv/kamera/m\\u00e4hdrescher \\u6e2c\\u5b9a.yaml\"}\n");
}
