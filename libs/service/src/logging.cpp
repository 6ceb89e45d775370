#include "evpipe/service/logging.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <string_view>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>

namespace evpipe::service {

namespace {
// Parses "<device>:<inode>" (both decimal, as systemd writes them); false on anything else.
bool parse_journal_stream(std::string_view text, unsigned long long& device, unsigned long long& inode) {
  const auto colon = text.find(':');
  if (colon == std::string_view::npos || colon == 0 || colon + 1 == text.size()) return false;
  auto parse = [](std::string_view digits, unsigned long long& out) {
    out = 0;
    for (char c : digits) {
      if (c < '0' || c > '9') return false;
      out = out * 10 + static_cast<unsigned long long>(c - '0');
    }
    return true;
  };
  return parse(text.substr(0, colon), device) && parse(text.substr(colon + 1), inode);
}
}  // namespace

bool journal_attached() {
  const char* value = std::getenv("JOURNAL_STREAM");
  if (value == nullptr) return false;
  unsigned long long device = 0, inode = 0;
  if (!parse_journal_stream(value, device, inode)) return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == device && static_cast<unsigned long long>(st.st_ino) == inode;
}

std::shared_ptr<spdlog::logger> make_logger(const std::string& name) {
  if (journal_attached()) {
    // No formatting: the journal stores time, priority and identifier as fields of its own.
    auto sink = std::make_shared<spdlog::sinks::systemd_sink_mt>(name, false);
    return std::make_shared<spdlog::logger>(name, std::move(sink));
  }
  auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  auto logger = std::make_shared<spdlog::logger>(name, std::move(sink));
  logger->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%^%l%$] %v");
  return logger;
}

}  // namespace evpipe::service
