/*
 * evpipe clean-room stub of libcaer's C API (names, values and packed layouts of libcaer 3.3.15,
 * written from evpipe's reference notes, not from libcaer's sources). Used only when the real
 * libcaer is not installed: caerDeviceOpen() then returns a handle to a scripted FAKE device
 * (see libcaer_stub/fake_device.h). Never link this into a build meant for a real camera.
 */
#ifndef LIBCAER_LIBCAER_H_
#define LIBCAER_LIBCAER_H_

#ifdef __cplusplus
#	include <cerrno>
#	include <cinttypes>
#	include <cstddef>
#	include <cstdint>
#	include <cstdlib>
#	include <cstring>
#else
#	include <errno.h>
#	include <inttypes.h>
#	include <stdbool.h>
#	include <stddef.h>
#	include <stdint.h>
#	include <stdlib.h>
#	include <string.h>
#endif

#if !defined(__BYTE_ORDER__) || (__BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__)
/* The stub's inline accessors read packet fields in host order; libcaer's wire layout is little-endian. */
#	error "the libcaer stub supports little-endian hosts only"
#endif

#define LIBCAER_VERSION_MAJOR 3
#define LIBCAER_VERSION_MINOR 3
#define LIBCAER_VERSION_PATCH 15
/* major * 10000 + minor * 100 + patch, as in libcaer. */
#define LIBCAER_VERSION ((LIBCAER_VERSION_MAJOR * 10000) + (LIBCAER_VERSION_MINOR * 100) + LIBCAER_VERSION_PATCH)
#define LIBCAER_NAME_STRING "libcaer"
#define LIBCAER_VERSION_STRING "3.3.15"
/* Not in the real library: lets code and tests tell the stub from libcaer. */
#define LIBCAER_IS_STUB 1
#define LIBCAER_HAVE_OPENCV 0
#define LIBCAER_HAVE_SERIALDEV 0

#if defined(__GNUC__) || defined(__clang__)
#	define PACKED_STRUCT(STRUCT_DECLARATION) STRUCT_DECLARATION __attribute__((__packed__))
#	define LIBRARY_PUBLIC_VISIBILITY __attribute__((visibility("default")))
#else
#	error "the libcaer stub needs GCC or clang (packed structs)"
#endif

/* Explicit-cast helpers, as libcaer's headers provide them. */
#define U8T(X)  ((uint8_t) (X))
#define U16T(X) ((uint16_t) (X))
#define U32T(X) ((uint32_t) (X))
#define U64T(X) ((uint64_t) (X))
#define I8T(X)  ((int8_t) (X))
#define I16T(X) ((int16_t) (X))
#define I32T(X) ((int32_t) (X))
#define I64T(X) ((int64_t) (X))

/* Error codes stored in errno by caerDeviceOpen() when it returns NULL. */
enum caer_error_codes {
	CAER_ERROR_MEMORY_ALLOCATION   = -1,
	CAER_ERROR_RESOURCE_ALLOCATION = -2,
	CAER_ERROR_OPEN_ACCESS         = -3,
	CAER_ERROR_COMMUNICATION       = -4,
	CAER_ERROR_FW_VERSION          = -5,
	CAER_ERROR_LOGIC_VERSION       = -6,
};

#include "log.h"

#endif /* LIBCAER_LIBCAER_H_ */
