/*
 * evpipe libcaer stub: device-independent functions and host-side configuration (see libcaer.h).
 * In the stub, every function operates on the scripted fake device of libcaer_stub/fake_device.h.
 */
#ifndef LIBCAER_DEVICES_DEVICE_H_
#define LIBCAER_DEVICES_DEVICE_H_

#include "../libcaer.h"
#include "../events/packetContainer.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Device type IDs (CAER_DEVICE_DAVIS, ...) are defined in the per-device headers (davis.h). */

typedef struct caer_device_handle *caerDeviceHandle;

/* Host-side module addresses (negative; device modules are >= 0). */
#define CAER_HOST_CONFIG_DATAEXCHANGE -2
#define CAER_HOST_CONFIG_PACKETS -3
#define CAER_HOST_CONFIG_LOG -4

/* CAER_HOST_CONFIG_DATAEXCHANGE: ring of containers between the USB thread and caerDeviceDataGet().
   BUFFER_SIZE (containers, power of two, default 64) takes effect at caerDeviceDataStart(). */
#define CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE 0
#define CAER_HOST_CONFIG_DATAEXCHANGE_BLOCKING 1
#define CAER_HOST_CONFIG_DATAEXCHANGE_START_PRODUCERS 2
#define CAER_HOST_CONFIG_DATAEXCHANGE_STOP_PRODUCERS 3

/* CAER_HOST_CONFIG_PACKETS: when a container is committed. PACKET_SIZE in events (0 = off, default),
   INTERVAL in µs (>= 1, default 10000). */
#define CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE 0
#define CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL 1

#define CAER_HOST_CONFIG_LOG_LEVEL 0

bool caerDeviceClose(caerDeviceHandle *handle);
bool caerDeviceSendDefaultConfig(caerDeviceHandle handle);
bool caerDeviceConfigSet(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint32_t param);
bool caerDeviceConfigGet(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint32_t *param);
bool caerDeviceConfigGet64(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint64_t *param);
bool caerDeviceDataStart(caerDeviceHandle handle, void (*dataNotifyIncrease)(void *ptr),
	void (*dataNotifyDecrease)(void *ptr), void *dataNotifyUserPtr, void (*dataShutdownNotify)(void *ptr),
	void *dataShutdownUserPtr);
bool caerDeviceDataStop(caerDeviceHandle handle);
/* Next container (caller frees it with caerEventPacketContainerFree()), or NULL when none is
   available (non-blocking mode) or after an exceptional shutdown. */
caerEventPacketContainer caerDeviceDataGet(caerDeviceHandle handle);

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_DEVICES_DEVICE_H_ */
