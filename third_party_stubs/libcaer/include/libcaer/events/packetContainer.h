/*
 * evpipe libcaer stub: event packet containers (see libcaer.h).
 *
 * A container groups the packets of one time slice (one slot per event type for a DAVIS; a slot is
 * NULL when that type had no events). The container owns its packets: caerEventPacketContainerFree()
 * frees them all.
 */
#ifndef LIBCAER_EVENTS_PACKETCONTAINER_H_
#define LIBCAER_EVENTS_PACKETCONTAINER_H_

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

PACKED_STRUCT(struct caer_event_packet_container {
	int64_t lowestEventTimestamp;  /* lowest 64-bit timestamp over all packets, -1 when empty */
	int64_t highestEventTimestamp; /* highest 64-bit timestamp over all packets, -1 when empty */
	int32_t eventsNumber;          /* sum of eventNumber over all packets */
	int32_t eventsValidNumber;     /* sum of eventValid over all packets */
	int32_t eventPacketsNumber;    /* number of slots in eventPackets[] */
	caerEventPacketHeader eventPackets[];
});

typedef struct caer_event_packet_container *caerEventPacketContainer;
typedef const struct caer_event_packet_container *caerEventPacketContainerConst;

/* A container with eventPacketsNumber empty (NULL) slots; free with caerEventPacketContainerFree(). */
static inline caerEventPacketContainer caerEventPacketContainerAllocate(int32_t eventPacketsNumber) {
	if (eventPacketsNumber <= 0) {
		return (NULL);
	}
	size_t bytes = sizeof(struct caer_event_packet_container) + ((size_t) eventPacketsNumber * sizeof(caerEventPacketHeader));
	caerEventPacketContainer container = (caerEventPacketContainer) calloc(1, bytes);
	if (container == NULL) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Container", "Failed to allocate %zu bytes for event packet container.", bytes);
		return (NULL);
	}
	container->eventPacketsNumber    = eventPacketsNumber;
	container->lowestEventTimestamp  = -1;
	container->highestEventTimestamp = -1;
	return (container);
}

static inline int32_t caerEventPacketContainerGetEventPacketsNumber(caerEventPacketContainerConst container) {
	if (container == NULL) {
		return (0);
	}
	return (container->eventPacketsNumber);
}

static inline caerEventPacketHeader caerEventPacketContainerGetEventPacket(caerEventPacketContainer container, int32_t n) {
	if (container == NULL) {
		return (NULL);
	}
	if (n < 0 || n >= container->eventPacketsNumber) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Container", "Called caerEventPacketContainerGetEventPacket() with invalid "
			"event packet offset %" PRIi32 ", while maximum allowed value is %" PRIi32 ".", n, container->eventPacketsNumber - 1);
		return (NULL);
	}
	return (container->eventPackets[n]);
}

static inline caerEventPacketHeaderConst caerEventPacketContainerGetEventPacketConst(caerEventPacketContainerConst container,
	int32_t n) {
	return (caerEventPacketContainerGetEventPacket((caerEventPacketContainer) (uintptr_t) container, n));
}

static inline int64_t caerEventPacketContainerGetLowestEventTimestamp(caerEventPacketContainerConst container) {
	return ((container == NULL) ? -1 : container->lowestEventTimestamp);
}
static inline int64_t caerEventPacketContainerGetHighestEventTimestamp(caerEventPacketContainerConst container) {
	return ((container == NULL) ? -1 : container->highestEventTimestamp);
}
static inline int32_t caerEventPacketContainerGetEventsNumber(caerEventPacketContainerConst container) {
	return ((container == NULL) ? 0 : container->eventsNumber);
}
static inline int32_t caerEventPacketContainerGetEventsValidNumber(caerEventPacketContainerConst container) {
	return ((container == NULL) ? 0 : container->eventsValidNumber);
}

/* Recomputes the container's statistics from its packets (events assumed in time order per packet). */
static inline void caerEventPacketContainerUpdateStatistics(caerEventPacketContainer container) {
	if (container == NULL) {
		return;
	}
	int64_t lowest  = -1;
	int64_t highest = -1;
	int32_t events  = 0;
	int32_t valid   = 0;
	for (int32_t i = 0; i < container->eventPacketsNumber; i++) {
		caerEventPacketHeaderConst packet = container->eventPackets[i];
		if (packet == NULL || caerEventPacketHeaderGetEventNumber(packet) <= 0) {
			continue;
		}
		int32_t number = caerEventPacketHeaderGetEventNumber(packet);
		int64_t first  = caerGenericEventGetTimestamp64(caerEventPacketGetEventConst(packet, 0), packet);
		int64_t last   = caerGenericEventGetTimestamp64(caerEventPacketGetEventConst(packet, number - 1), packet);
		if (lowest == -1 || first < lowest) {
			lowest = first;
		}
		if (last > highest) {
			highest = last;
		}
		events += number;
		valid += caerEventPacketHeaderGetEventValid(packet);
	}
	container->lowestEventTimestamp  = lowest;
	container->highestEventTimestamp = highest;
	container->eventsNumber          = events;
	container->eventsValidNumber     = valid;
}

/* Puts a packet into slot n (the container takes ownership) and updates the statistics. */
static inline void caerEventPacketContainerSetEventPacket(caerEventPacketContainer container, int32_t n,
	caerEventPacketHeader packetHeader) {
	if (container == NULL) {
		return;
	}
	if (n < 0 || n >= container->eventPacketsNumber) {
		caerLog(CAER_LOG_CRITICAL, "EventPacket Container", "Called caerEventPacketContainerSetEventPacket() with invalid "
			"event packet offset %" PRIi32 ", while maximum allowed value is %" PRIi32 ".", n, container->eventPacketsNumber - 1);
		return;
	}
	container->eventPackets[n] = packetHeader;
	caerEventPacketContainerUpdateStatistics(container);
}

/* Frees the container and every packet it holds. NULL is accepted. */
static inline void caerEventPacketContainerFree(caerEventPacketContainer container) {
	if (container == NULL) {
		return;
	}
	for (int32_t i = 0; i < container->eventPacketsNumber; i++) {
		free(container->eventPackets[i]);
	}
	free(container);
}

/* The first packet of the given event type, or NULL. */
static inline caerEventPacketHeader caerEventPacketContainerFindEventPacketByType(caerEventPacketContainer container,
	int16_t typeID) {
	if (container == NULL) {
		return (NULL);
	}
	for (int32_t i = 0; i < container->eventPacketsNumber; i++) {
		caerEventPacketHeader packet = container->eventPackets[i];
		if (packet != NULL && caerEventPacketHeaderGetEventType(packet) == typeID) {
			return (packet);
		}
	}
	return (NULL);
}

static inline caerEventPacketHeaderConst caerEventPacketContainerFindEventPacketByTypeConst(
	caerEventPacketContainerConst container, int16_t typeID) {
	return (caerEventPacketContainerFindEventPacketByType((caerEventPacketContainer) (uintptr_t) container, typeID));
}

/* Iterates over the non-NULL packets: caerEventPacketContainerIteratorElement / ...Counter in scope. */
#define CAER_EVENT_PACKET_CONTAINER_ITERATOR_START(PACKET_CONTAINER)                                              \
	if ((PACKET_CONTAINER) != NULL) {                                                                              \
		for (int32_t caerEventPacketContainerIteratorCounter = 0;                                                  \
			 caerEventPacketContainerIteratorCounter < caerEventPacketContainerGetEventPacketsNumber(PACKET_CONTAINER); \
			 caerEventPacketContainerIteratorCounter++) {                                                          \
			caerEventPacketHeader caerEventPacketContainerIteratorElement                                          \
				= caerEventPacketContainerGetEventPacket(PACKET_CONTAINER, caerEventPacketContainerIteratorCounter); \
			if (caerEventPacketContainerIteratorElement == NULL) {                                                 \
				continue;                                                                                          \
			}

#define CAER_EVENT_PACKET_CONTAINER_CONST_ITERATOR_START(PACKET_CONTAINER)                                        \
	if ((PACKET_CONTAINER) != NULL) {                                                                              \
		for (int32_t caerEventPacketContainerIteratorCounter = 0;                                                  \
			 caerEventPacketContainerIteratorCounter < caerEventPacketContainerGetEventPacketsNumber(PACKET_CONTAINER); \
			 caerEventPacketContainerIteratorCounter++) {                                                          \
			caerEventPacketHeaderConst caerEventPacketContainerIteratorElement                                     \
				= caerEventPacketContainerGetEventPacketConst(PACKET_CONTAINER, caerEventPacketContainerIteratorCounter); \
			if (caerEventPacketContainerIteratorElement == NULL) {                                                 \
				continue;                                                                                          \
			}

#define CAER_EVENT_PACKET_CONTAINER_ITERATOR_END \
	}                                            \
	}

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_PACKETCONTAINER_H_ */
