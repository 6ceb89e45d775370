#pragma once
// Helpers for the evpipe::camera tests: reproducible seeds, scratch files, ModelError checks.

#include "evpipe/camera/error.hpp"
#include "evpipe_test_data.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <vector>

namespace evpipe::camera::test {

/// Suite seed: EVPIPE_TEST_SEED from the environment, else a fixed value (runs are reproducible by default).
inline std::uint64_t suite_seed() {
  static const std::uint64_t seed = [] {
    if (const char* s = std::getenv("EVPIPE_TEST_SEED"))
      return static_cast<std::uint64_t>(std::strtoull(s, nullptr, 10));
    return std::uint64_t{20250407};
  }();
  return seed;
}

/// A generator seeded from the suite seed and the current test's name (PoseLib-style); the seed is printed and
/// attached to failures so a failing case can be rerun with EVPIPE_TEST_SEED.
inline std::mt19937_64 test_rng() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string name = std::string(info->test_suite_name()) + "." + info->name();
  const std::uint64_t seed = suite_seed() ^ std::hash<std::string>{}(name);
  std::cout << "[   SEED   ] " << name << ": EVPIPE_TEST_SEED=" << suite_seed() << " (test seed " << seed << ")\n";
  ::testing::Test::RecordProperty("suite_seed", std::to_string(suite_seed()));
  return std::mt19937_64(seed);
}

/// Writes text to a fresh file in this test process's scratch directory and returns its path.
inline std::string write_file(const std::string& name, const std::string& text) {
  const auto dir = ::evpipe::testing::temp_dir("camera");
  const auto path = dir / name;
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

/// A shipped configuration file.
inline std::string config_file(const std::string& name) {
  return (::evpipe::testing::source_dir() / "config" / name).string();
}

/// Runs fn, expects a ModelError, and returns its message (empty + test failure otherwise).
inline std::string model_error_message(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const ModelError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected ModelError, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected ModelError, nothing was thrown";
  return {};
}

}  // namespace evpipe::camera::test
