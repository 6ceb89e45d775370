// evpipe libcaer stub: logging (same line format and default outputs as libcaer) and bias encoders.

#include <libcaer/devices/davis.h>
#include <libcaer/libcaer.h>

#include <unistd.h>

#include <atomic>
#include <cstdarg>
#include <cstdio>
#include <ctime>
#include <string>

namespace {

std::atomic<int> g_log_level{CAER_LOG_ERROR};
std::atomic<int> g_log_fd1{STDERR_FILENO};
std::atomic<int> g_log_fd2{-1};
std::atomic<caerLogCallback> g_log_callback{nullptr};

const char* level_name(enum caer_log_level level) {
  switch (level) {
    case CAER_LOG_EMERGENCY: return "EMERGENCY";
    case CAER_LOG_ALERT: return "ALERT";
    case CAER_LOG_CRITICAL: return "CRITICAL";
    case CAER_LOG_ERROR: return "ERROR";
    case CAER_LOG_WARNING: return "WARNING";
    case CAER_LOG_NOTICE: return "NOTICE";
    case CAER_LOG_INFO: return "INFO";
    case CAER_LOG_DEBUG: return "DEBUG";
  }
  return "UNKNOWN";
}

void write_all(int fd, const std::string& text) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) return;  // nothing sensible to do about a failing log sink
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

void caerLogLevelSet(enum caer_log_level logLevel) { g_log_level.store(logLevel); }

enum caer_log_level caerLogLevelGet(void) { return static_cast<enum caer_log_level>(g_log_level.load()); }

void caerLogCallbackSet(caerLogCallback callback) { g_log_callback.store(callback); }

caerLogCallback caerLogCallbackGet(void) { return g_log_callback.load(); }

void caerLogFileDescriptorsSet(int fd1, int fd2) {
  if (fd1 == fd2) fd2 = -1;  // one sink is enough
  g_log_fd1.store(fd1);
  g_log_fd2.store(fd2);
}

int caerLogFileDescriptorsGetFirst(void) { return g_log_fd1.load(); }

int caerLogFileDescriptorsGetSecond(void) { return g_log_fd2.load(); }

void caerLog(enum caer_log_level logLevel, const char* subSystem, const char* format, ...) {
  va_list args;
  va_start(args, format);
  caerLogVA(logLevel, subSystem, format, args);
  va_end(args);
}

void caerLogVA(enum caer_log_level logLevel, const char* subSystem, const char* format, va_list args) {
  caerLogVAFull(static_cast<uint8_t>(g_log_level.load()), logLevel, subSystem, format, args);
}

void caerLogVAFull(uint8_t systemLogLevel, enum caer_log_level logLevel, const char* subSystem, const char* format,
                   va_list args) {
  if (subSystem == nullptr || format == nullptr) return;
  if (static_cast<int>(logLevel) > static_cast<int>(systemLogLevel)) return;
  const int fd1 = g_log_fd1.load();
  const int fd2 = g_log_fd2.load();
  const caerLogCallback callback = g_log_callback.load();
  if (fd1 < 0 && fd2 < 0 && callback == nullptr) return;

  char message[2048];
  std::vsnprintf(message, sizeof message, format, args);

  const std::time_t now = std::time(nullptr);
  std::tm local{};
  localtime_r(&now, &local);
  char when[64];
  std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S (TZ%z)", &local);

  std::string line;
  line.reserve(64 + std::char_traits<char>::length(message));
  line.append(when).append(": ").append(level_name(logLevel)).append(": ").append(subSystem).append(": ");
  line.append(message).append("\n");

  if (fd1 >= 0) write_all(fd1, line);
  if (fd2 >= 0) write_all(fd2, line);
  if (callback != nullptr) callback(line.c_str(), line.size());
}

// ---- bias encoders ----
// VDAC: bits 0-5 voltage, bits 6-8 current.
uint16_t caerBiasVDACGenerate(const struct caer_bias_vdac vdacBias) {
  return static_cast<uint16_t>((vdacBias.voltageValue & 0x3Fu) | ((vdacBias.currentValue & 0x07u) << 6));
}

struct caer_bias_vdac caerBiasVDACParse(const uint16_t vdacBias) {
  struct caer_bias_vdac bias{};
  bias.voltageValue = static_cast<uint8_t>(vdacBias & 0x3Fu);
  bias.currentValue = static_cast<uint8_t>((vdacBias >> 6) & 0x07u);
  return bias;
}

namespace {
// The coarse field is stored with its three bits in reverse order.
uint8_t reverse3(uint8_t v) {
  return static_cast<uint8_t>(((v & 0x1u) << 2) | (v & 0x2u) | ((v & 0x4u) >> 2));
}
}  // namespace

// Coarse-fine: bit 0 enabled, bit 1 sex N, bit 2 type normal, bit 3 current level normal,
// bits 4-11 fine, bits 12-14 coarse (bit-reversed).
uint16_t caerBiasCoarseFineGenerate(const struct caer_bias_coarsefine coarseFineBias) {
  unsigned v = 0;
  if (coarseFineBias.enabled) v |= 0x1u;
  if (coarseFineBias.sexN) v |= 0x2u;
  if (coarseFineBias.typeNormal) v |= 0x4u;
  if (coarseFineBias.currentLevelNormal) v |= 0x8u;
  v |= (coarseFineBias.fineValue & 0xFFu) << 4;
  v |= (reverse3(static_cast<uint8_t>(coarseFineBias.coarseValue & 0x07u)) & 0x07u) << 12;
  return static_cast<uint16_t>(v);
}

struct caer_bias_coarsefine caerBiasCoarseFineParse(const uint16_t coarseFineBias) {
  struct caer_bias_coarsefine bias{};
  bias.enabled = (coarseFineBias & 0x1u) != 0;
  bias.sexN = (coarseFineBias & 0x2u) != 0;
  bias.typeNormal = (coarseFineBias & 0x4u) != 0;
  bias.currentLevelNormal = (coarseFineBias & 0x8u) != 0;
  bias.fineValue = static_cast<uint8_t>((coarseFineBias >> 4) & 0xFFu);
  bias.coarseValue = reverse3(static_cast<uint8_t>((coarseFineBias >> 12) & 0x07u));
  return bias;
}
