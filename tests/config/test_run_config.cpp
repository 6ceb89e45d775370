#include <gtest/gtest.h>

#include <fstream>

#include "evpipe/config/run_config.hpp"
#include "evpipe_test_data.hpp"

using evpipe::config::ConfigError;
using evpipe::config::parse_config;

namespace {
std::string error_of(const std::string& yaml) {
  try {
    parse_config(yaml, "t.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(RunConfig, DefaultsMatchThePaper) {
  const auto c = parse_config("");
  EXPECT_EQ(c.window.length_us, 30'000);
  EXPECT_EQ(c.window.hop_us, 30'000);
  EXPECT_EQ(c.source.speed, 1.0);
  EXPECT_TRUE(c.device.ba_filter);
  EXPECT_EQ(c.device.ba_filter_time_us, 2000);
}

TEST(RunConfig, ShippedConfigLoadsAndEqualsDefaults) {
  const auto path = evpipe::testing::source_dir() / "config" / "evpipe.yaml";
  const auto c = evpipe::config::load_config(path.string());
  EXPECT_EQ(c.to_yaml(), evpipe::config::RunConfig{}.to_yaml())
      << "config/evpipe.yaml must document every key with its default value";
}

TEST(RunConfig, RoundTripsThroughYaml) {
  auto c = parse_config("source: {speed: max, batch_events: 100}\nwindow: {length_us: 20000, hop_us: 5000}\n");
  EXPECT_FALSE(c.source.speed.has_value());
  const auto again = parse_config(c.to_yaml());
  EXPECT_EQ(again.to_yaml(), c.to_yaml());
  EXPECT_EQ(again.window.hop_us, 5000);
}

TEST(RunConfig, ErrorsNameFileAndKey) {
  EXPECT_EQ(error_of("window: {length_us: -5}")
                .rfind("t.yaml: line 1: window.length_us: must be in [1000, 1000000], got -5", 0),
            0U);
  EXPECT_NE(error_of("window: {lenght_us: 5}").find("t.yaml: line 1: window.lenght_us: unknown key"),
            std::string::npos);
  EXPECT_NE(error_of("foo: 1").find("t.yaml: line 1: foo: unknown section"), std::string::npos);
  EXPECT_NE(
      error_of("source: {speed: fast}").find("source.speed: must be 'max' or a number in [0.01, 1000], got 'fast'"),
      std::string::npos);
  EXPECT_NE(error_of("source: {batch_events: abc}")
                .find("t.yaml: line 1: source.batch_events: expected an integer, got 'abc'"),
            std::string::npos);
  EXPECT_NE(error_of("device: {ba_filter_time_us: 9999999}").find("device.ba_filter_time_us"), std::string::npos);
  EXPECT_NE(error_of("window: {length_us: 10000, hop_us: 20000}").find("window.hop_us"), std::string::npos);
  EXPECT_NE(error_of("log: {level: loud}").find("log.level"), std::string::npos);
  EXPECT_NE(error_of("source: [1, 2").find("t.yaml: line"), std::string::npos);
}

TEST(RunConfig, DenoiseSectionKeepsParamsInOrder) {
  const auto c = parse_config("denoise: {filter: 'hotpixel,curvature', params: {curvature.mode: causal, radius: 3}}");
  EXPECT_EQ(c.denoise.filter, "hotpixel,curvature");
  ASSERT_EQ(c.denoise.params.size(), 2U);
  EXPECT_EQ(c.denoise.params[0], (std::pair<std::string, std::string>{"curvature.mode", "causal"}));
  EXPECT_EQ(c.denoise.params[1], (std::pair<std::string, std::string>{"radius", "3"}));
  EXPECT_EQ(parse_config(c.to_yaml()).to_yaml(), c.to_yaml());
  EXPECT_EQ(parse_config("").denoise.filter, "significance");
  EXPECT_NE(error_of("denoise: {params: [1, 2]}").find("t.yaml: line 1: denoise.params: expected a map"),
            std::string::npos);
  EXPECT_NE(error_of("denoise: {filter: ''}").find("denoise.filter"), std::string::npos);
  EXPECT_NE(error_of("denoise: {filtre: baf}").find("t.yaml: line 1: denoise.filtre: unknown key"), std::string::npos);
}

TEST(RunConfig, PipelineFilterParamsAddEvpipesCurvatureDefaultsWhereUnset) {
  using Params = std::vector<std::pair<std::string, std::string>>;
  const auto params_of = [](const std::string& yaml) { return parse_config(yaml).denoise.pipeline_params(); };
  // The default filter (significance) gets exact_scores: false (it reads no scores), unless set.
  EXPECT_EQ(params_of(""), (Params{{"exact_scores", "false"}}));
  EXPECT_EQ(params_of("denoise: {params: {exact_scores: true}}"), (Params{{"exact_scores", "true"}}));
  EXPECT_EQ(params_of("denoise: {filter: 'hotpixel,significance'}"), (Params{{"significance.exact_scores", "false"}}));
  // curvature alone: singular keep, and the adaptive threshold capped at the paper's 5.
  EXPECT_EQ(params_of("denoise: {filter: curvature}"),
            (Params{{"singular", "keep"}, {"adaptive", "true"}, {"adaptive_max_threshold", "5"}}));
  // In a chain, prefixed; the user's own keys come first and are kept.
  EXPECT_EQ(params_of("denoise: {filter: 'hotpixel,curvature', params: {hotpixel.ratio: 9}}"),
            (Params{{"hotpixel.ratio", "9"},
                    {"curvature.singular", "keep"},
                    {"curvature.adaptive", "true"},
                    {"curvature.adaptive_max_threshold", "5"}}));
  // Any threshold choice of the user's stands as given (a fixed threshold stays fixed).
  EXPECT_EQ(params_of("denoise: {filter: curvature, params: {density_threshold: 6}}"),
            (Params{{"density_threshold", "6"}, {"singular", "keep"}}));
  EXPECT_EQ(params_of("denoise: {filter: curvature, params: {adaptive: false, singular: reject}}"),
            (Params{{"adaptive", "false"}, {"singular", "reject"}}));
  // A cap of the user's (0 = none) keeps adaptive on; adaptive set alone gets the cap; adaptive off gets none.
  EXPECT_EQ(params_of("denoise: {filter: curvature, params: {curvature.adaptive_max_threshold: 0}}"),
            (Params{{"curvature.adaptive_max_threshold", "0"}, {"singular", "keep"}, {"adaptive", "true"}}));
  EXPECT_EQ(params_of("denoise: {filter: curvature, params: {adaptive_max_threshold: 7}}"),
            (Params{{"adaptive_max_threshold", "7"}, {"singular", "keep"}, {"adaptive", "true"}}));
  EXPECT_EQ(
      params_of("denoise: {filter: 'hotpixel,curvature', params: {curvature.adaptive: true}}"),
      (Params{
          {"curvature.adaptive", "true"}, {"curvature.singular", "keep"}, {"curvature.adaptive_max_threshold", "5"}}));
  EXPECT_EQ(params_of("denoise: {filter: curvature, params: {adaptive: off}}"),
            (Params{{"adaptive", "off"}, {"singular", "keep"}}));
  // A bare key in a chain goes to the one filter that has it (curvature): it counts as set.
  EXPECT_EQ(params_of("denoise: {filter: 'hotpixel,curvature', params: {singular: reject, density_threshold: 4}}"),
            (Params{{"singular", "reject"}, {"density_threshold", "4"}}));
  // Other filters get nothing added.
  EXPECT_EQ(params_of("denoise: {filter: baf}"), Params{});
  EXPECT_EQ(params_of("denoise: {filter: none}"), Params{});
}

TEST(RunConfig, MissingFile) {
  try {
    evpipe::config::load_config("/nonexistent/evpipe.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/evpipe.yaml"), std::string::npos);
  }
}

TEST(RunConfig, LcmPipelineAndPoseSections) {
  const auto c = parse_config(
      "lcm: {url: 'memq://', pose_channel: P, stats_channel: S, stats_period_ms: 200, enabled: false}\n"
      "pipeline: {source_queue_packets: 8, source_queue_events: 50000, pose_queue_windows: 1, publish_queue: 4}\n"
      "pose: {ground_truth: gt.csv, lost_after_windows: 5, init_worker: off, init_worker_nice: 3, "
      "require_redundancy: true, direct_alignment: true}\n");
  EXPECT_EQ(c.lcm.url, "memq://");
  EXPECT_EQ(c.lcm.pose_channel, "P");
  EXPECT_EQ(c.lcm.stats_period_ms, 200);
  EXPECT_FALSE(c.lcm.enabled);
  EXPECT_EQ(c.pipeline.source_queue_packets, 8);
  EXPECT_EQ(c.pipeline.source_queue_events, 50000);
  EXPECT_EQ(c.pipeline.pose_queue_windows, 1);
  EXPECT_EQ(c.pose.ground_truth, "gt.csv");
  EXPECT_EQ(c.pose.lost_after_windows, 5);
  EXPECT_EQ(c.pose.init_worker, "off");
  EXPECT_EQ(c.pose.init_worker_nice, 3);
  EXPECT_TRUE(c.pose.require_redundancy);
  EXPECT_FALSE(parse_config("").pose.require_redundancy);
  EXPECT_EQ(c.pose.direct_alignment, "true");
  EXPECT_EQ(parse_config("").pose.direct_alignment, "auto");
  EXPECT_EQ(parse_config("pose: {direct_alignment: off}").pose.direct_alignment, "off");
  EXPECT_NE(error_of("pose: {direct_alignment: sometimes}").find("pose.direct_alignment"), std::string::npos);
  EXPECT_EQ(parse_config(c.to_yaml()).to_yaml(), c.to_yaml());
  EXPECT_NE(error_of("lcm: {stats_period_ms: 5000}").find("lcm.stats_period_ms: must be in [10, 1000]"),
            std::string::npos);
  EXPECT_NE(error_of("lcm: {pose_channel: ''}").find("lcm.pose_channel: must not be empty"), std::string::npos);
  EXPECT_NE(error_of("pipeline: {source_queue_packets: 1}").find("pipeline.source_queue_packets"), std::string::npos);
  EXPECT_NE(error_of("pipeline: {source_queue_events: 10}").find("pipeline.source_queue_events: must be in [1000, "),
            std::string::npos);
  EXPECT_NE(error_of("pose: {lost_after_windows: 0}").find("pose.lost_after_windows: must be in [1, 10000], got 0"),
            std::string::npos);
  EXPECT_NE(error_of("pose: {init_worker: sometimes}")
                .find("pose.init_worker: must be one of auto, on, off, got 'sometimes'"),
            std::string::npos);
  EXPECT_NE(error_of("pose: {init_worker_nice: 20}").find("pose.init_worker_nice: must be in [0, 19], got 20"),
            std::string::npos);
  EXPECT_NE(error_of("lcm: {urll: x}").find("t.yaml: line 1: lcm.urll: unknown key"), std::string::npos);
}

TEST(RunConfig, DenoiseThreads) {
  EXPECT_EQ(parse_config("denoise: {filter: curvature}\n").denoise.threads, 0);  // auto
  EXPECT_EQ(parse_config("denoise: {threads: auto}\n").denoise.threads, 0);
  const auto c = parse_config("denoise: {threads: 3}\n");
  EXPECT_EQ(c.denoise.threads, 3);
  EXPECT_EQ(parse_config(c.to_yaml()).denoise.threads, 3);
  EXPECT_EQ(parse_config(parse_config("{}\n").to_yaml()).denoise.threads, 0);
  EXPECT_NE(error_of("denoise: {threads: 0}").find("denoise.threads: must be 'auto' or in [1, 64], got 0"),
            std::string::npos);
  EXPECT_NE(error_of("denoise: {threads: many}").find("denoise.threads: expected a number or 'auto', got 'many'"),
            std::string::npos);
}

TEST(RunConfig, LcmPreviewKeys) {  // issue 22: off by default, 10 Hz when on
  const evpipe::config::RunConfig defaults;
  EXPECT_FALSE(defaults.lcm.preview);
  EXPECT_DOUBLE_EQ(defaults.lcm.preview_hz, 10.0);
  EXPECT_EQ(defaults.lcm.preview_channel, "EVPIPE_PREVIEW");
  const auto c = parse_config("lcm: {preview: true, preview_hz: 2.5, preview_channel: VIEW}\n");
  EXPECT_TRUE(c.lcm.preview);
  EXPECT_DOUBLE_EQ(c.lcm.preview_hz, 2.5);
  EXPECT_EQ(c.lcm.preview_channel, "VIEW");
  EXPECT_EQ(parse_config(c.to_yaml()).to_yaml(), c.to_yaml());
  EXPECT_NE(error_of("lcm: {preview_hz: 100}").find("lcm.preview_hz: must be a number in [0.1, 30]"),
            std::string::npos);
  EXPECT_NE(error_of("lcm: {preview_channel: ''}").find("lcm.preview_channel: must not be empty"), std::string::npos);
}
