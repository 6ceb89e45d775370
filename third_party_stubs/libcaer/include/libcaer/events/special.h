/*
 * evpipe libcaer stub: special events (timestamp wrap/reset, external inputs, ...) (see libcaer.h).
 *
 * One event is 8 bytes, packed: uint32 data, int32 timestamp.
 * data bit 0 = valid, bits 1-7 = type (enum caer_special_event_types), bits 8-31 = payload.
 */
#ifndef LIBCAER_EVENTS_SPECIAL_H_
#define LIBCAER_EVENTS_SPECIAL_H_

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPECIAL_TYPE_SHIFT 1
#define SPECIAL_TYPE_MASK 0x0000007F
#define SPECIAL_DATA_SHIFT 8
#define SPECIAL_DATA_MASK 0x00FFFFFF

enum caer_special_event_types {
	TIMESTAMP_WRAP                    = 0,
	TIMESTAMP_RESET                   = 1,
	EXTERNAL_INPUT_RISING_EDGE        = 2,
	EXTERNAL_INPUT_FALLING_EDGE       = 3,
	EXTERNAL_INPUT_PULSE              = 4,
	DVS_ROW_ONLY                      = 5,
	EXTERNAL_INPUT1_RISING_EDGE       = 6,
	EXTERNAL_INPUT1_FALLING_EDGE      = 7,
	EXTERNAL_INPUT1_PULSE             = 8,
	EXTERNAL_INPUT2_RISING_EDGE       = 9,
	EXTERNAL_INPUT2_FALLING_EDGE      = 10,
	EXTERNAL_INPUT2_PULSE             = 11,
	EXTERNAL_GENERATOR_RISING_EDGE    = 12,
	EXTERNAL_GENERATOR_FALLING_EDGE   = 13,
	APS_FRAME_START                   = 14,
	APS_FRAME_END                     = 15,
	APS_EXPOSURE_START                = 16,
	APS_EXPOSURE_END                  = 17,
	EVENT_READOUT_START               = 18,
};

PACKED_STRUCT(struct caer_special_event {
	uint32_t data;
	int32_t timestamp;
});

typedef struct caer_special_event *caerSpecialEvent;
typedef const struct caer_special_event *caerSpecialEventConst;

PACKED_STRUCT(struct caer_special_event_packet {
	struct caer_event_packet_header packetHeader;
	struct caer_special_event events[];
});

typedef struct caer_special_event_packet *caerSpecialEventPacket;
typedef const struct caer_special_event_packet *caerSpecialEventPacketConst;

static inline caerSpecialEventPacket caerSpecialEventPacketAllocate(int32_t eventCapacity, int16_t eventSource,
	int32_t tsOverflow) {
	return ((caerSpecialEventPacket) caerEventPacketAllocate(eventCapacity, eventSource, tsOverflow, SPECIAL_EVENT,
		(int32_t) sizeof(struct caer_special_event), (int32_t) offsetof(struct caer_special_event, timestamp)));
}

static inline caerSpecialEventPacket caerSpecialEventPacketFromPacketHeader(caerEventPacketHeader header) {
	if (header == NULL) {
		return (NULL);
	}
	if (caerEventPacketHeaderGetEventType(header) != SPECIAL_EVENT) {
		caerLog(CAER_LOG_CRITICAL, "Special Event", "Called caerSpecialEventPacketFromPacketHeader() with a packet of "
			"event type %" PRIi16 ".", caerEventPacketHeaderGetEventType(header));
		return (NULL);
	}
	return ((caerSpecialEventPacket) header);
}

static inline caerSpecialEventPacketConst caerSpecialEventPacketFromPacketHeaderConst(caerEventPacketHeaderConst header) {
	return (caerSpecialEventPacketFromPacketHeader((caerEventPacketHeader) (uintptr_t) header));
}

static inline caerSpecialEvent caerSpecialEventPacketGetEvent(caerSpecialEventPacket packet, int32_t n) {
	if (n < 0 || n >= caerEventPacketHeaderGetEventCapacity(&packet->packetHeader)) {
		caerLog(CAER_LOG_CRITICAL, "Special Event", "Called caerSpecialEventPacketGetEvent() with invalid event offset %"
			PRIi32 ", while maximum allowed value is %" PRIi32 ".", n,
			caerEventPacketHeaderGetEventCapacity(&packet->packetHeader) - 1);
		return (NULL);
	}
	return (packet->events + n);
}

static inline caerSpecialEventConst caerSpecialEventPacketGetEventConst(caerSpecialEventPacketConst packet, int32_t n) {
	return (caerSpecialEventPacketGetEvent((caerSpecialEventPacket) (uintptr_t) packet, n));
}

static inline int32_t caerSpecialEventGetTimestamp(caerSpecialEventConst event) {
	return (event->timestamp);
}
static inline int64_t caerSpecialEventGetTimestamp64(caerSpecialEventConst event, caerSpecialEventPacketConst packet) {
	return ((int64_t) (((uint64_t) caerEventPacketHeaderGetEventTSOverflow(&packet->packetHeader) << TS_OVERFLOW_SHIFT)
					   | (uint64_t) caerSpecialEventGetTimestamp(event)));
}
static inline void caerSpecialEventSetTimestamp(caerSpecialEvent event, int32_t timestamp) {
	if (timestamp < 0) {
		caerLog(CAER_LOG_CRITICAL, "Special Event", "Called caerSpecialEventSetTimestamp() with negative value!");
		return;
	}
	event->timestamp = timestamp;
}

static inline bool caerSpecialEventIsValid(caerSpecialEventConst event) {
	return ((event->data >> VALID_MARK_SHIFT) & VALID_MARK_MASK);
}
static inline void caerSpecialEventValidate(caerSpecialEvent event, caerSpecialEventPacket packet) {
	if (caerSpecialEventIsValid(event)) {
		caerLog(CAER_LOG_CRITICAL, "Special Event", "Called caerSpecialEventValidate() on already valid event.");
		return;
	}
	event->data |= (uint32_t) VALID_MARK_MASK << VALID_MARK_SHIFT;
	packet->packetHeader.eventValid = packet->packetHeader.eventValid + 1;
}
static inline void caerSpecialEventInvalidate(caerSpecialEvent event, caerSpecialEventPacket packet) {
	if (!caerSpecialEventIsValid(event)) {
		caerLog(CAER_LOG_CRITICAL, "Special Event", "Called caerSpecialEventInvalidate() on already invalid event.");
		return;
	}
	event->data &= ~((uint32_t) VALID_MARK_MASK << VALID_MARK_SHIFT);
	packet->packetHeader.eventValid = packet->packetHeader.eventValid - 1;
}

static inline uint8_t caerSpecialEventGetType(caerSpecialEventConst event) {
	return ((uint8_t) ((event->data >> SPECIAL_TYPE_SHIFT) & SPECIAL_TYPE_MASK));
}
static inline void caerSpecialEventSetType(caerSpecialEvent event, uint8_t type) {
	event->data = (event->data & ~((uint32_t) SPECIAL_TYPE_MASK << SPECIAL_TYPE_SHIFT))
				| (((uint32_t) type & SPECIAL_TYPE_MASK) << SPECIAL_TYPE_SHIFT);
}
static inline uint32_t caerSpecialEventGetData(caerSpecialEventConst event) {
	return ((event->data >> SPECIAL_DATA_SHIFT) & SPECIAL_DATA_MASK);
}
static inline void caerSpecialEventSetData(caerSpecialEvent event, uint32_t data) {
	event->data = (event->data & ~((uint32_t) SPECIAL_DATA_MASK << SPECIAL_DATA_SHIFT))
				| ((data & SPECIAL_DATA_MASK) << SPECIAL_DATA_SHIFT);
}

/* The first event (valid or not) of the given type in the packet, or NULL. */
static inline caerSpecialEvent caerSpecialEventPacketFindEventByType(caerSpecialEventPacket packet, uint8_t type) {
	if (packet == NULL) {
		return (NULL);
	}
	for (int32_t i = 0; i < caerEventPacketHeaderGetEventNumber(&packet->packetHeader); i++) {
		caerSpecialEvent event = packet->events + i;
		if (caerSpecialEventGetType(event) == type) {
			return (event);
		}
	}
	return (NULL);
}

/* The first valid event of the given type in the packet, or NULL. */
static inline caerSpecialEvent caerSpecialEventPacketFindValidEventByType(caerSpecialEventPacket packet, uint8_t type) {
	if (packet == NULL) {
		return (NULL);
	}
	for (int32_t i = 0; i < caerEventPacketHeaderGetEventNumber(&packet->packetHeader); i++) {
		caerSpecialEvent event = packet->events + i;
		if (caerSpecialEventIsValid(event) && caerSpecialEventGetType(event) == type) {
			return (event);
		}
	}
	return (NULL);
}
static inline caerSpecialEventConst caerSpecialEventPacketFindValidEventByTypeConst(caerSpecialEventPacketConst packet,
	uint8_t type) {
	return (caerSpecialEventPacketFindValidEventByType((caerSpecialEventPacket) (uintptr_t) packet, type));
}

#define CAER_SPECIAL_ITERATOR_ALL_START(SPECIAL_PACKET)                                                                 \
	for (int32_t caerSpecialIteratorCounter = 0;                                                                        \
		 caerSpecialIteratorCounter < caerEventPacketHeaderGetEventNumber(&(SPECIAL_PACKET)->packetHeader);             \
		 caerSpecialIteratorCounter++) {                                                                                \
		caerSpecialEvent caerSpecialIteratorElement = caerSpecialEventPacketGetEvent(SPECIAL_PACKET, caerSpecialIteratorCounter);

#define CAER_SPECIAL_CONST_ITERATOR_ALL_START(SPECIAL_PACKET)                                                           \
	for (int32_t caerSpecialIteratorCounter = 0;                                                                        \
		 caerSpecialIteratorCounter < caerEventPacketHeaderGetEventNumber(&(SPECIAL_PACKET)->packetHeader);             \
		 caerSpecialIteratorCounter++) {                                                                                \
		caerSpecialEventConst caerSpecialIteratorElement                                                                \
			= caerSpecialEventPacketGetEventConst(SPECIAL_PACKET, caerSpecialIteratorCounter);

#define CAER_SPECIAL_ITERATOR_ALL_END }

#define CAER_SPECIAL_ITERATOR_VALID_START(SPECIAL_PACKET)                                                               \
	for (int32_t caerSpecialIteratorCounter = 0;                                                                        \
		 caerSpecialIteratorCounter < caerEventPacketHeaderGetEventNumber(&(SPECIAL_PACKET)->packetHeader);             \
		 caerSpecialIteratorCounter++) {                                                                                \
		caerSpecialEvent caerSpecialIteratorElement = caerSpecialEventPacketGetEvent(SPECIAL_PACKET, caerSpecialIteratorCounter); \
		if (!caerSpecialEventIsValid(caerSpecialIteratorElement)) {                                                     \
			continue;                                                                                                   \
		}

#define CAER_SPECIAL_CONST_ITERATOR_VALID_START(SPECIAL_PACKET)                                                         \
	for (int32_t caerSpecialIteratorCounter = 0;                                                                        \
		 caerSpecialIteratorCounter < caerEventPacketHeaderGetEventNumber(&(SPECIAL_PACKET)->packetHeader);             \
		 caerSpecialIteratorCounter++) {                                                                                \
		caerSpecialEventConst caerSpecialIteratorElement                                                                \
			= caerSpecialEventPacketGetEventConst(SPECIAL_PACKET, caerSpecialIteratorCounter);                          \
		if (!caerSpecialEventIsValid(caerSpecialIteratorElement)) {                                                     \
			continue;                                                                                                   \
		}

#define CAER_SPECIAL_ITERATOR_VALID_END }

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_SPECIAL_H_ */
