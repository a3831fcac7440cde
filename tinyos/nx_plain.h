/*
 * nx_plain.h -- nesC network types for plain C.
 *
 * nesC compiles nx_ types to structs of bytes in big-endian order (see
 * nesc_nx.h in the nesC distribution).  This header gives gcc and avr-gcc
 * the same layout, so the plain C logic under tinyos/ and the host library
 * use NineDofMsg.h itself rather than a copy of it.  Fields are read and
 * written through the nxp_* accessors; nesC code uses plain assignment.
 */
#ifndef NX_PLAIN_H
#define NX_PLAIN_H

#ifdef NESC
#error "nx_plain.h is for plain C; nesC has network types built in"
#endif

#include <stdint.h>

#define nx_struct struct
#define nx_union union

typedef struct { uint8_t nxdata[1]; } nx_uint8_t;
typedef struct { uint8_t nxdata[1]; } nx_int8_t;
typedef struct { uint8_t nxdata[2]; } nx_uint16_t;
typedef struct { uint8_t nxdata[2]; } nx_int16_t;
typedef struct { uint8_t nxdata[4]; } nx_uint32_t;
typedef struct { uint8_t nxdata[4]; } nx_int32_t;

static inline uint8_t nxp_get_u8(const nx_uint8_t *p) { return p->nxdata[0]; }
static inline void nxp_set_u8(nx_uint8_t *p, uint8_t v) { p->nxdata[0] = v; }

static inline uint16_t nxp_get_u16(const nx_uint16_t *p)
{
  return (uint16_t)(((uint16_t)p->nxdata[0] << 8) | p->nxdata[1]);
}
static inline void nxp_set_u16(nx_uint16_t *p, uint16_t v)
{
  p->nxdata[0] = (uint8_t)(v >> 8);
  p->nxdata[1] = (uint8_t)v;
}

static inline int16_t nxp_get_i16(const nx_int16_t *p)
{
  return (int16_t)(((uint16_t)p->nxdata[0] << 8) | p->nxdata[1]);
}
static inline void nxp_set_i16(nx_int16_t *p, int16_t v)
{
  p->nxdata[0] = (uint8_t)((uint16_t)v >> 8);
  p->nxdata[1] = (uint8_t)v;
}

static inline uint32_t nxp_get_u32(const nx_uint32_t *p)
{
  return ((uint32_t)p->nxdata[0] << 24) | ((uint32_t)p->nxdata[1] << 16) |
         ((uint32_t)p->nxdata[2] << 8) | p->nxdata[3];
}
static inline void nxp_set_u32(nx_uint32_t *p, uint32_t v)
{
  p->nxdata[0] = (uint8_t)(v >> 24);
  p->nxdata[1] = (uint8_t)(v >> 16);
  p->nxdata[2] = (uint8_t)(v >> 8);
  p->nxdata[3] = (uint8_t)v;
}

static inline int32_t nxp_get_i32(const nx_int32_t *p)
{
  return (int32_t)nxp_get_u32((const nx_uint32_t *)p);
}
static inline void nxp_set_i32(nx_int32_t *p, int32_t v)
{
  nxp_set_u32((nx_uint32_t *)p, (uint32_t)v);
}

#endif /* NX_PLAIN_H */
