# Include paths of the 9DOF drivers, for an application's Makefile (the
# sensor mote's, tinyos/Makefile, and the example apps in tinyos/apps/):
#   NINEDOF_DIR := <path to this folder>
#   include $(NINEDOF_DIR)/ninedof.mk
# Laid out like the TinyOS tree:
#   chips/adxl345, chips/itg3200, chips/hmc5883l   one public generic
#       configuration per chip (Read<>, SplitControl), own bus client
#   lib/regchip             the register-table chip driver they share
#   sensorboards/ninedof    the board: one synchronized nine-axis read
#                           under one bus grant, fault handling
#   platforms/iris          the I2C binding (stock or lean master), bus
#                           recovery
#   lib/calibration         the calibration receiver + EEPROM writer
#   .                       the plain C shared with the host and tests
#                           (ninedof_*.c/h) and the messages (NineDofMsg.h)
# NINEDOF_LEAN_I2C=1 selects the lean TWI master (off by default).
NINEDOF_LEAN_I2C ?= 0
PFLAGS += -I$(NINEDOF_DIR)/chips/adxl345 -I$(NINEDOF_DIR)/chips/itg3200 \
          -I$(NINEDOF_DIR)/chips/hmc5883l -I$(NINEDOF_DIR)/lib/regchip \
          -I$(NINEDOF_DIR)/sensorboards/ninedof -I$(NINEDOF_DIR)/platforms/iris \
          -I$(NINEDOF_DIR)/lib/calibration -I$(NINEDOF_DIR)
CFLAGS += -DNINEDOF_LEAN_I2C=$(NINEDOF_LEAN_I2C)
