/* evpipe libcaer stub: logging (see libcaer.h for what this stub is). */
#ifndef LIBCAER_LOG_H_
#define LIBCAER_LOG_H_

#include "libcaer.h"

#ifdef __cplusplus
#	include <cstdarg>
#else
#	include <stdarg.h>
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* syslog-style severities: a message is emitted when its level <= the configured level. */
enum caer_log_level {
	CAER_LOG_EMERGENCY = 0,
	CAER_LOG_ALERT     = 1,
	CAER_LOG_CRITICAL  = 2,
	CAER_LOG_ERROR     = 3,
	CAER_LOG_WARNING   = 4,
	CAER_LOG_NOTICE    = 5,
	CAER_LOG_INFO      = 6,
	CAER_LOG_DEBUG     = 7,
};

/* Receives each formatted line "<time>: <LEVEL>: <subsystem>: <message>\n" and its length. */
typedef void (*caerLogCallback)(const char *msg, size_t msgLength);

void caerLogLevelSet(enum caer_log_level logLevel);
enum caer_log_level caerLogLevelGet(void);
void caerLogCallbackSet(caerLogCallback callback);
caerLogCallback caerLogCallbackGet(void);
/* Up to two file descriptors receive every line (default: 2 = stderr, and none); -1 disables one. */
void caerLogFileDescriptorsSet(int fd1, int fd2);
int caerLogFileDescriptorsGetFirst(void);
int caerLogFileDescriptorsGetSecond(void);
void caerLog(enum caer_log_level logLevel, const char *subSystem, const char *format, ...)
	__attribute__((format(printf, 3, 4)));
void caerLogVA(enum caer_log_level logLevel, const char *subSystem, const char *format, va_list args)
	__attribute__((format(printf, 3, 0)));
void caerLogVAFull(uint8_t systemLogLevel, enum caer_log_level logLevel, const char *subSystem, const char *format,
	va_list args) __attribute__((format(printf, 4, 0)));

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_LOG_H_ */
