#pragma once
// Where evpipe's log goes: to the journal with proper priorities when systemd connected stderr to journald
// ($JOURNAL_STREAM matches stderr), otherwise to stderr with timestamps and colours.

#include <memory>
#include <string>

#include <spdlog/logger.h>

namespace evpipe::service {

/// True when stderr is the journal stream systemd set up ($JOURNAL_STREAM = "<device>:<inode>" of stderr).
/// Comparing with fstat(stderr) rather than only testing the variable: a program started from a service whose
/// stderr was redirected (e.g. into a file) inherits the variable but does not write to the journal.
[[nodiscard]] bool journal_attached();

/// A logger named `name`: spdlog's systemd sink (sd_journal_send with PRIORITY=, SYSLOG_IDENTIFIER=`name`) when
/// journal_attached(), else a coloured stderr sink with the pattern "[time] [level] message". Not registered
/// in spdlog's registry: pass it to spdlog::set_default_logger.
[[nodiscard]] std::shared_ptr<spdlog::logger> make_logger(const std::string& name);

}  // namespace evpipe::service
