/*
 * NineDofBase.h -- nesC side of the BaseStation: message definitions and
 * its plain C (ninedof_bs.c), compiled in here once.
 */
#ifndef NINEDOF_BASE_NESC_H
#define NINEDOF_BASE_NESC_H

#include "NineDofMsg.h"
#include "nx_nesc.h"
#include "ninedof_bs.h"
#include "ninedof_bs.c"

#endif
