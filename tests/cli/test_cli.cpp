// The programs' command-line front (libs/cli): values bound, checks and relations applied, and the exit status of
// App::parse (nothing to go on with, 0 after --help, 2 for a usage error) as every program uses it.

#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "evpipe/cli/cli.hpp"

namespace {

using evpipe::cli::App;

std::optional<int> parse(App& app, std::vector<std::string> args) {
  args.insert(args.begin(), "prog");
  std::vector<const char*> argv;
  for (const auto& a : args) argv.push_back(a.c_str());
  return app.parse(static_cast<int>(argv.size()), argv.data());
}

TEST(Cli, BindsValuesOfEveryKind) {
  App app{"test"};
  std::string in;
  double rate = 0.0;
  int threads = 1;
  std::int64_t t0_us = 0;
  std::size_t batch = 0;
  std::vector<std::string> sets;
  bool quiet = false, manifest = true;
  app.add_option("IN", in, "input")->required();
  app.add_option("--rate", rate)->check(evpipe::cli::non_negative_number());
  app.add_option("--threads", threads)->check(evpipe::cli::range(1, 64));
  app.add_option("--t0-us", t0_us)->check(evpipe::cli::range(std::int64_t{-5}, std::int64_t{3'600'000'000}));
  app.add_option("--batch", batch)->check(evpipe::cli::range(std::size_t{1}, std::size_t{1} << 24));
  app.add_option("--set", sets)
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(evpipe::cli::MultiOptionPolicy::take_all);
  app.add_flag("-q,--quiet", quiet);
  app.add_flag("!--no-manifest", manifest);
  EXPECT_EQ(parse(app, {"a.aedat4", "--rate", "2.5", "--threads", "4", "--t0-us", "3000000000", "--batch", "7", "--set",
                        "a=1", "--set", "b=2", "-q", "--no-manifest"}),
            std::nullopt);
  EXPECT_EQ(in, "a.aedat4");
  EXPECT_EQ(rate, 2.5);
  EXPECT_EQ(threads, 4);
  EXPECT_EQ(t0_us, 3'000'000'000);
  EXPECT_EQ(batch, 7u);
  EXPECT_EQ(sets, (std::vector<std::string>{"a=1", "b=2"}));
  EXPECT_TRUE(quiet);
  EXPECT_FALSE(manifest);
  ASSERT_EQ(app.options().size(), 8u);
  EXPECT_EQ(app.options()[1]->count(), 1u);
  EXPECT_EQ(app.options()[1]->results(), (std::vector<std::string>{"2.5"}));
  EXPECT_EQ(app.options()[1]->get_name(), "--rate");
  EXPECT_EQ(app.options()[1]->get_type_name().rfind("FLOAT", 0), 0u);
}

TEST(Cli, OptionalValuesAndLists) {
  App app{"test"};
  app.always_capture_default();
  std::optional<std::string> config;
  std::optional<double> hz, unset;
  std::vector<std::string> stops;
  double png_t_ms = 0.0;
  app.add_option("--config", config);
  app.add_option("--hz", hz)->check(evpipe::cli::range(0.1, 30.0));
  app.add_option("--unset", unset);
  app.add_option("--stop", stops)->delimiter(',');
  app.add_option("--png-t-ms", png_t_ms)->default_str("middle");
  EXPECT_EQ(parse(app, {"--config", "a.yaml", "--hz", "12.5", "--stop", "1:2,3:4", "--stop", "5:6"}), std::nullopt);
  EXPECT_EQ(config, "a.yaml");
  EXPECT_EQ(hz, 12.5);
  EXPECT_FALSE(unset.has_value());
  EXPECT_EQ(stops, (std::vector<std::string>{"1:2", "3:4", "5:6"}));
  EXPECT_EQ(app.options()[4]->count(), 0u);
}

TEST(Cli, UsageErrorsAreStatusTwoAndHelpIsZero) {
  const auto fresh = [](std::vector<std::string> args) {
    App app{"test"};
    std::string in, a, b;
    int threads = 1;
    double speed = 1.0;
    app.add_option("IN", in)->required();
    app.add_option("--threads", threads)->check(evpipe::cli::range(1, 64));
    app.add_option("--speed", speed)->check(evpipe::cli::positive_number());
    app.add_option("--compression", a)->check(evpipe::cli::is_member({"lz4", "zstd", "none"}));
    auto* x = app.add_option("--x", b);
    auto* y = app.add_option("--y", b);
    x->excludes(y);
    return parse(app, std::move(args));
  };
  EXPECT_EQ(fresh({"in"}), std::nullopt);
  EXPECT_EQ(fresh({}), 2);                         // IN required
  EXPECT_EQ(fresh({"in", "--threads", "65"}), 2);  // out of range
  EXPECT_EQ(fresh({"in", "--threads", "x"}), 2);   // not a number
  EXPECT_EQ(fresh({"in", "--speed", "0"}), 2);
  EXPECT_EQ(fresh({"in", "--compression", "gzip"}), 2);
  EXPECT_EQ(fresh({"in", "--x", "1", "--y", "2"}), 2);
  EXPECT_EQ(fresh({"in", "--unknown"}), 2);
  EXPECT_EQ(fresh({"--help"}), 0);
}

TEST(Cli, VersionFlagIsStatusZero) {
  App app{"test"};
  app.set_version_flag("--version", "test 1.0");
  EXPECT_EQ(parse(app, {"--version"}), 0);
}

}  // namespace
