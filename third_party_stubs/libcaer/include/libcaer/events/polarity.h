/*
 * evpipe libcaer stub: polarity (DVS) events (see libcaer.h).
 *
 * One event is 8 bytes, packed: uint32 data, int32 timestamp (31-bit, µs).
 * data bit 0 = valid, bit 1 = polarity (1 = ON), bits 2-16 = y, bits 17-31 = x.
 */
#ifndef LIBCAER_EVENTS_POLARITY_H_
#define LIBCAER_EVENTS_POLARITY_H_

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define POLARITY_SHIFT 1
#define POLARITY_MASK 0x00000001
#define POLARITY_Y_ADDR_SHIFT 2
#define POLARITY_Y_ADDR_MASK 0x00007FFF
#define POLARITY_X_ADDR_SHIFT 17
#define POLARITY_X_ADDR_MASK 0x00007FFF

PACKED_STRUCT(struct caer_polarity_event {
	uint32_t data;
	int32_t timestamp;
});

typedef struct caer_polarity_event *caerPolarityEvent;
typedef const struct caer_polarity_event *caerPolarityEventConst;

PACKED_STRUCT(struct caer_polarity_event_packet {
	struct caer_event_packet_header packetHeader;
	struct caer_polarity_event events[];
});

typedef struct caer_polarity_event_packet *caerPolarityEventPacket;
typedef const struct caer_polarity_event_packet *caerPolarityEventPacketConst;

static inline caerPolarityEventPacket caerPolarityEventPacketAllocate(int32_t eventCapacity, int16_t eventSource,
	int32_t tsOverflow) {
	return ((caerPolarityEventPacket) caerEventPacketAllocate(eventCapacity, eventSource, tsOverflow, POLARITY_EVENT,
		(int32_t) sizeof(struct caer_polarity_event), (int32_t) offsetof(struct caer_polarity_event, timestamp)));
}

/* The header viewed as a polarity packet; NULL for NULL or (logged) for another event type. */
static inline caerPolarityEventPacket caerPolarityEventPacketFromPacketHeader(caerEventPacketHeader header) {
	if (header == NULL) {
		return (NULL);
	}
	if (caerEventPacketHeaderGetEventType(header) != POLARITY_EVENT) {
		caerLog(CAER_LOG_CRITICAL, "Polarity Event", "Called caerPolarityEventPacketFromPacketHeader() with a packet of "
			"event type %" PRIi16 ".", caerEventPacketHeaderGetEventType(header));
		return (NULL);
	}
	return ((caerPolarityEventPacket) header);
}

static inline caerPolarityEventPacketConst caerPolarityEventPacketFromPacketHeaderConst(caerEventPacketHeaderConst header) {
	return (caerPolarityEventPacketFromPacketHeader((caerEventPacketHeader) (uintptr_t) header));
}

/* Event n (0 <= n < capacity), or NULL (logged) when out of range. */
static inline caerPolarityEvent caerPolarityEventPacketGetEvent(caerPolarityEventPacket packet, int32_t n) {
	if (n < 0 || n >= caerEventPacketHeaderGetEventCapacity(&packet->packetHeader)) {
		caerLog(CAER_LOG_CRITICAL, "Polarity Event", "Called caerPolarityEventPacketGetEvent() with invalid event offset %"
			PRIi32 ", while maximum allowed value is %" PRIi32 ".", n,
			caerEventPacketHeaderGetEventCapacity(&packet->packetHeader) - 1);
		return (NULL);
	}
	return (packet->events + n);
}

static inline caerPolarityEventConst caerPolarityEventPacketGetEventConst(caerPolarityEventPacketConst packet, int32_t n) {
	return (caerPolarityEventPacketGetEvent((caerPolarityEventPacket) (uintptr_t) packet, n));
}

static inline int32_t caerPolarityEventGetTimestamp(caerPolarityEventConst event) {
	return (event->timestamp);
}

/* Full 62-bit device time in µs: (packet tsOverflow << 31) | event timestamp. */
static inline int64_t caerPolarityEventGetTimestamp64(caerPolarityEventConst event, caerPolarityEventPacketConst packet) {
	return ((int64_t) (((uint64_t) caerEventPacketHeaderGetEventTSOverflow(&packet->packetHeader) << TS_OVERFLOW_SHIFT)
					   | (uint64_t) caerPolarityEventGetTimestamp(event)));
}

static inline void caerPolarityEventSetTimestamp(caerPolarityEvent event, int32_t timestamp) {
	if (timestamp < 0) {
		caerLog(CAER_LOG_CRITICAL, "Polarity Event", "Called caerPolarityEventSetTimestamp() with negative value!");
		return;
	}
	event->timestamp = timestamp;
}

static inline bool caerPolarityEventIsValid(caerPolarityEventConst event) {
	return ((event->data >> VALID_MARK_SHIFT) & VALID_MARK_MASK);
}

/* Sets the valid bit and counts the event in the packet's eventValid (logged no-op if already valid). */
static inline void caerPolarityEventValidate(caerPolarityEvent event, caerPolarityEventPacket packet) {
	if (caerPolarityEventIsValid(event)) {
		caerLog(CAER_LOG_CRITICAL, "Polarity Event", "Called caerPolarityEventValidate() on already valid event.");
		return;
	}
	event->data |= (uint32_t) VALID_MARK_MASK << VALID_MARK_SHIFT;
	packet->packetHeader.eventValid = packet->packetHeader.eventValid + 1;
}

static inline void caerPolarityEventInvalidate(caerPolarityEvent event, caerPolarityEventPacket packet) {
	if (!caerPolarityEventIsValid(event)) {
		caerLog(CAER_LOG_CRITICAL, "Polarity Event", "Called caerPolarityEventInvalidate() on already invalid event.");
		return;
	}
	event->data &= ~((uint32_t) VALID_MARK_MASK << VALID_MARK_SHIFT);
	packet->packetHeader.eventValid = packet->packetHeader.eventValid - 1;
}

static inline bool caerPolarityEventGetPolarity(caerPolarityEventConst event) {
	return ((event->data >> POLARITY_SHIFT) & POLARITY_MASK);
}
static inline void caerPolarityEventSetPolarity(caerPolarityEvent event, bool polarity) {
	event->data = (event->data & ~((uint32_t) POLARITY_MASK << POLARITY_SHIFT))
				| (((uint32_t) polarity & POLARITY_MASK) << POLARITY_SHIFT);
}
static inline uint16_t caerPolarityEventGetY(caerPolarityEventConst event) {
	return ((uint16_t) ((event->data >> POLARITY_Y_ADDR_SHIFT) & POLARITY_Y_ADDR_MASK));
}
static inline void caerPolarityEventSetY(caerPolarityEvent event, uint16_t yAddress) {
	event->data = (event->data & ~((uint32_t) POLARITY_Y_ADDR_MASK << POLARITY_Y_ADDR_SHIFT))
				| (((uint32_t) yAddress & POLARITY_Y_ADDR_MASK) << POLARITY_Y_ADDR_SHIFT);
}
static inline uint16_t caerPolarityEventGetX(caerPolarityEventConst event) {
	return ((uint16_t) ((event->data >> POLARITY_X_ADDR_SHIFT) & POLARITY_X_ADDR_MASK));
}
static inline void caerPolarityEventSetX(caerPolarityEvent event, uint16_t xAddress) {
	event->data = (event->data & ~((uint32_t) POLARITY_X_ADDR_MASK << POLARITY_X_ADDR_SHIFT))
				| (((uint32_t) xAddress & POLARITY_X_ADDR_MASK) << POLARITY_X_ADDR_SHIFT);
}

/* Iterators over the eventNumber events in use: caerPolarityIteratorElement / caerPolarityIteratorCounter
   are in scope inside the loop; the VALID variants skip invalidated events. */
#define CAER_POLARITY_ITERATOR_ALL_START(POLARITY_PACKET)                                                               \
	for (int32_t caerPolarityIteratorCounter = 0;                                                                       \
		 caerPolarityIteratorCounter < caerEventPacketHeaderGetEventNumber(&(POLARITY_PACKET)->packetHeader);           \
		 caerPolarityIteratorCounter++) {                                                                               \
		caerPolarityEvent caerPolarityIteratorElement                                                                   \
			= caerPolarityEventPacketGetEvent(POLARITY_PACKET, caerPolarityIteratorCounter);

#define CAER_POLARITY_CONST_ITERATOR_ALL_START(POLARITY_PACKET)                                                         \
	for (int32_t caerPolarityIteratorCounter = 0;                                                                       \
		 caerPolarityIteratorCounter < caerEventPacketHeaderGetEventNumber(&(POLARITY_PACKET)->packetHeader);           \
		 caerPolarityIteratorCounter++) {                                                                               \
		caerPolarityEventConst caerPolarityIteratorElement                                                              \
			= caerPolarityEventPacketGetEventConst(POLARITY_PACKET, caerPolarityIteratorCounter);

#define CAER_POLARITY_ITERATOR_ALL_END }

#define CAER_POLARITY_ITERATOR_VALID_START(POLARITY_PACKET)                                                             \
	for (int32_t caerPolarityIteratorCounter = 0;                                                                       \
		 caerPolarityIteratorCounter < caerEventPacketHeaderGetEventNumber(&(POLARITY_PACKET)->packetHeader);           \
		 caerPolarityIteratorCounter++) {                                                                               \
		caerPolarityEvent caerPolarityIteratorElement                                                                   \
			= caerPolarityEventPacketGetEvent(POLARITY_PACKET, caerPolarityIteratorCounter);                            \
		if (!caerPolarityEventIsValid(caerPolarityIteratorElement)) {                                                   \
			continue;                                                                                                   \
		}

#define CAER_POLARITY_CONST_ITERATOR_VALID_START(POLARITY_PACKET)                                                       \
	for (int32_t caerPolarityIteratorCounter = 0;                                                                       \
		 caerPolarityIteratorCounter < caerEventPacketHeaderGetEventNumber(&(POLARITY_PACKET)->packetHeader);           \
		 caerPolarityIteratorCounter++) {                                                                               \
		caerPolarityEventConst caerPolarityIteratorElement                                                              \
			= caerPolarityEventPacketGetEventConst(POLARITY_PACKET, caerPolarityIteratorCounter);                       \
		if (!caerPolarityEventIsValid(caerPolarityIteratorElement)) {                                                   \
			continue;                                                                                                   \
		}

#define CAER_POLARITY_ITERATOR_VALID_END }

#define CAER_POLARITY_REVERSE_ITERATOR_ALL_START(POLARITY_PACKET)                                                       \
	for (int32_t caerPolarityIteratorCounter = caerEventPacketHeaderGetEventNumber(&(POLARITY_PACKET)->packetHeader) - 1; \
		 caerPolarityIteratorCounter >= 0; caerPolarityIteratorCounter--) {                                             \
		caerPolarityEvent caerPolarityIteratorElement                                                                   \
			= caerPolarityEventPacketGetEvent(POLARITY_PACKET, caerPolarityIteratorCounter);

#define CAER_POLARITY_REVERSE_ITERATOR_ALL_END }

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_POLARITY_H_ */
