/*
 * NineDofTwi.h -- nesC side of the lean TWI master (NINEDOF_LEAN_I2C=1).
 * Its state machine is plain C (ninedof_twi.c, tested on the host and in
 * simavr), compiled in here with `static inline` functions so the
 * interrupt handler makes no call on its fast path.
 */
#ifndef NINEDOF_TWI_NESC_H
#define NINEDOF_TWI_NESC_H

#define UQ_NINEDOF_TWI "NineDofTwiMasterC.Resource"

#define NINEDOF_TWI_FN static inline
#include "ninedof_twi.h"
#include "ninedof_twi.c"

#endif
