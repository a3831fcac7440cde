/*
 * nx_nesc.h -- the nxp_* accessors of nx_plain.h for nesC, where network
 * types are built in: the plain C logic (ninedof_calset.c, ninedof_calrx.c,
 * ninedof_sampling.c) reads and writes message fields through these in both
 * worlds.
 */
#ifndef NX_NESC_H
#define NX_NESC_H

#ifndef NESC
#error "nx_nesc.h is for nesC; plain C uses nx_plain.h"
#endif

static inline uint8_t nxp_get_u8(const nx_uint8_t *p) { return *p; }
static inline void nxp_set_u8(nx_uint8_t *p, uint8_t v) { *p = v; }
static inline uint16_t nxp_get_u16(const nx_uint16_t *p) { return *p; }
static inline void nxp_set_u16(nx_uint16_t *p, uint16_t v) { *p = v; }
static inline int16_t nxp_get_i16(const nx_int16_t *p) { return *p; }
static inline void nxp_set_i16(nx_int16_t *p, int16_t v) { *p = v; }
static inline uint32_t nxp_get_u32(const nx_uint32_t *p) { return *p; }
static inline void nxp_set_u32(nx_uint32_t *p, uint32_t v) { *p = v; }
static inline int32_t nxp_get_i32(const nx_int32_t *p) { return *p; }
static inline void nxp_set_i32(nx_int32_t *p, int32_t v) { *p = v; }

#endif
