/* evpipe libcaer stub: IMU models (see libcaer.h). */
#ifndef LIBCAER_DEVICES_IMU_SUPPORT_H_
#define LIBCAER_DEVICES_IMU_SUPPORT_H_

enum caer_imu_types {
	IMU_NONE                 = 0,
	IMU_INVENSENSE_6050_6150 = 1,
	IMU_INVENSENSE_9250      = 2,
	IMU_BOSCH_BMI_160        = 3,
};

#endif /* LIBCAER_DEVICES_IMU_SUPPORT_H_ */
