/*
 * evpipe libcaer stub: the event packet header shared by all event types (see libcaer.h).
 *
 * A packet is a 28-byte packed header followed by eventCapacity events of eventSize bytes each;
 * eventNumber of them are in use, eventValid of those have their valid bit (bit 0 of the first
 * 32-bit word) set. An event's full 64-bit timestamp is (eventTSOverflow << 31) | its 31-bit timestamp.
 */
#ifndef LIBCAER_EVENTS_COMMON_H_
#define LIBCAER_EVENTS_COMMON_H_

#include "../libcaer.h"

#ifdef __cplusplus
extern "C" {
#endif

#define VALID_MARK_SHIFT 0
#define VALID_MARK_MASK 0x00000001
#define TS_OVERFLOW_SHIFT 31

/* Event type IDs used in eventType. 5-11 are deprecated in libcaer 3.x and omitted here. */
enum caer_default_event_types {
	SPECIAL_EVENT   = 0,
	POLARITY_EVENT  = 1,
	FRAME_EVENT     = 2,
	IMU6_EVENT      = 3,
	IMU9_EVENT      = 4,
	SPIKE_EVENT     = 12,
	MATRIX4x4_EVENT = 13,
};
#define CAER_DEFAULT_EVENT_TYPES_COUNT 14

#define CAER_EVENT_PACKET_HEADER_SIZE 28

PACKED_STRUCT(struct caer_event_packet_header {
	int16_t eventType;
	int16_t eventSource;
	int32_t eventSize;
	int32_t eventTSOffset;
	int32_t eventTSOverflow;
	int32_t eventCapacity;
	int32_t eventNumber;
	int32_t eventValid;
});

typedef struct caer_event_packet_header *caerEventPacketHeader;
typedef const struct caer_event_packet_header *caerEventPacketHeaderConst;

/* ---- header field accessors ---- */
static inline int16_t caerEventPacketHeaderGetEventType(caerEventPacketHeaderConst header) {
	return (header->eventType);
}
static inline void caerEventPacketHeaderSetEventType(caerEventPacketHeader header, int16_t eventType) {
	if (eventType < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventType() with negative value!");
		return;
	}
	header->eventType = eventType;
}
static inline int16_t caerEventPacketHeaderGetEventSource(caerEventPacketHeaderConst header) {
	return (header->eventSource);
}
static inline void caerEventPacketHeaderSetEventSource(caerEventPacketHeader header, int16_t eventSource) {
	if (eventSource < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventSource() with negative value!");
		return;
	}
	header->eventSource = eventSource;
}
static inline int32_t caerEventPacketHeaderGetEventSize(caerEventPacketHeaderConst header) {
	return (header->eventSize);
}
static inline void caerEventPacketHeaderSetEventSize(caerEventPacketHeader header, int32_t eventSize) {
	if (eventSize < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventSize() with negative value!");
		return;
	}
	header->eventSize = eventSize;
}
static inline int32_t caerEventPacketHeaderGetEventTSOffset(caerEventPacketHeaderConst header) {
	return (header->eventTSOffset);
}
static inline void caerEventPacketHeaderSetEventTSOffset(caerEventPacketHeader header, int32_t eventTSOffset) {
	if (eventTSOffset < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventTSOffset() with negative value!");
		return;
	}
	header->eventTSOffset = eventTSOffset;
}
static inline int32_t caerEventPacketHeaderGetEventTSOverflow(caerEventPacketHeaderConst header) {
	return (header->eventTSOverflow);
}
static inline void caerEventPacketHeaderSetEventTSOverflow(caerEventPacketHeader header, int32_t eventTSOverflow) {
	if (eventTSOverflow < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventTSOverflow() with negative value!");
		return;
	}
	header->eventTSOverflow = eventTSOverflow;
}
static inline int32_t caerEventPacketHeaderGetEventCapacity(caerEventPacketHeaderConst header) {
	return (header->eventCapacity);
}
static inline void caerEventPacketHeaderSetEventCapacity(caerEventPacketHeader header, int32_t eventCapacity) {
	if (eventCapacity < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventCapacity() with negative value!");
		return;
	}
	header->eventCapacity = eventCapacity;
}
static inline int32_t caerEventPacketHeaderGetEventNumber(caerEventPacketHeaderConst header) {
	return (header->eventNumber);
}
static inline void caerEventPacketHeaderSetEventNumber(caerEventPacketHeader header, int32_t eventNumber) {
	if (eventNumber < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventNumber() with negative value!");
		return;
	}
	header->eventNumber = eventNumber;
}
static inline int32_t caerEventPacketHeaderGetEventValid(caerEventPacketHeaderConst header) {
	return (header->eventValid);
}
static inline void caerEventPacketHeaderSetEventValid(caerEventPacketHeader header, int32_t eventValid) {
	if (eventValid < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Header", "Called caerEventPacketHeaderSetEventValid() with negative value!");
		return;
	}
	header->eventValid = eventValid;
}

/* ---- generic event access ---- */
/* Pointer to event n (0 <= n < capacity), or NULL (logged) when out of range. */
static inline const void *caerEventPacketGetEventConst(caerEventPacketHeaderConst header, int32_t n) {
	if (n < 0 || n >= caerEventPacketHeaderGetEventCapacity(header)) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket", "Called caerEventPacketGetEvent() with invalid event offset %" PRIi32
			", while maximum allowed value is %" PRIi32 ".", n, caerEventPacketHeaderGetEventCapacity(header) - 1);
		return (NULL);
	}
	return ((const uint8_t *) header + CAER_EVENT_PACKET_HEADER_SIZE
			+ ((size_t) n * (size_t) caerEventPacketHeaderGetEventSize(header)));
}
static inline void *caerEventPacketGetEvent(caerEventPacketHeader header, int32_t n) {
	return ((void *) (uintptr_t) caerEventPacketGetEventConst(header, n));
}

/* Bytes of event data in use (eventNumber * eventSize) and of the whole packet in use (+ header). */
static inline int64_t caerEventPacketGetDataSize(caerEventPacketHeaderConst header) {
	return ((int64_t) caerEventPacketHeaderGetEventSize(header) * (int64_t) caerEventPacketHeaderGetEventNumber(header));
}
static inline int64_t caerEventPacketGetSize(caerEventPacketHeaderConst header) {
	return (CAER_EVENT_PACKET_HEADER_SIZE + caerEventPacketGetDataSize(header));
}

static inline int32_t caerGenericEventGetTimestamp(const void *eventPtr, caerEventPacketHeaderConst headerPtr) {
	int32_t ts;
	memcpy(&ts, (const uint8_t *) eventPtr + caerEventPacketHeaderGetEventTSOffset(headerPtr), sizeof(ts));
	return (ts);
}
static inline int64_t caerGenericEventGetTimestamp64(const void *eventPtr, caerEventPacketHeaderConst headerPtr) {
	return ((int64_t) (((uint64_t) caerEventPacketHeaderGetEventTSOverflow(headerPtr) << TS_OVERFLOW_SHIFT)
					   | (uint64_t) caerGenericEventGetTimestamp(eventPtr, headerPtr)));
}
static inline bool caerGenericEventIsValid(const void *eventPtr) {
	uint32_t firstWord;
	memcpy(&firstWord, eventPtr, sizeof(firstWord));
	return ((firstWord >> VALID_MARK_SHIFT) & VALID_MARK_MASK);
}

/* ---- allocation ---- */
/* A zeroed packet with room for eventCapacity events (all invalid, eventNumber 0); free() it.
   NULL (logged) on non-positive sizes or when the allocation fails. */
static inline caerEventPacketHeader caerEventPacketAllocate(int32_t eventCapacity, int16_t eventSource,
	int32_t eventTSOverflow, int16_t eventType, int32_t eventSize, int32_t eventTSOffset) {
	if (eventCapacity <= 0 || eventSize <= 0 || eventTSOffset < 0 || eventType < 0 || eventSource < 0
		|| eventTSOverflow < 0) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket", "Called caerEventPacketAllocate() with invalid arguments.");
		return (NULL);
	}
	size_t bytes = CAER_EVENT_PACKET_HEADER_SIZE + ((size_t) eventCapacity * (size_t) eventSize);
	caerEventPacketHeader packet = (caerEventPacketHeader) calloc(1, bytes);
	if (packet == NULL) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket", "Failed to allocate %zu bytes for event packet.", bytes);
		return (NULL);
	}
	packet->eventType       = eventType;
	packet->eventSource     = eventSource;
	packet->eventSize       = eventSize;
	packet->eventTSOffset   = eventTSOffset;
	packet->eventTSOverflow = eventTSOverflow;
	packet->eventCapacity   = eventCapacity;
	return (packet);
}

/* A new packet holding a copy of the events in use (capacity = eventNumber, or 1 when empty). */
static inline caerEventPacketHeader caerEventPacketCopyOnlyEvents(caerEventPacketHeaderConst header) {
	if (header == NULL) {
		return (NULL);
	}
	int32_t number = caerEventPacketHeaderGetEventNumber(header);
	caerEventPacketHeader copy = caerEventPacketAllocate((number > 0) ? number : 1, header->eventSource,
		header->eventTSOverflow, header->eventType, header->eventSize, header->eventTSOffset);
	if (copy == NULL) {
		return (NULL);
	}
	memcpy((uint8_t *) copy + CAER_EVENT_PACKET_HEADER_SIZE, (const uint8_t *) header + CAER_EVENT_PACKET_HEADER_SIZE,
		(size_t) caerEventPacketGetDataSize(header));
	copy->eventNumber = number;
	copy->eventValid  = header->eventValid;
	return (copy);
}

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_COMMON_H_ */
