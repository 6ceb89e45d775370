/*
 * evpipe libcaer stub: 6-axis IMU samples, minimal version (see libcaer.h). evpipe skips IMU data;
 * this header exists because devices/davis.h includes it.
 *
 * One event is 36 bytes, packed: uint32 info (bit 0 = valid), int32 timestamp, then float
 * accel_x/y/z (g), gyro_x/y/z (deg/s), temp (deg C).
 */
#ifndef LIBCAER_EVENTS_IMU6_H_
#define LIBCAER_EVENTS_IMU6_H_

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

PACKED_STRUCT(struct caer_imu6_event {
	uint32_t info;
	int32_t timestamp;
	float accel_x;
	float accel_y;
	float accel_z;
	float gyro_x;
	float gyro_y;
	float gyro_z;
	float temp;
});

typedef struct caer_imu6_event *caerIMU6Event;
typedef const struct caer_imu6_event *caerIMU6EventConst;

PACKED_STRUCT(struct caer_imu6_event_packet {
	struct caer_event_packet_header packetHeader;
	struct caer_imu6_event events[];
});

typedef struct caer_imu6_event_packet *caerIMU6EventPacket;
typedef const struct caer_imu6_event_packet *caerIMU6EventPacketConst;

static inline caerIMU6EventPacket caerIMU6EventPacketAllocate(int32_t eventCapacity, int16_t eventSource, int32_t tsOverflow) {
	return ((caerIMU6EventPacket) caerEventPacketAllocate(eventCapacity, eventSource, tsOverflow, IMU6_EVENT,
		(int32_t) sizeof(struct caer_imu6_event), (int32_t) offsetof(struct caer_imu6_event, timestamp)));
}

static inline caerIMU6EventPacket caerIMU6EventPacketFromPacketHeader(caerEventPacketHeader header) {
	if (header == NULL || caerEventPacketHeaderGetEventType(header) != IMU6_EVENT) {
		return (NULL);
	}
	return ((caerIMU6EventPacket) header);
}
static inline caerIMU6EventPacketConst caerIMU6EventPacketFromPacketHeaderConst(caerEventPacketHeaderConst header) {
	return (caerIMU6EventPacketFromPacketHeader((caerEventPacketHeader) (uintptr_t) header));
}

static inline caerIMU6Event caerIMU6EventPacketGetEvent(caerIMU6EventPacket packet, int32_t n) {
	if (n < 0 || n >= caerEventPacketHeaderGetEventCapacity(&packet->packetHeader)) {
		caerLog(CAER_LOG_CRITICAL, "IMU6 Event", "Called caerIMU6EventPacketGetEvent() with invalid event offset %" PRIi32 ".", n);
		return (NULL);
	}
	return (packet->events + n);
}
static inline caerIMU6EventConst caerIMU6EventPacketGetEventConst(caerIMU6EventPacketConst packet, int32_t n) {
	return (caerIMU6EventPacketGetEvent((caerIMU6EventPacket) (uintptr_t) packet, n));
}

static inline int32_t caerIMU6EventGetTimestamp(caerIMU6EventConst event) {
	return (event->timestamp);
}
static inline int64_t caerIMU6EventGetTimestamp64(caerIMU6EventConst event, caerIMU6EventPacketConst packet) {
	return ((int64_t) (((uint64_t) caerEventPacketHeaderGetEventTSOverflow(&packet->packetHeader) << TS_OVERFLOW_SHIFT)
					   | (uint64_t) caerIMU6EventGetTimestamp(event)));
}
static inline bool caerIMU6EventIsValid(caerIMU6EventConst event) {
	return ((event->info >> VALID_MARK_SHIFT) & VALID_MARK_MASK);
}
static inline float caerIMU6EventGetAccelX(caerIMU6EventConst event) { return (event->accel_x); }
static inline float caerIMU6EventGetAccelY(caerIMU6EventConst event) { return (event->accel_y); }
static inline float caerIMU6EventGetAccelZ(caerIMU6EventConst event) { return (event->accel_z); }
static inline float caerIMU6EventGetGyroX(caerIMU6EventConst event) { return (event->gyro_x); }
static inline float caerIMU6EventGetGyroY(caerIMU6EventConst event) { return (event->gyro_y); }
static inline float caerIMU6EventGetGyroZ(caerIMU6EventConst event) { return (event->gyro_z); }
static inline float caerIMU6EventGetTemp(caerIMU6EventConst event) { return (event->temp); }

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_IMU6_H_ */
