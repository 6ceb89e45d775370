/* evpipe libcaer stub: USB devices (see libcaer.h). */
#ifndef LIBCAER_DEVICES_USB_H_
#define LIBCAER_DEVICES_USB_H_

#include "device.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Host-side USB transfer configuration: number of transfers and bytes per transfer (default 8 x 8192). */
#define CAER_HOST_CONFIG_USB -1
#define CAER_HOST_CONFIG_USB_BUFFER_NUMBER 0
#define CAER_HOST_CONFIG_USB_BUFFER_SIZE 1

/* Opens a device of deviceType; busNumberRestrict / devAddressRestrict 0 and serialNumberRestrict NULL
   (or "") accept any. deviceID becomes the eventSource of every packet. NULL on failure, with errno set
   to one of enum caer_error_codes. */
caerDeviceHandle caerDeviceOpen(uint16_t deviceID, uint16_t deviceType, uint8_t busNumberRestrict,
	uint8_t devAddressRestrict, const char *serialNumberRestrict);

#ifdef __cplusplus
}
#endif

#endif /* LIBCAER_DEVICES_USB_H_ */
