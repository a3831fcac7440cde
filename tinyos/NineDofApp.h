/*
 * NineDofApp.h -- nesC side of the sampling app: the message definitions
 * and the app's plain C (calibration receiver and correction, batching,
 * counters, EEPROM writer, sampling clock), compiled in here once for the
 * application.
 */
#ifndef NINEDOF_APP_NESC_H
#define NINEDOF_APP_NESC_H

#include "NineDofMsg.h"
#include "nx_nesc.h"
#include "ninedof_cal.h"
#include "ninedof_sampling.h"
#include "ninedof_clock.h"
#include "ninedof_calset.c"
#include "ninedof_correct.c"
#include "ninedof_calrx.c"
#include "ninedof_sampling.c"
#include "ninedof_clock.c"

#endif
