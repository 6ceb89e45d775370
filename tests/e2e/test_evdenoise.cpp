// End-to-end: the real evdenoise binary on the bundled sample and on labelled evsim recordings, compared with a
// direct run of the same filter through the library. Every filter of the registry is exercised generically.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/metrics/classification.hpp"
#include "evpipe/metrics/esr.hpp"
#include "evpipe/metrics/roc.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"

namespace fs = std::filesystem;
using namespace evpipe;

namespace {

// ---- running binaries -------------------------------------------------------------------------------------

using evpipe::testing::q;
using evpipe::testing::Run;
using evpipe::testing::slurp;

fs::path dir() {
  static const fs::path d = evpipe::testing::temp_dir("evdenoise");
  return d;
}

Run run(const std::string& cmd) {
  return evpipe::testing::run(cmd, dir());
}

const std::string kEvdenoise = EVDENOISE_EXE;
const std::string kEvsim = EVSIM_EXE;
const std::string kSample = (evpipe::testing::source_dir() / "tests/data/demo-sample.aedat4").string();

// ---- a small strict JSON parser (the --metrics output must be one valid JSON object) -----------------------

struct Json {
  enum class Type { null, boolean, number, string, array, object } type = Type::null;
  bool boolean = false;
  double number = 0;
  std::string string;
  std::vector<Json> array;
  std::vector<std::string> keys;  // an object's members in order: keys[i] names values[i] (not a vector of
  std::vector<Json> values;       // pairs: clang rejects std::pair of the still incomplete Json)

  [[nodiscard]] const Json& at(const std::string& key) const {
    for (std::size_t i = 0; i < keys.size(); ++i)
      if (keys[i] == key) return values[i];
    throw std::out_of_range("JSON member missing: " + key);
  }
  [[nodiscard]] bool is_null() const { return type == Type::null; }
  [[nodiscard]] double num() const {
    if (type != Type::number) throw std::runtime_error("JSON value is not a number");
    return number;
  }
  [[nodiscard]] std::uint64_t count() const { return static_cast<std::uint64_t>(num()); }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& text) : s_(text) {}
  Json parse() {
    Json v = value();
    space();
    if (i_ != s_.size()) fail("trailing characters");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& why) const {
    throw std::runtime_error("bad JSON at " + std::to_string(i_) + ": " + why);
  }
  void space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\t' || s_[i_] == '\r')) ++i_;
  }
  bool eat(char c) {
    space();
    if (i_ < s_.size() && s_[i_] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  void expect(char c) {
    if (!eat(c)) fail(std::string("expected '") + c + "'");
  }
  std::string str() {
    expect('"');
    std::string out;
    while (i_ < s_.size() && s_[i_] != '"') {
      if (s_[i_] == '\\') {
        ++i_;
        if (i_ >= s_.size()) fail("bad escape");
        const char e = s_[i_];
        if (e == 'u') {
          out += static_cast<char>(std::stoi(s_.substr(i_ + 1, 4), nullptr, 16));
          i_ += 4;
        } else {
          out += e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e;
        }
      } else {
        out += s_[i_];
      }
      ++i_;
    }
    expect('"');
    return out;
  }
  Json value() {
    space();
    Json v;
    if (i_ >= s_.size()) fail("unexpected end");
    const char c = s_[i_];
    if (c == '{') {
      ++i_;
      v.type = Json::Type::object;
      if (eat('}')) return v;
      do {
        space();
        std::string k = str();
        expect(':');
        v.keys.push_back(std::move(k));
        v.values.push_back(value());
      } while (eat(','));
      expect('}');
    } else if (c == '[') {
      ++i_;
      v.type = Json::Type::array;
      if (eat(']')) return v;
      do v.array.push_back(value());
      while (eat(','));
      expect(']');
    } else if (c == '"') {
      v.type = Json::Type::string;
      v.string = str();
    } else if (s_.compare(i_, 4, "null") == 0) {
      i_ += 4;
    } else if (s_.compare(i_, 4, "true") == 0) {
      v.type = Json::Type::boolean;
      v.boolean = true;
      i_ += 4;
    } else if (s_.compare(i_, 5, "false") == 0) {
      v.type = Json::Type::boolean;
      i_ += 5;
    } else {
      static const std::regex kNumber(R"(-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?)");
      std::smatch m;
      const std::string rest = s_.substr(i_, 40);
      if (!std::regex_search(rest, m, kNumber, std::regex_constants::match_continuous)) fail("bad value");
      v.type = Json::Type::number;
      v.number = std::strtod(m.str().c_str(), nullptr);
      i_ += m.length();
    }
    return v;
  }
  const std::string& s_;
  std::size_t i_ = 0;
};

Json parse_json(const std::string& text) {
  return JsonParser(text).parse();
}

// ---- the direct (library) run the binary must match --------------------------------------------------------

struct Direct {
  EventBatch input;
  denoise::Decisions decisions;
  std::vector<Event> kept;
  std::vector<Label> kept_labels;
  bool has_score = false;
  std::int64_t latency_us = 0;
};

Direct direct(const std::string& path, const std::string& filter,
              const std::vector<std::pair<std::string, std::string>>& settings = {},
              std::size_t max_events = SIZE_MAX) {
  Direct d;
  const auto reader = io::open_reader(path);
  const SensorGeometry geometry = reader->info().geometry;
  d.input = io::read_all(path);
  if (d.input.events.size() > max_events) {
    d.input.events.resize(max_events);
    if (d.input.labelled()) d.input.labels.resize(max_events);
  }
  auto f = denoise::make_filter_chain(filter, settings, geometry);
  d.decisions = denoise::run_filter(*f, d.input.events);
  d.has_score = f->has_score();
  d.latency_us = f->latency_us();
  for (std::size_t i = 0; i < d.input.events.size(); ++i) {
    if (d.decisions.keep[i] == 0) continue;
    d.kept.push_back(d.input.events[i]);
    if (d.input.labelled()) d.kept_labels.push_back(d.input.labels[i]);
  }
  return d;
}

std::vector<std::string> filter_names() {
  std::vector<std::string> names;
  for (const auto& s : denoise::filter_specs()) names.emplace_back(s.name);
  return names;
}

/// A labelled evsim recording (made once per test program).
const std::string& labelled_recording() {
  static const std::string path = [] {
    const std::string p = (dir() / "labelled.txt").string();
    const auto r = run(kEvsim + " --scene demo --duration-ms 300 --noise-hz 3 --hot-pixels 5 --seed 11 --out " + q(p) +
                       " --no-manifest");
    if (r.status != 0) throw std::runtime_error("evsim failed: " + r.err);
    return p;
  }();
  return path;
}

std::pair<int, int> png_size(const std::string& path) {
  const std::string bytes = slurp(path);
  if (bytes.size() < 24 || bytes.compare(1, 3, "PNG") != 0 || bytes.compare(12, 4, "IHDR") != 0) return {-1, -1};
  auto be32 = [&](std::size_t at) {
    int v = 0;
    for (std::size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(bytes[at + k]);
    return v;
  };
  return {be32(16), be32(20)};
}

}  // namespace

// ---- tests ------------------------------------------------------------------------------------------------

TEST(Evdenoise, ListFiltersShowsEveryFilterWithItsParameters) {
  const auto r = run(kEvdenoise + " --list-filters");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const auto& spec : denoise::filter_specs()) {
    EXPECT_NE(r.out.find(std::string(spec.name) + "\n"), std::string::npos) << spec.name << " missing:\n" << r.out;
    EXPECT_NE(r.out.find(std::string(spec.summary)), std::string::npos) << spec.name;
    for (const auto& p : denoise::describe(spec)) {
      const std::string line = "--set " + p.key + "=VALUE  (default " + p.default_value + "): " + p.help;
      EXPECT_NE(r.out.find(line), std::string::npos) << spec.name << ": " << line << " missing";
    }
  }
  EXPECT_NE(r.out.find("--set duration_us=VALUE  (default 2000)"), std::string::npos) << r.out;
}

TEST(Evdenoise, SampleOutputIsTheDirectRunsKeptSubsetInBothFormats) {
  for (const auto& name : filter_names()) {
    const Direct d = direct(kSample, name);
    ASSERT_GT(d.input.events.size(), 0U);
    for (const char* ext : {".aedat4", ".txt"}) {
      const std::string out = (dir() / ("sample-" + name + ext)).string();
      const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(out) + " --filter " + name + " -q");
      ASSERT_EQ(r.status, 0) << name << ext << ": " << r.err;
      EXPECT_EQ(r.out, "") << "-q prints nothing";
      const auto back = io::read_all(out);
      EXPECT_EQ(back.events.size(), d.kept.size()) << name << ext;
      EXPECT_TRUE(back.events == d.kept) << name << ext << ": output differs from a direct run_filter";
      EXPECT_FALSE(back.labelled()) << name << ext;
    }
    // Read batches of another size: decisions do not depend on how the stream is cut.
    const std::string small = (dir() / ("sample-" + name + "-b777.aedat4")).string();
    const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(small) + " --filter " + name + " --batch-events 777 -q");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(io::read_all(small).events == d.kept) << name;
  }
}

TEST(Evdenoise, ThreadsGiveTheSameOutput) {
  // The curvature filter's row bands on 3 threads (2 workers + the caller): the same events kept, in order.
  for (const std::string args : {"--filter curvature", "--filter hotpixel,curvature --set mode=frames",
                                 "--filter curvature --set adaptive=true --set singular=keep"}) {
    const std::string one = (dir() / "threads-1.aedat4").string();
    const std::string three = (dir() / "threads-3.aedat4").string();
    const auto r1 = run(kEvdenoise + " " + q(kSample) + " " + q(one) + " " + args + " --metrics");
    const auto r3 = run(kEvdenoise + " " + q(kSample) + " " + q(three) + " " + args + " --threads 3 --metrics");
    ASSERT_EQ(r1.status, 0) << args << ": " << r1.err;
    ASSERT_EQ(r3.status, 0) << args << ": " << r3.err;
    EXPECT_EQ(parse_json(r1.out).at("threads").num(), 1);
    EXPECT_EQ(parse_json(r3.out).at("threads").num(), 3);
    EXPECT_EQ(parse_json(r1.out).at("parallel_runs").num(), 0) << args;
    EXPECT_GT(parse_json(r3.out).at("parallel_runs").num(), 0) << args << ": the blocks were not split";
    const auto a = io::read_all(one);
    const auto b = io::read_all(three);
    ASSERT_GT(a.events.size(), 0U) << args;
    EXPECT_TRUE(a.events == b.events) << args;
    EXPECT_EQ(parse_json(r1.out).at("events_kept").num(), parse_json(r3.out).at("events_kept").num()) << args;
  }
  // Causal mode decides event by event: nothing to split.
  const auto causal = run(kEvdenoise + " " + q(kSample) + " " + q((dir() / "threads-causal.aedat4").string()) +
                          " --filter curvature --set mode=causal --threads 2 --metrics");
  ASSERT_EQ(causal.status, 0) << causal.err;
  EXPECT_EQ(parse_json(causal.out).at("parallel_runs").num(), 0);
  const std::string out = (dir() / "threads-0.aedat4").string();
  fs::remove(out);
  const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(out) + " --filter curvature --threads 0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--threads"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST(Evdenoise, SummaryLineWithoutMetrics) {
  const std::string out = (dir() / "summary.aedat4").string();
  const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(out) + " --filter baf");
  ASSERT_EQ(r.status, 0) << r.err;
  const Direct d = direct(kSample, "baf");
  EXPECT_NE(r.out.find(std::to_string(d.input.events.size()) + " events"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(std::to_string(d.kept.size()) + " kept"), std::string::npos) << r.out;
}

TEST(Evdenoise, MetricsOnTheUnlabelledSample) {
  for (const auto& name : filter_names()) {
    const std::string out = (dir() / ("metrics-" + name + ".aedat4")).string();
    const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(out) + " --filter " + name + " --metrics");
    ASSERT_EQ(r.status, 0) << name << ": " << r.err;
    const Json j = parse_json(r.out);
    const Direct d = direct(kSample, name);
    const auto n_in = d.input.events.size();
    const auto n_kept = d.kept.size();
    EXPECT_EQ(j.at("input").string, kSample);
    EXPECT_EQ(j.at("input_format").string, "aedat4");
    EXPECT_EQ(j.at("output").string, out);
    EXPECT_EQ(j.at("width").num(), 346);
    EXPECT_EQ(j.at("height").num(), 260);
    EXPECT_EQ(j.at("filter").string, name);
    ASSERT_EQ(j.at("filters").array.size(), 1U);
    EXPECT_EQ(j.at("filters").array[0].at("name").string, name);
    // Every parameter of the filter is listed with its (default) value.
    const auto& params = j.at("filters").array[0].at("params");
    const auto described = denoise::describe(*denoise::find_filter(name));
    ASSERT_EQ(params.keys.size(), described.size()) << name;
    for (std::size_t i = 0; i < described.size(); ++i) {
      EXPECT_EQ(params.keys[i], described[i].key);
      const Json& v = params.values[i];
      if (v.type == Json::Type::number) {
        EXPECT_EQ(v.number, std::strtod(described[i].default_value.c_str(), nullptr)) << described[i].key;
      } else {
        EXPECT_EQ(v.string, described[i].default_value) << described[i].key;
      }
    }
    EXPECT_EQ(j.at("events_in").count(), n_in) << name;
    EXPECT_EQ(j.at("events_kept").count(), n_kept) << name;
    EXPECT_EQ(j.at("events_kept").count() + j.at("events_removed").count(), j.at("events_in").count());
    EXPECT_DOUBLE_EQ(j.at("nrr").num(), static_cast<double>(n_in - n_kept) / static_cast<double>(n_in));
    EXPECT_DOUBLE_EQ(j.at("kept_fraction").num(), static_cast<double>(n_kept) / static_cast<double>(n_in));
    EXPECT_EQ(j.at("latency_us").num(), static_cast<double>(d.latency_us));
    EXPECT_GE(j.at("max_pending_events").num(), 0);
    EXPECT_GT(j.at("throughput_mev_s").num(), 0);
    EXPECT_GE(j.at("wall_s").num(), j.at("filter_s").num());
    EXPECT_EQ(j.at("report").type, Json::Type::object);
    // ESR: streamed over the input and the output; equal to the one-shot metric on the same events.
    const auto esr_raw = metrics::esr(d.input.events, kDavis346);
    const auto esr_out = metrics::esr(d.kept, kDavis346);
    EXPECT_EQ(j.at("esr_raw").at("chunks").count(), n_in / 30'000);
    EXPECT_EQ(j.at("esr_raw").at("chunks").count(), esr_raw.chunks.size());
    ASSERT_TRUE(esr_raw.mean);
    EXPECT_NEAR(j.at("esr_raw").at("mean").num(), *esr_raw.mean, 1e-12);
    EXPECT_EQ(j.at("esr_filtered").at("chunks").count(), esr_out.chunks.size());
    if (esr_out.mean) {
      EXPECT_NEAR(j.at("esr_filtered").at("mean").num(), *esr_out.mean, 1e-12);
    } else {
      EXPECT_TRUE(j.at("esr_filtered").at("mean").is_null()) << "fewer than 30 000 kept: n/a";
    }
    // Unlabelled: no confusion-matrix figures.
    EXPECT_FALSE(j.at("labelled").boolean);
    for (const char* k : {"signal_in", "noise_in", "tp", "fp", "tn", "fn", "sr", "nr", "precision", "f1", "auc"})
      EXPECT_TRUE(j.at(k).is_null()) << k;
    EXPECT_EQ(j.at("has_score").boolean, d.has_score);
    EXPECT_EQ(j.at("out_of_order_dropped").num(), 0);
    EXPECT_TRUE(j.at("error").is_null());
  }
}

TEST(Evdenoise, LabelledInputKeepsLabelsAndScoresAgainstThem) {
  const std::string& in = labelled_recording();
  for (const auto& name : filter_names()) {
    const Direct d = direct(in, name);
    ASSERT_TRUE(d.input.labelled());
    const std::string out = (dir() / ("labelled-" + name + ".txt")).string();
    const auto r = run(kEvdenoise + " " + q(in) + " " + q(out) + " --filter " + name + " --metrics");
    ASSERT_EQ(r.status, 0) << name << ": " << r.err;
    const auto back = io::read_all(out);
    EXPECT_TRUE(back.events == d.kept) << name;
    ASSERT_TRUE(back.labelled()) << name << ": labels carried to the .txt output";
    EXPECT_TRUE(back.labels == d.kept_labels) << name;

    const Json j = parse_json(r.out);
    const auto c = metrics::classify(d.decisions.keep, d.input.labels);
    ASSERT_TRUE(c.confusion);
    EXPECT_TRUE(j.at("labelled").boolean);
    EXPECT_EQ(j.at("signal_in").count(), c.confusion->signal());
    EXPECT_EQ(j.at("noise_in").count(), c.confusion->noise());
    EXPECT_EQ(j.at("signal_in").count() + j.at("noise_in").count(), j.at("events_in").count());
    EXPECT_EQ(j.at("tp").count(), c.confusion->tp) << name;
    EXPECT_EQ(j.at("fp").count(), c.confusion->fp) << name;
    EXPECT_EQ(j.at("tn").count(), c.confusion->tn) << name;
    EXPECT_EQ(j.at("fn").count(), c.confusion->fn) << name;
    EXPECT_EQ(j.at("tp").count() + j.at("fp").count(), j.at("events_kept").count());
    const auto& m = *c.confusion;
    const double tp = static_cast<double>(m.tp);
    EXPECT_DOUBLE_EQ(j.at("sr").num(), tp / static_cast<double>(m.tp + m.fn)) << name;
    EXPECT_DOUBLE_EQ(j.at("nr").num(), static_cast<double>(m.tn) / static_cast<double>(m.tn + m.fp)) << name;
    if (m.tp + m.fp > 0) {
      EXPECT_DOUBLE_EQ(j.at("precision").num(), tp / static_cast<double>(m.tp + m.fp)) << name;
    } else {
      EXPECT_TRUE(j.at("precision").is_null()) << name;
    }
    EXPECT_DOUBLE_EQ(j.at("f1").num(), 2 * tp / static_cast<double>(2 * m.tp + m.fp + m.fn)) << name;
    EXPECT_EQ(j.at("has_score").boolean, d.has_score);
    if (d.has_score) {
      const auto auc = metrics::roc_auc(d.decisions.score, d.input.labels);
      ASSERT_TRUE(auc);
      EXPECT_NEAR(j.at("auc").num(), *auc, 1e-12) << name;
    } else {
      EXPECT_TRUE(j.at("auc").is_null()) << name;
    }
  }
}

TEST(Evdenoise, SettingsReachTheFilterAndChainsWork) {
  const std::string& in = labelled_recording();
  struct Case {
    std::string filter;
    std::vector<std::pair<std::string, std::string>> settings;
  };
  for (const Case& c : {Case{"baf", {{"duration_us", "1000"}, {"init", "never"}}},
                        Case{"baf,baf", {{"duration_us", "5000"}}}, Case{"baf,baf", {{"baf.duration_us", "700"}}}}) {
    std::string args;
    for (const auto& [k, v] : c.settings) args += " --set " + k + "=" + v;
    const std::string out = (dir() / "settings.txt").string();
    const auto r = run(kEvdenoise + " " + q(in) + " " + q(out) + " --filter " + c.filter + args + " --metrics");
    ASSERT_EQ(r.status, 0) << c.filter << args << ": " << r.err;
    const Direct d = direct(in, c.filter, c.settings);
    EXPECT_TRUE(io::read_all(out).events == d.kept) << c.filter << args;
    const Json j = parse_json(r.out);
    ASSERT_EQ(j.at("filters").array.size(), c.filter == "baf" ? 1U : 2U);
    const double expected_duration = std::strtod(c.settings.front().second.c_str(), nullptr);
    for (const auto& stage : j.at("filters").array)
      EXPECT_EQ(stage.at("params").at("duration_us").num(), expected_duration) << c.filter << args;
  }
  // The defaults differ from a setting: the setting really changed the output.
  EXPECT_NE(direct(in, "baf").kept.size(), direct(in, "baf", {{"duration_us", "1000"}}).kept.size());
}

TEST(Evdenoise, PngIsAGridOfBeforeAndAfterFrames) {
  // The 1.5 s sample: 4 frames spread over it; a 50 ms recording: 2 consecutive frames (docs/evdenoise.md).
  auto expected = [](int frames) {
    return std::pair<int, int>{frames * 346 + (frames + 1) * 4, 2 * (20 + 260) + 3 * 4};
  };
  const std::string png = (dir() / "grid.png").string();
  auto r = run(kEvdenoise + " " + q(kSample) + " " + q((dir() / "grid.aedat4").string()) + " --filter baf -q --png " +
               q(png));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(png_size(png), expected(4));

  const std::string short_rec = (dir() / "short.txt").string();
  r = run(kEvsim + " --scene demo --duration-ms 50 --noise-hz 1 --seed 2 --out " + q(short_rec) + " --no-manifest");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string png2 = (dir() / "grid2.png").string();
  r = run(kEvdenoise + " " + q(short_rec) + " " + q((dir() / "short-out.txt").string()) + " --filter baf -q --png " +
          q(png2));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(png_size(png2), expected(2));

  r = run(kEvdenoise + " " + q(kSample) + " " + q((dir() / "grid.aedat4").string()) + " --filter baf --png " +
          q((dir() / "grid.nope").string()));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("grid.nope"), std::string::npos) << r.err;
}

TEST(Evdenoise, BadCommandLinesAreUsageErrorsAndTouchNoFile) {
  const std::string out = (dir() / "never-written.aedat4").string();
  struct Case {
    std::string args;
    std::string must_name;
  };
  for (const Case& c :
       {Case{"--filter nope", "nope"}, Case{"--filter baf,nope", "nope"}, Case{"--filter baf --set nokey=1", "nokey"},
        Case{"--filter baf --set duration_us=-5", "duration_us=-5"},
        Case{"--filter baf --set duration_us=abc", "duration_us=abc"},
        Case{"--filter baf --set init=sometimes", "init=sometimes"},
        Case{"--filter baf --set duration_us", "duration_us"},
        Case{"--filter baf,baf --set other.duration_us=5", "other"}, Case{"", "--filter"}}) {
    fs::remove(out);
    const auto r = run(kEvdenoise + " " + q(kSample) + " " + q(out) + " " + c.args);
    EXPECT_EQ(r.status, 2) << c.args << ": " << r.err;
    EXPECT_NE(r.err.find(c.must_name), std::string::npos) << c.args << ": " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "one line: " << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  // Output extension, and the output being the input.
  auto r = run(kEvdenoise + " " + q(kSample) + " " + q((dir() / "x.mp4").string()) + " --filter baf");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("x.mp4"), std::string::npos) << r.err;
  const std::string copy = (dir() / "copy.aedat4").string();
  fs::copy_file(kSample, copy, fs::copy_options::overwrite_existing);
  r = run(kEvdenoise + " " + q(copy) + " " + q(copy) + " --filter baf");
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(fs::file_size(copy), fs::file_size(kSample)) << "the input is untouched";
}

TEST(Evdenoise, MissingAndCorruptInputsAreRuntimeErrors) {
  const std::string out = (dir() / "from-missing.aedat4").string();
  fs::remove(out);
  auto r = run(kEvdenoise + " /nonexistent/in.aedat4 " + q(out) + " --filter baf");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("/nonexistent/in.aedat4"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));

  // A file cut inside its header.
  const std::string cut = (dir() / "cut-header.aedat4").string();
  const std::string bytes = slurp(kSample);
  std::ofstream(cut, std::ios::binary).write(bytes.data(), 300);
  r = run(kEvdenoise + " " + q(cut) + " " + q(out) + " --filter baf");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(cut + ": byte "), std::string::npos) << r.err;

  // Not an event file at all.
  const std::string junk = (dir() / "junk.bin").string();
  std::ofstream(junk, std::ios::binary) << std::string(1000, '\x7f');
  r = run(kEvdenoise + " " + q(junk) + " " + q(out) + " --filter baf");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(junk), std::string::npos) << r.err;
}

TEST(Evdenoise, FormatErrorMidFileWritesWhatWasDecidedAndFails) {
  // A labelled text file cut in the middle of a line: a fatal format error after many valid events.
  const std::string& full = labelled_recording();
  const std::string text = slurp(full);
  std::size_t at = text.find(' ', text.size() * 2 / 3);
  ASSERT_NE(at, std::string::npos);
  const std::string cut = (dir() / "cut-line.txt").string();
  std::ofstream(cut, std::ios::binary) << text.substr(0, at + 1);
  for (const auto& name : filter_names()) {
    const std::string out = (dir() / ("cut-line-" + name + ".txt")).string();
    const auto r = run(kEvdenoise + " " + q(cut) + " " + q(out) + " --filter " + name + " --metrics");
    EXPECT_EQ(r.status, 1) << name;
    EXPECT_NE(r.err.find(cut + ": byte "), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "one line: " << r.err;
    const Json j = parse_json(r.out);
    EXPECT_FALSE(j.at("error").is_null());
    const auto n = j.at("events_in").count();
    EXPECT_GT(n, 0U);
    // The output is complete and readable: exactly the direct run's decisions over the events read.
    const Direct d = direct(full, name, {}, n);
    const auto back = io::read_all(out);
    EXPECT_TRUE(back.events == d.kept) << name << " over the first " << n << " events";
    EXPECT_TRUE(back.labels == d.kept_labels) << name;
    EXPECT_EQ(j.at("events_kept").count(), d.kept.size());
  }
}

TEST(Evdenoise, ClockResetRestartsTheFilter) {
  // The labelled recording twice: first shifted 2 s later, then as is, so the clock jumps back by ~2 s (a
  // discontinuity, not disorder). Expected: each part run through a fresh filter, the first one finished.
  const EventBatch part = io::read_all(labelled_recording());
  std::vector<Event> later_events = part.events;
  for (Event& e : later_events) e.t_us += 2'000'000;
  const std::vector<Event>& later = later_events;
  const std::string in = (dir() / "reset.txt").string();
  {
    std::ofstream f(in);
    f << "# width=346 height=260\n";
    for (const auto* events : {&later, &part.events})
      for (std::size_t i = 0; i < events->size(); ++i) {
        const Event& e = (*events)[i];
        f << e.t_us << ' ' << e.x << ' ' << e.y << ' ' << (e.polarity ? 1 : 0) << ' '
          << (part.labels[i] == Label::signal ? 1 : 0) << '\n';
      }
  }
  for (const auto& name : filter_names()) {
    std::vector<Event> expected;
    for (const auto* events : {&later, &part.events}) {
      auto f = denoise::make_filter_chain(name, {}, kDavis346);
      const auto d = denoise::run_filter(*f, *events);
      for (std::size_t i = 0; i < events->size(); ++i)
        if (d.keep[i] != 0) expected.push_back((*events)[i]);
    }
    const std::string out = (dir() / ("reset-" + name + ".txt")).string();
    const auto r = run(kEvdenoise + " " + q(in) + " " + q(out) + " --filter " + name + " --metrics");
    ASSERT_EQ(r.status, 0) << name << ": " << r.err;
    const Json j = parse_json(r.out);
    EXPECT_EQ(j.at("discontinuities").count(), 1U);
    EXPECT_EQ(j.at("out_of_order_dropped").count(), 0U);
    EXPECT_EQ(j.at("events_in").count(), 2 * part.events.size());
    io::ReaderOptions keep_order;
    keep_order.out_of_order = io::OutOfOrderPolicy::keep;
    const auto back = io::read_all(out, keep_order);
    EXPECT_EQ(back.events.size(), expected.size()) << name;
    EXPECT_TRUE(back.events == expected) << name;
  }
}

TEST(Evdenoise, RealEmlbDemoMatchesTheReferenceNumbers) {
  // denoise.md §8.3 / §8.4: dv-processing's BA filter (2 000 µs) keeps 261 950 of 319 512 events; the reference
  // ESR is 1.0133 raw (10 chunks) and 1.0374 after BA (printed to 4 decimals).
  EVPIPE_REQUIRE_REAL(in, "emlb-demo-01/demo-01.aedat4");
  const std::string out = (dir() / "demo-01-baf.aedat4").string();
  const auto r = run(kEvdenoise + " " + q(in) + " " + q(out) + " --filter baf --metrics");
  ASSERT_EQ(r.status, 0) << r.err;
  const Json j = parse_json(r.out);
  EXPECT_EQ(j.at("events_in").count(), 319'512U);
  EXPECT_EQ(j.at("events_kept").count(), 261'950U);
  EXPECT_EQ(j.at("esr_raw").at("chunks").count(), 10U);
  EXPECT_NEAR(j.at("esr_raw").at("mean").num(), 1.0133, 6e-5);
  EXPECT_EQ(j.at("esr_filtered").at("chunks").count(), 8U);
  EXPECT_NEAR(j.at("esr_filtered").at("mean").num(), 1.0374, 6e-5);
  EXPECT_EQ(io::read_all(out).events.size(), 261'950U);
}
