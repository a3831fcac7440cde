/*
 * NineDofTwi.h -- nesC side of the lean TWI master (NINEDOF_LEAN_I2C=1).
 * Its state machine is plain C (ninedof_twi.c, tested on the host and in
 * simavr), compiled in here with functions inlined where they are used,
 * so the interrupt handler and the start of an operation make no call.
 */
#ifndef NINEDOF_TWI_NESC_H
#define NINEDOF_TWI_NESC_H

#define UQ_NINEDOF_TWI "NineDofTwiMasterC.Resource"

#define NINEDOF_TWI_FN static inline __attribute__((always_inline))
#include "ninedof_twi.h"
#include "ninedof_twi.c"

#endif
