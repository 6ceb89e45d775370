/*
 * evpipe libcaer stub: APS frames, minimal version (see libcaer.h). evpipe skips frames; this header
 * exists because devices/davis.h includes it (and struct caer_davis_info uses the color filter enum).
 *
 * Frames have a variable size: eventSize in the packet header is the size of one whole frame event
 * (fixed fields below followed by lengthX * lengthY * channels uint16 pixels).
 */
#ifndef LIBCAER_EVENTS_FRAME_H_
#define LIBCAER_EVENTS_FRAME_H_

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FRAME_COLOR_CHANNELS_SHIFT 1
#define FRAME_COLOR_CHANNELS_MASK 0x00000007
#define FRAME_COLOR_FILTER_SHIFT 4
#define FRAME_COLOR_FILTER_MASK 0x0000000F
#define FRAME_ROI_IDENTIFIER_SHIFT 8
#define FRAME_ROI_IDENTIFIER_MASK 0x0000007F

enum caer_frame_event_color_channels {
	GRAYSCALE = 1,
	RGB       = 3,
	RGBA      = 4,
};

enum caer_frame_event_color_filter {
	MONO = 0,
	RGBG = 1,
	GRGB = 2,
	GBGR = 3,
	BGRG = 4,
	RGBW = 5,
	GRWB = 6,
	WBGR = 7,
	BWRG = 8,
};

PACKED_STRUCT(struct caer_frame_event {
	uint32_t info;
	int32_t ts_startframe;
	int32_t ts_endframe;
	int32_t ts_startexposure;
	int32_t ts_endexposure;
	int32_t lengthX;
	int32_t lengthY;
	int32_t positionX;
	int32_t positionY;
	uint16_t pixels[];
});

typedef struct caer_frame_event *caerFrameEvent;
typedef const struct caer_frame_event *caerFrameEventConst;

/* Frames are addressed through the generic header (their size varies per packet). */
PACKED_STRUCT(struct caer_frame_event_packet {
	struct caer_event_packet_header packetHeader;
});

typedef struct caer_frame_event_packet *caerFrameEventPacket;
typedef const struct caer_frame_event_packet *caerFrameEventPacketConst;

static inline caerFrameEventPacket caerFrameEventPacketFromPacketHeader(caerEventPacketHeader header) {
	if (header == NULL || caerEventPacketHeaderGetEventType(header) != FRAME_EVENT) {
		return (NULL);
	}
	return ((caerFrameEventPacket) header);
}
static inline caerFrameEventPacketConst caerFrameEventPacketFromPacketHeaderConst(caerEventPacketHeaderConst header) {
	return (caerFrameEventPacketFromPacketHeader((caerEventPacketHeader) (uintptr_t) header));
}

static inline caerFrameEvent caerFrameEventPacketGetEvent(caerFrameEventPacket packet, int32_t n) {
	return ((caerFrameEvent) caerEventPacketGetEvent(&packet->packetHeader, n));
}
static inline caerFrameEventConst caerFrameEventPacketGetEventConst(caerFrameEventPacketConst packet, int32_t n) {
	return ((caerFrameEventConst) caerEventPacketGetEventConst(&packet->packetHeader, n));
}

static inline bool caerFrameEventIsValid(caerFrameEventConst event) {
	return ((event->info >> VALID_MARK_SHIFT) & VALID_MARK_MASK);
}
/* The frame's main timestamp is the start of exposure. */
static inline int32_t caerFrameEventGetTimestamp(caerFrameEventConst event) {
	return (event->ts_startexposure);
}
static inline int32_t caerFrameEventGetLengthX(caerFrameEventConst event) { return (event->lengthX); }
static inline int32_t caerFrameEventGetLengthY(caerFrameEventConst event) { return (event->lengthY); }
static inline enum caer_frame_event_color_channels caerFrameEventGetChannelNumber(caerFrameEventConst event) {
	return ((enum caer_frame_event_color_channels) ((event->info >> FRAME_COLOR_CHANNELS_SHIFT) & FRAME_COLOR_CHANNELS_MASK));
}

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_EVENTS_FRAME_H_ */
