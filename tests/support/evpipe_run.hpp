#pragma once
// Running the project's programs from end-to-end tests: a shell command with stdout/stderr captured to files.

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>

namespace evpipe::testing {

struct Run {
  int status = -1;  ///< exit status, or 128 + signal
  std::string out;
  std::string err;
};

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

/// Runs `cmd` through the shell with stdin from /dev/null; its output is kept in numbered files under `dir`.
inline Run run(const std::string& cmd, const std::filesystem::path& dir) {
  static int counter = 0;
  const auto out = dir / ("stdout" + std::to_string(counter) + ".txt");
  const auto err = dir / ("stderr" + std::to_string(counter++) + ".txt");
  const std::string full = cmd + " >" + out.string() + " 2>" + err.string() + " </dev/null";
  const int rc = std::system(full.c_str());
  Run r;
  r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : 128 + WTERMSIG(rc);
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

/// A number, bool or string field of a flat one-line JSON object (evpipe --json); "<missing KEY>" if absent.
inline std::string json_field(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\":(\"[^\"]*\"|[^,}]*)");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return "<missing " + key + ">";
  std::string v = m[1];
  if (!v.empty() && v.front() == '"') v = v.substr(1, v.size() - 2);
  return v;
}

/// Single-quotes a path for the shell (test paths hold no quotes).
inline std::string q(const std::string& s) {
  return "'" + s + "'";
}

}  // namespace evpipe::testing
