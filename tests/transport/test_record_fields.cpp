// The records' field tables (records.hpp) walked against the .lcm files and the generated types: every field of an
// .lcm file has exactly one table line of the same name; each line's value lands in the bytes of that field on the
// wire (offsets computed from the .lcm file, so a name paired with another field's member is caught); every field
// survives encode -> decode with distinct values; the JSON line has every name as a key, in table order.
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/records.hpp"
#include "evpipe/transport/text.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace evpipe::transport {
namespace {

using Bytes = std::vector<std::uint8_t>;

struct LcmField {
  std::string type;
  std::string name;
  int count{1};  ///< fixed array size; 1 for a scalar, -1 for an array sized by another field
};

std::string lcm_path(const std::string& type) {
  return std::string(EVPIPE_SOURCE_DIR) + "/libs/transport/lcmtypes/" + type + ".lcm";
}

/// The non-const fields of the one struct in an .lcm file, in order.
std::vector<LcmField> parse_lcm(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::string text;
  for (std::string line; std::getline(in, line);) {
    text += line.substr(0, line.find("//")) + ' ';
  }
  const auto open = text.find('{');
  const auto close = text.rfind('}');
  EXPECT_NE(open, std::string::npos) << path;
  EXPECT_NE(close, std::string::npos) << path;
  std::vector<LcmField> fields;
  std::istringstream body(text.substr(open + 1, close - open - 1));
  const std::regex decl(
      R"(^\s*([A-Za-z_][A-Za-z0-9_]*)\s+([A-Za-z_][A-Za-z0-9_]*)\s*(\[\s*([A-Za-z0-9_]+)\s*\])?\s*$)");
  for (std::string stmt; std::getline(body, stmt, ';');) {
    if (stmt.find_first_not_of(" \t\r\n") == std::string::npos) continue;
    if (std::regex_search(stmt, std::regex(R"(^\s*const\s)"))) continue;
    std::smatch m;
    EXPECT_TRUE(std::regex_match(stmt, m, decl)) << "unexpected declaration in " << path << ": " << stmt;
    if (m.empty()) continue;
    const std::string dim = m[4];
    fields.push_back(
        {m[1], m[2], dim.empty() ? 1 : (std::isdigit(static_cast<unsigned char>(dim[0])) ? std::stoi(dim) : -1)});
  }
  return fields;
}

std::size_t lcm_size(const std::string& type) {
  static const std::map<std::string, std::size_t> sizes = {{"int8_t", 1},  {"boolean", 1}, {"byte", 1},
                                                           {"int16_t", 2}, {"int32_t", 4}, {"float", 4},
                                                           {"int64_t", 8}, {"double", 8}};
  const auto it = sizes.find(type);
  EXPECT_NE(it, sizes.end()) << "type " << type;
  return it == sizes.end() ? 0 : it->second;
}

/// Each field's bytes in an encoded message (strings: the characters, without length and NUL).
std::map<std::string, Bytes> split_wire(const Bytes& bytes, const std::vector<LcmField>& fields) {
  std::map<std::string, Bytes> out;
  std::size_t pos = 8;  // the fingerprint
  for (const LcmField& f : fields) {
    EXPECT_GE(f.count, 1) << f.name << ": only fixed-size arrays here";
    Bytes b;
    for (int k = 0; k < f.count; ++k) {
      if (f.type == "string") {
        std::uint32_t n = 0;
        for (int i = 0; i < 4; ++i) n = (n << 8) | bytes.at(pos + static_cast<std::size_t>(i));
        b.insert(b.end(), bytes.begin() + static_cast<std::ptrdiff_t>(pos + 4),
                 bytes.begin() + static_cast<std::ptrdiff_t>(pos + 4 + n - 1));
        pos += 4 + n;
      } else {
        const std::size_t n = lcm_size(f.type);
        b.insert(b.end(), bytes.begin() + static_cast<std::ptrdiff_t>(pos),
                 bytes.begin() + static_cast<std::ptrdiff_t>(pos + n));
        pos += n;
      }
    }
    out[f.name] = b;
  }
  EXPECT_EQ(pos, bytes.size()) << "the .lcm fields do not account for every byte";
  return out;
}

/// A value as LCM writes it (big endian).
template <typename T>
Bytes big_endian(T v) {
  if constexpr (std::is_same_v<T, bool>) {
    return {static_cast<std::uint8_t>(v ? 1 : 0)};
  } else if constexpr (std::is_same_v<T, TrackStatus>) {
    return {static_cast<std::uint8_t>(v)};
  } else if constexpr (std::is_same_v<T, std::string>) {
    return Bytes(v.begin(), v.end());
  } else if constexpr (kIsStdArray<T>) {
    Bytes b;
    for (const auto& e : v) {
      const Bytes eb = big_endian(e);
      b.insert(b.end(), eb.begin(), eb.end());
    }
    return b;
  } else {
    static_assert(std::is_arithmetic_v<T>);
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &v, sizeof(T));
    return Bytes(std::rbegin(raw), std::rend(raw));  // x86-64 is little endian
  }
}

/// A value for table line `i` that no other line has; `flip` gives a second set (booleans the other way).
template <typename T>
T distinct_value(std::size_t i, bool flip) {
  const auto k = static_cast<std::int64_t>(i) + (flip ? 100 : 0);
  if constexpr (std::is_same_v<T, bool>) {
    return (i % 2 == 0) != flip;
  } else if constexpr (std::is_same_v<T, TrackStatus>) {
    return flip ? TrackStatus::lost : TrackStatus::holding;  // neither is the default
  } else if constexpr (std::is_same_v<T, std::string>) {
    return "field " + std::to_string(k);
  } else if constexpr (std::is_floating_point_v<T>) {
    return static_cast<T>(1.0 + static_cast<double>(k) / 8.0);
  } else if constexpr (kIsStdArray<T>) {
    T a{};
    for (std::size_t j = 0; j < a.size(); ++j) a[j] = distinct_value<typename T::value_type>(i * 64 + j, flip);
    return a;
  } else {
    static_assert(std::is_integral_v<T>);
    // Every byte non-zero where the type has room, so that a field read at a wrong offset or width shows.
    if constexpr (sizeof(T) == 8) {
      return static_cast<T>(0x0102030405060700LL + k);
    } else if constexpr (sizeof(T) == 4) {
      return static_cast<T>(0x01020300 + k);
    } else {
      return static_cast<T>(k + 1);
    }
  }
}

/// The .lcm field names a table covers (a descriptor of a list covers its count and arrays: wire_names).
template <typename Table>
std::vector<std::string> wire_names(const Table& table) {
  std::vector<std::string> names;
  for_each_field(table, [&](const auto& f) {
    if constexpr (requires { f.wire_names; }) {
      names.insert(names.end(), f.wire_names.begin(), f.wire_names.end());
    } else {
      names.emplace_back(f.name);
    }
  });
  return names;
}

/// The JSON keys of a table, in order.
template <typename Table>
std::vector<std::string> json_keys(const Table& table) {
  std::vector<std::string> names;
  for_each_field(table, [&](const auto& f) { names.emplace_back(f.name); });
  return names;
}

/// A distinct value in every table line of `table` (the plain ones, wire_field).
template <typename Record, typename Table>
void fill_distinct(Record& r, const Table& table, bool flip) {
  std::size_t i = 0;
  for_each_field(table, [&](const auto& f) {
    if constexpr (requires { f.record; }) {
      using R = std::decay_t<decltype(r.*f.record)>;
      r.*f.record = distinct_value<R>(i, flip);
    }
    ++i;
  });
}

/// Every plain line of `table` equal in a and b.
template <typename Record, typename Table>
void expect_lines_equal(const Record& a, const Record& b, const Table& table, const std::string& what) {
  for_each_field(table, [&](const auto& f) {
    if constexpr (requires { f.record; }) {
      EXPECT_EQ(a.*f.record, b.*f.record) << what << "." << f.name;
    }
  });
}

/// Each .lcm field is named by exactly one table line.
template <typename Table>
void expect_table_covers(const Table& table, const std::string& type) {
  const std::vector<LcmField> lcm = parse_lcm(lcm_path(type));
  ASSERT_FALSE(lcm.empty()) << type;
  std::map<std::string, int> in_table;
  for (const std::string& n : wire_names(table)) ++in_table[n];
  for (const LcmField& f : lcm) {
    EXPECT_EQ(in_table[f.name], 1) << type << "." << f.name << " (" << type << ".lcm) needs exactly one table line";
  }
  EXPECT_EQ(in_table.size(), lcm.size()) << "a line of the table for " << type << " names no field of its .lcm";
}

/// Each plain line of `table` writes r's value into the bytes of its own field of the encoded message.
template <typename Record, typename Message, typename Table>
void expect_lines_on_the_wire(const Record& r, const Message& m, const Table& table, const std::string& type) {
  Bytes bytes(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  const std::map<std::string, Bytes> wire = split_wire(bytes, parse_lcm(lcm_path(type)));
  for_each_field(table, [&](const auto& f) {
    if constexpr (requires { f.record; }) {
      const auto it = wire.find(std::string(f.name));
      ASSERT_NE(it, wire.end()) << type << "." << f.name;
      EXPECT_EQ(it->second, big_endian(r.*f.record)) << type << "." << f.name;
    }
  });
}

std::vector<std::string> table_names() {
  return json_keys(kPoseFields);
}

/// A record with a distinct value in every table line, and a pose, covariance and flags that are not defaults.
PoseRecord distinct_record(bool flip) {
  PoseRecord r;
  fill_distinct(r, kPoseFields, flip);
  r.covariance_known = true;  // the covariance travels only when known
  for (std::size_t k = 0; k < r.covariance.size(); ++k)
    r.covariance[k] = 1e-6 * static_cast<double>(k + (flip ? 7 : 1));
  r.T_cam_model.t_cam_model_m = flip ? Eigen::Vector3d(-0.25, 0.5, 3.5) : Eigen::Vector3d(0.125, -1.5, 2.25);
  r.T_cam_model.q_cam_model = flip ? Eigen::Quaterniond(0.0, 0.6, 0.0, 0.8) : Eigen::Quaterniond(0.6, 0.0, 0.8, 0.0);
  return r;
}

StatsRecord distinct_stats(bool flip) {
  StatsRecord r;
  fill_distinct(r, kStatsFields, flip);
  for (int k = 0; k < 3; ++k) {
    StageStatsRecord s;
    fill_distinct(s, kStageStatsFields, flip != (k == 1));
    s.name += "/" + std::to_string(k);
    r.stages.push_back(s);
    QueueStatsRecord q;
    fill_distinct(q, kQueueStatsFields, flip != (k == 1));
    q.name += "/" + std::to_string(k);
    r.queues.push_back(q);
    r.denoise_figures.emplace_back("figure " + std::to_string(k), 0.25 * k + (flip ? 1 : 0));
  }
  return r;
}

TEST(PoseRecordFields, EveryFieldOfPoseTLcmHasOneTableLine) {
  expect_table_covers(kPoseFields, "pose_t");
}

TEST(PoseRecordFields, EachLineWritesItsOwnFieldOnTheWire) {
  const std::vector<LcmField> lcm = parse_lcm(lcm_path("pose_t"));
  for (const bool flip : {false, true}) {
    const PoseRecord r = distinct_record(flip);
    expect_lines_on_the_wire(r, to_lcm(r), kPoseFields, "pose_t");
    const std::map<std::string, Bytes> wire = split_wire(encode(r), lcm);
    // The descriptors of their own: position, wire quaternion (qw first), covariance.
    EXPECT_EQ(wire.at("position_m"),
              big_endian(std::array<double, 3>{r.T_cam_model.t_cam_model_m.x(), r.T_cam_model.t_cam_model_m.y(),
                                               r.T_cam_model.t_cam_model_m.z()}));
    const camera::WireQuaternion q = camera::to_wire(r.T_cam_model.q_cam_model);
    EXPECT_EQ(wire.at("orientation"), big_endian(std::array<double, 4>{q.qw, q.qx, q.qy, q.qz}));
    EXPECT_EQ(wire.at("covariance"), big_endian(r.covariance));
  }
}

TEST(PoseRecordFields, EveryFieldRoundTrips) {
  for (const bool flip : {false, true}) {
    const PoseRecord in = distinct_record(flip);
    const Bytes bytes = encode(in);
    const std::optional<PoseRecord> out = decode_pose(bytes.data(), bytes.size());
    ASSERT_TRUE(out);
    expect_lines_equal(*out, in, kPoseFields, "pose_t");
    EXPECT_EQ(out->T_cam_model.t_cam_model_m, in.T_cam_model.t_cam_model_m);
    const camera::WireQuaternion a = camera::to_wire(in.T_cam_model.q_cam_model);
    const camera::WireQuaternion b = camera::to_wire(out->T_cam_model.q_cam_model);
    EXPECT_NEAR(b.qw, a.qw, 1e-15);
    EXPECT_NEAR(b.qx, a.qx, 1e-15);
    EXPECT_NEAR(b.qy, a.qy, 1e-15);
    EXPECT_NEAR(b.qz, a.qz, 1e-15);
    EXPECT_EQ(out->covariance, in.covariance);
  }
}

TEST(PoseRecordFields, JsonHasEveryFieldInTableOrder) {
  const PoseRecord r = distinct_record(false);
  const std::string json = to_json(r, "EVPIPE_POSE");
  std::size_t last = 0;
  for (const std::string& n : table_names()) {
    const std::string key = "\"" + n + "\":";
    const std::size_t at = json.find(key);
    ASSERT_NE(at, std::string::npos) << key << " missing from " << json;
    EXPECT_EQ(json.find(key, at + 1), std::string::npos) << key << " twice in " << json;
    EXPECT_GT(at, last) << key << " out of table order in " << json;
    last = at;
  }
  EXPECT_EQ(json.back(), '}');
}

TEST(PoseRecordFields, StatusIsTheOneCoreEnumWithTheWireValues) {
  static_assert(std::is_same_v<TrackingStatus, evpipe::TrackStatus>);
  for (const TrackStatus s : kTrackStatuses) {
    PoseRecord r;
    r.status = s;
    EXPECT_EQ(to_lcm(r).status, static_cast<std::int8_t>(s));
    const Bytes bytes = encode(r);
    EXPECT_EQ(decode_pose(bytes.data(), bytes.size())->status, s);
    EXPECT_NE(to_json(r, "P").find("\"status\":\"" + std::string(to_string(s)) + "\""), std::string::npos);
  }
  EXPECT_EQ(static_cast<int>(evpipe::pose_t::STATUS_HOLDING), static_cast<int>(TrackStatus::holding));
}

TEST(StatsRecordFields, EveryFieldOfTheLcmFilesHasOneTableLine) {
  expect_table_covers(kStatsFields, "stats_t");
  expect_table_covers(kStageStatsFields, "stage_stats_t");
  expect_table_covers(kQueueStatsFields, "queue_stats_t");
}

TEST(StatsRecordFields, EachLineWritesItsOwnFieldOnTheWire) {
  for (const bool flip : {false, true}) {
    const StatsRecord r = distinct_stats(flip);
    const evpipe::stats_t m = to_lcm(r);
    for_each_field(kStatsFields, [&](const auto& f) {
      if constexpr (requires { f.record; }) {  // stats_t's own bytes: by member (its lists make offsets vary)
        using W = std::decay_t<decltype(m.*f.wire)>;
        EXPECT_EQ(m.*f.wire, static_cast<W>(r.*f.record)) << "stats_t." << f.name;
      }
    });
    ASSERT_EQ(m.stages.size(), r.stages.size());
    ASSERT_EQ(m.queues.size(), r.queues.size());
    for (std::size_t k = 0; k < r.stages.size(); ++k) {
      expect_lines_on_the_wire(r.stages[k], m.stages[k], kStageStatsFields, "stage_stats_t");
      expect_lines_on_the_wire(r.queues[k], m.queues[k], kQueueStatsFields, "queue_stats_t");
    }
  }
}

TEST(StatsRecordFields, EveryFieldRoundTrips) {
  for (const bool flip : {false, true}) {
    const StatsRecord in = distinct_stats(flip);
    const Bytes bytes = encode(in);
    const std::optional<StatsRecord> out = decode_stats(bytes.data(), bytes.size());
    ASSERT_TRUE(out);
    expect_lines_equal(*out, in, kStatsFields, "stats_t");
    ASSERT_EQ(out->stages.size(), in.stages.size());
    ASSERT_EQ(out->queues.size(), in.queues.size());
    for (std::size_t k = 0; k < in.stages.size(); ++k) {
      expect_lines_equal(out->stages[k], in.stages[k], kStageStatsFields, "stage_stats_t");
      expect_lines_equal(out->queues[k], in.queues[k], kQueueStatsFields, "queue_stats_t");
    }
    EXPECT_EQ(out->denoise_figures, in.denoise_figures);
  }
}

TEST(StatsRecordFields, JsonHasEveryFieldInTableOrder) {
  const std::string json = to_json(distinct_stats(false), "EVPIPE_STATS");
  std::size_t last = 0;
  for (const std::string& n : json_keys(kStatsFields)) {
    const std::size_t at = json.find("\"" + n + "\":");
    ASSERT_NE(at, std::string::npos) << n << " missing from " << json;
    EXPECT_GT(at, last) << n << " out of table order in " << json;
    last = at;
  }
  const std::pair<std::string, std::vector<std::string>> lists[] = {{"stages", json_keys(kStageStatsFields)},
                                                                    {"queues", json_keys(kQueueStatsFields)}};
  for (const auto& [list, keys] : lists) {
    // The list's first object has every key of its table, in order.
    std::size_t at = json.find("\"" + list + "\":[{\"" + keys.front() + "\":");
    ASSERT_NE(at, std::string::npos) << list << " in " << json;
    for (const std::string& n : keys) {
      const std::size_t next = json.find("\"" + n + "\":", at);
      ASSERT_NE(next, std::string::npos) << list << "." << n << " in " << json;
      EXPECT_LT(next, json.find('}', at)) << list << "." << n << " not in the first object of " << json;
      at = next;
    }
  }
  EXPECT_NE(json.find("\"denoise_figures\":{\"figure 0\":0,\"figure 1\":0.25,\"figure 2\":0.5}}"), std::string::npos)
      << json;
}

}  // namespace
}  // namespace evpipe::transport
