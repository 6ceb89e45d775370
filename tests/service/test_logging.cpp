// Log routing: journald when stderr is the journal stream systemd set up, stderr otherwise.
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>

#include "evpipe/service/logging.hpp"

namespace service = evpipe::service;

namespace {
std::string stderr_identity() {
  struct stat st {};
  EXPECT_EQ(fstat(STDERR_FILENO, &st), 0);
  return std::to_string(static_cast<unsigned long long>(st.st_dev)) + ":" +
         std::to_string(static_cast<unsigned long long>(st.st_ino));
}
template <class Sink>
bool has_sink(const spdlog::logger& logger) {
  return logger.sinks().size() == 1 && std::dynamic_pointer_cast<Sink>(logger.sinks().front()) != nullptr;
}
}  // namespace

TEST(Logging, JournalOnlyWhenJournalStreamIsStderr) {
  ::unsetenv("JOURNAL_STREAM");
  EXPECT_FALSE(service::journal_attached());

  ::setenv("JOURNAL_STREAM", stderr_identity().c_str(), 1);
  EXPECT_TRUE(service::journal_attached());

  // Inherited from a service but stderr now goes elsewhere: not the journal.
  ::setenv("JOURNAL_STREAM", "1:1", 1);
  EXPECT_FALSE(service::journal_attached());
  for (const char* bad : {"", ":", "12", "12:", ":34", "1x:2", "1:2:3"}) {
    ::setenv("JOURNAL_STREAM", bad, 1);
    EXPECT_FALSE(service::journal_attached()) << "JOURNAL_STREAM=\"" << bad << "\"";
  }
  ::unsetenv("JOURNAL_STREAM");
}

TEST(Logging, MakeLoggerPicksTheSink) {
  ::unsetenv("JOURNAL_STREAM");
  auto plain = service::make_logger("evpipe");
  ASSERT_NE(plain, nullptr);
  EXPECT_EQ(plain->name(), "evpipe");
  EXPECT_TRUE(has_sink<spdlog::sinks::stderr_color_sink_mt>(*plain));

  ::setenv("JOURNAL_STREAM", stderr_identity().c_str(), 1);
  auto journal = service::make_logger("evpipe");
  EXPECT_EQ(journal->name(), "evpipe");
  EXPECT_TRUE(has_sink<spdlog::sinks::systemd_sink_mt>(*journal));
  ::unsetenv("JOURNAL_STREAM");

  // Two loggers of the same name: not registered, so no "logger already exists" error.
  auto again = service::make_logger("evpipe");
  EXPECT_NE(again, plain);
}
