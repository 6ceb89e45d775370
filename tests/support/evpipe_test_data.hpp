#pragma once
// Paths to test data and a skip helper for the third-party recordings in ../shared/data/real.

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <string>

namespace evpipe::testing {

inline std::filesystem::path shared_data_dir() {
  return EVPIPE_SHARED_DATA_DIR;
}
inline std::filesystem::path source_dir() {
  return EVPIPE_SOURCE_DIR;
}
inline std::filesystem::path binary_dir() {
  return EVPIPE_BINARY_DIR;
}

/// Path of a real recording, e.g. real("davis346-faery/davis346.aedat4"); empty when absent.
inline std::string real(const std::string& rel) {
  const auto p = shared_data_dir() / rel;
  return std::filesystem::exists(p) ? p.string() : std::string{};
}

/// A fresh temporary directory for one test.
inline std::filesystem::path temp_dir(const std::string& tag) {
  auto d = std::filesystem::temp_directory_path() / ("evpipe-test-" + tag + "-" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace evpipe::testing

/// Skips the current test with a clear message when a real recording is not available.
#define EVPIPE_REQUIRE_REAL(var, rel)                                                              \
  const std::string var = ::evpipe::testing::real(rel);                                            \
  if (var.empty())                                                                                 \
  GTEST_SKIP() << "real recording not available: " << (::evpipe::testing::shared_data_dir() / rel) \
               << " (../shared/data/real is absent)"
