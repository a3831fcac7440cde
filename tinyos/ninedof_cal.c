/*
 * ninedof_cal.c -- implementation of ninedof_cal.h (see there for the API).
 *
 * Plain C99 without floats.  The same file is compiled
 *   - into the nesC firmware (NineDofAppC includes it),
 *   - for the host into the shared library the simulator loads
 *     (host/motecal/mote_c.py), and
 *   - with avr-gcc for the simavr tests and the cycle benchmark.
 *
 * Correction: a validated set always fits Q14 without loss (diagonal
 * <= 32767 and off-diagonal <= 8192 in Q14 terms, |c| <= 4096 counts), so
 * every sensor is brought to Q14 once per block and one fixed kernel does
 *   out = sat((c14 + 2^13 + sum a14_j * raw_j) >> 14)
 * which is bit-identical to the header's Q(shift) formula:
 *   (x * 2^k + 2^(s+k-1)) >> (s+k) == (x + 2^(s-1)) >> s.
 * A decodable set that is not representable in Q14 (only possible without
 * validation) takes a slower generic path with the same formula.
 * Signed right shifts are arithmetic on gcc and avr-gcc (documented GCC
 * behaviour), which the rounding rule relies on.
 */
#include <string.h>
#include "ninedof_cal.h"

/* ---------------------------------------------------------------------- */
/* CRC-16-CCITT (XMODEM)                                                   */
/* ---------------------------------------------------------------------- */
uint16_t ninedof_crc16(uint16_t crc, const uint8_t *data, uint16_t len)
{
  while (len--) {
    uint8_t i;
    crc ^= (uint16_t)(*data++) << 8;
    for (i = 0; i < 8; i++)
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
  }
  return crc;
}

/* ---------------------------------------------------------------------- */
/* Wire <-> native                                                         */
/* ---------------------------------------------------------------------- */
#define SENSOR_BITS ((1u << NINEDOF_SENSORS) - 1u)

uint8_t ninedof_cal_decode(const ninedof_calset_t *wire, ninedof_cal_t *out)
{
  uint8_t k, i, bad = 0;

  out->mote = nxp_get_u16(&wire->mote);
  out->version = nxp_get_u16(&wire->version);
  out->sensors = nxp_get_u8(&wire->sensors);
  if (nxp_get_u8(&wire->reserved) != 0 || (out->sensors & ~SENSOR_BITS) != 0)
    bad = 1;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    const ninedof_cal_sensor_t *w = &wire->s[k];
    ninedof_cal_sensor_native_t *n = &out->s[k];
    for (i = 0; i < 9; i++)
      n->a[i] = nxp_get_i16(&w->a[i]);
    for (i = 0; i < 3; i++)
      n->c[i] = nxp_get_i32(&w->c[i]);
    n->shift = nxp_get_u8(&w->shift);
    if (n->shift < NINEDOF_SHIFT_MIN || n->shift > NINEDOF_SHIFT_MAX ||
        nxp_get_u8(&w->reserved) != 0)
      bad = 1;
  }
  return bad ? NINEDOF_CAL_E_FORMAT : NINEDOF_CAL_OK;
}

void ninedof_cal_encode(const ninedof_cal_t *cal, ninedof_calset_t *wire)
{
  uint8_t k, i;

  nxp_set_u16(&wire->mote, cal->mote);
  nxp_set_u16(&wire->version, cal->version);
  nxp_set_u8(&wire->sensors, cal->sensors);
  nxp_set_u8(&wire->reserved, 0);
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    ninedof_cal_sensor_t *w = &wire->s[k];
    const ninedof_cal_sensor_native_t *n = &cal->s[k];
    for (i = 0; i < 9; i++)
      nxp_set_i16(&w->a[i], n->a[i]);
    for (i = 0; i < 3; i++)
      nxp_set_i32(&w->c[i], n->c[i]);
    nxp_set_u8(&w->shift, n->shift);
    nxp_set_u8(&w->reserved, 0);
  }
}

void ninedof_cal_identity(ninedof_cal_t *cal, uint16_t mote, uint16_t version)
{
  uint8_t k;

  memset(cal, 0, sizeof(*cal));
  cal->mote = mote;
  cal->version = version;
  cal->sensors = 0;
  for (k = 0; k < NINEDOF_SENSORS; k++) {
    cal->s[k].a[0] = cal->s[k].a[4] = cal->s[k].a[8] = 1 << NINEDOF_SHIFT_MAX;
    cal->s[k].shift = NINEDOF_SHIFT_MAX;
  }
}

/* ---------------------------------------------------------------------- */
/* Validation                                                              */
/* ---------------------------------------------------------------------- */
static uint32_t abs32(int32_t v)
{
  return v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
}

/* Range of one sensor (shift already known to be 8..14). */
static uint8_t sensor_in_range(const ninedof_cal_sensor_native_t *s)
{
  uint8_t up = (uint8_t)(NINEDOF_SHIFT_MAX - s->shift);   /* to Q14 */
  uint8_t r, j;

  for (r = 0; r < 3; r++) {
    uint32_t sum = 0;
    uint32_t c = abs32(s->c[r]);
    for (j = 0; j < 3; j++) {
      int32_t q14 = (int32_t)s->a[3 * r + j] * ((int32_t)1 << up);
      uint32_t m = abs32(q14);
      if (r == j) {
        if (q14 < NINEDOF_LIMIT_DIAG_MIN_Q14 || q14 > NINEDOF_LIMIT_DIAG_MAX_Q14)
          return 0;
      } else if (m > NINEDOF_LIMIT_OFFDIAG_Q14) {
        return 0;
      }
      sum += abs32(s->a[3 * r + j]);
    }
    /* |c| <= 4096 counts in Q(shift) */
    if (c > ((uint32_t)NINEDOF_LIMIT_OFFSET_COUNTS << s->shift))
      return 0;
    /* sum |a| * 32768 + |c| < 2^31: sum <= 3 * 32768 so sum * 32768 fits
     * uint32; test without overflowing. */
    if (sum >= 65536UL || sum * 32768UL >= 0x80000000UL - c)
      return 0;
  }
  return 1;
}

uint8_t ninedof_cal_validate(const ninedof_cal_t *cal, uint16_t my_id)
{
  uint8_t k;

  if (cal->mote != my_id)
    return NINEDOF_CAL_E_MOTE;
  if (cal->version == 0)
    return NINEDOF_CAL_E_VERSION;
  if (cal->sensors & ~SENSOR_BITS)
    return NINEDOF_CAL_E_FORMAT;
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if (cal->s[k].shift < NINEDOF_SHIFT_MIN || cal->s[k].shift > NINEDOF_SHIFT_MAX)
      return NINEDOF_CAL_E_FORMAT;
  /* Only corrected sensors are range-checked: the others are never used. */
  for (k = 0; k < NINEDOF_SENSORS; k++)
    if ((cal->sensors & (1u << k)) && !sensor_in_range(&cal->s[k]))
      return NINEDOF_CAL_E_RANGE;
  return NINEDOF_CAL_OK;
}

/* ---------------------------------------------------------------------- */
/* Correction                                                              */
/* ---------------------------------------------------------------------- */
/* One sensor prepared for the kernel: Q14 matrix, offset + rounding half. */
typedef struct {
  int16_t a[9];
  int32_t c[3];        /* c14 + 2^13 (Q14 path) or c + 2^(shift-1) (generic) */
  uint8_t shift;       /* 14 on the fast path */
  uint8_t mode;        /* PREP_RAW, PREP_Q14, PREP_GENERIC */
} prep_t;

enum { PREP_RAW = 0, PREP_Q14 = 1, PREP_GENERIC = 2 };

static void prepare(const ninedof_cal_t *cal, uint8_t k, prep_t *p)
{
  const ninedof_cal_sensor_native_t *s = &cal->s[k];
  uint8_t i, up, ok = 1;

  p->shift = s->shift;
  if (!(cal->sensors & (1u << k))) {
    p->mode = PREP_RAW;
    return;
  }
  if (s->shift < NINEDOF_SHIFT_MIN || s->shift > NINEDOF_SHIFT_MAX) {
    /* never reaches here after decode/validate; treat like raw */
    p->mode = PREP_RAW;
    return;
  }
  up = (uint8_t)(NINEDOF_SHIFT_MAX - s->shift);
  for (i = 0; i < 9; i++) {
    int32_t v = (int32_t)s->a[i] * ((int32_t)1 << up);
    if (v > 32767 || v < -32768)
      ok = 0;
    p->a[i] = (int16_t)v;
  }
  for (i = 0; i < 3; i++) {
    /* |c| <= 2^26 keeps c * 2^up + 2^13 well inside int32 */
    if (s->c[i] > (1L << 26) || s->c[i] < -(1L << 26))
      ok = 0;
    else
      p->c[i] = s->c[i] * ((int32_t)1 << up) + (1L << (NINEDOF_SHIFT_MAX - 1));
  }
  if (ok) {
    p->mode = PREP_Q14;
    p->shift = NINEDOF_SHIFT_MAX;
    return;
  }
  p->mode = PREP_GENERIC;
  for (i = 0; i < 9; i++)
    p->a[i] = s->a[i];
  for (i = 0; i < 3; i++)  /* wrap like int32 hardware would, without UB */
    p->c[i] = (int32_t)((uint32_t)s->c[i] + (1UL << (s->shift - 1)));
}

static int16_t sat16(int32_t v)
{
  if (v > 32767)
    return 32767;
  if (v < -32768)
    return -32768;
  return (int16_t)v;
}

#if defined(__AVR__) && !defined(NINEDOF_PORTABLE_KERNEL)
/*
 * AVR kernel: one row, out = sat16((c + a0*x0 + a1*x1 + a2*x2) >> 14).
 * Signed 16x16 -> 32 multiply-accumulate with MULS/MULSU/MUL as in Atmel
 * application note AVR201 (23 cycles per product instead of a call to the
 * generic 32-bit multiply), then >>14 as "<<2, take the high word" after
 * checking that bits 31..29 agree (otherwise saturate by sign).
 */
static inline int16_t row_q14(const int16_t *a, int32_t acc,
                              int16_t x0, int16_t x1, int16_t x2)
{
  int16_t ai;
  uint8_t zero;

#define NINEDOF_MAC(XV)                                                    \
  ai = *a++;                                                             \
  __asm__ (                                                              \
    "clr  %[z]             \n\t"                                         \
    "muls %B[m], %B[x]     \n\t"  /* ah*xh (signed) -> bytes 2,3 */       \
    "add  %C[acc], r0      \n\t"                                         \
    "adc  %D[acc], r1      \n\t"                                         \
    "mul  %A[m], %A[x]     \n\t"  /* al*xl -> bytes 0,1 */                \
    "add  %A[acc], r0      \n\t"                                         \
    "adc  %B[acc], r1      \n\t"                                         \
    "adc  %C[acc], %[z]    \n\t"                                         \
    "adc  %D[acc], %[z]    \n\t"                                         \
    "mulsu %B[m], %A[x]    \n\t"  /* ah(signed)*xl -> bytes 1,2 */        \
    "sbc  %D[acc], %[z]    \n\t"                                         \
    "add  %B[acc], r0      \n\t"                                         \
    "adc  %C[acc], r1      \n\t"                                         \
    "adc  %D[acc], %[z]    \n\t"                                         \
    "mulsu %B[x], %A[m]    \n\t"  /* xh(signed)*al -> bytes 1,2 */        \
    "sbc  %D[acc], %[z]    \n\t"                                         \
    "add  %B[acc], r0      \n\t"                                         \
    "adc  %C[acc], r1      \n\t"                                         \
    "adc  %D[acc], %[z]    \n\t"                                         \
    "clr  r1               \n\t"                                         \
    : [acc] "+r" (acc), [z] "=&r" (zero)                                 \
    : [m] "a" (ai), [x] "a" (XV)                                         \
    : "r0", "r1")

  NINEDOF_MAC(x0);
  NINEDOF_MAC(x1);
  NINEDOF_MAC(x2);
#undef NINEDOF_MAC
  (void)zero;
  {
    uint8_t top = (uint8_t)((uint32_t)acc >> 24) & 0xE0;
    if (top == 0x00 || top == 0xE0)
      return (int16_t)((uint32_t)acc >> 14);
    return (acc < 0) ? (int16_t)-32768 : (int16_t)32767;
  }
}
#else
static int16_t row_q14(const int16_t *a, int32_t acc,
                       int16_t x0, int16_t x1, int16_t x2)
{
  acc += (int32_t)a[0] * x0;
  acc += (int32_t)a[1] * x1;
  acc += (int32_t)a[2] * x2;
  return sat16(acc >> NINEDOF_SHIFT_MAX);
}
#endif

static int16_t row_generic(const int16_t *a, int32_t acc, uint8_t shift,
                           int16_t x0, int16_t x1, int16_t x2)
{
  uint32_t u = (uint32_t)acc;          /* wraps only for unvalidated sets */
  u += (uint32_t)((int32_t)a[0] * x0);
  u += (uint32_t)((int32_t)a[1] * x1);
  u += (uint32_t)((int32_t)a[2] * x2);
  return sat16((int32_t)u >> shift);
}

static void apply3(const prep_t *p, const int16_t *in, int16_t *out, uint8_t is_mag)
{
  int16_t x0 = in[0], x1 = in[1], x2 = in[2];   /* in and out may alias */
  int16_t y0, y1, y2;

  if (p->mode == PREP_RAW) {
    out[0] = x0; out[1] = x1; out[2] = x2;
    return;
  }
  if (is_mag && (x0 == NINEDOF_MAG_OVERFLOW || x1 == NINEDOF_MAG_OVERFLOW ||
                 x2 == NINEDOF_MAG_OVERFLOW)) {
    out[0] = out[1] = out[2] = NINEDOF_MAG_OVERFLOW;
    return;
  }
  if (p->mode == PREP_Q14) {
    y0 = row_q14(p->a, p->c[0], x0, x1, x2);
    y1 = row_q14(p->a + 3, p->c[1], x0, x1, x2);
    y2 = row_q14(p->a + 6, p->c[2], x0, x1, x2);
  } else {
    y0 = row_generic(p->a, p->c[0], p->shift, x0, x1, x2);
    y1 = row_generic(p->a + 3, p->c[1], p->shift, x0, x1, x2);
    y2 = row_generic(p->a + 6, p->c[2], p->shift, x0, x1, x2);
  }
  if (is_mag) {
    if (y0 > 4095) y0 = 4095; else if (y0 < -4095) y0 = -4095;
    if (y1 > 4095) y1 = 4095; else if (y1 < -4095) y1 = -4095;
    if (y2 > 4095) y2 = 4095; else if (y2 < -4095) y2 = -4095;
  }
  out[0] = y0; out[1] = y1; out[2] = y2;
}

void ninedof_correct_block(const ninedof_cal_t *cal, const int16_t *raw,
                           int16_t *out, uint16_t n)
{
  prep_t p[NINEDOF_SENSORS];
  uint8_t k;

  for (k = 0; k < NINEDOF_SENSORS; k++)
    prepare(cal, k, &p[k]);
  while (n--) {
    apply3(&p[NINEDOF_SENSOR_ACCEL], raw, out, 0);
    apply3(&p[NINEDOF_SENSOR_GYRO], raw + 3, out + 3, 0);
    apply3(&p[NINEDOF_SENSOR_MAG], raw + 6, out + 6, 1);
    raw += 9;
    out += 9;
  }
}

void ninedof_correct(const ninedof_cal_t *cal, const int16_t raw[9], int16_t out[9])
{
  ninedof_correct_block(cal, raw, out, 1);
}

/* ---------------------------------------------------------------------- */
/* Upload receiver                                                         */
/* ---------------------------------------------------------------------- */
#define CALSET_SIZE ((uint8_t)sizeof(ninedof_calset_t))

static void set_active(ninedof_calrx_t *rx, const ninedof_calset_t *wire,
                       const ninedof_cal_t *cal)
{
  rx->active_wire = *wire;
  rx->active = *cal;
  rx->active_crc = ninedof_crc16(0, (const uint8_t *)wire, CALSET_SIZE);
}

static void active_identity(ninedof_calrx_t *rx, uint16_t version)
{
  ninedof_cal_t cal;
  ninedof_calset_t wire;

  ninedof_cal_identity(&cal, rx->my_id, version);
  ninedof_cal_encode(&cal, &wire);
  set_active(rx, &wire, &cal);
}

static void staging_clear(ninedof_calrx_t *rx, uint16_t version)
{
  memset(&rx->staged, 0, sizeof(rx->staged));
  memset(rx->have, 0, sizeof(rx->have));
  rx->staged_version = version;
}

static uint8_t staging_complete(const ninedof_calrx_t *rx)
{
  uint8_t i;

  for (i = 0; i < CALSET_SIZE; i++)
    if (!(rx->have[i >> 3] & (1u << (i & 7))))
      return 0;
  return 1;
}

void ninedof_calrx_init(ninedof_calrx_t *rx, uint16_t my_id)
{
  memset(rx, 0, sizeof(*rx));
  rx->my_id = my_id;
  staging_clear(rx, 0);
  active_identity(rx, 0);
  rx->dirty = 0;
}

static uint8_t handle_frag(ninedof_calrx_t *rx, const ninedof_cal_frag_msg_t *m,
                           uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_frag_ack_msg_t *ack = (ninedof_cal_frag_ack_msg_t *)reply;
  uint16_t version = nxp_get_u16(&m->version);
  uint8_t offset = nxp_get_u8(&m->offset);
  uint8_t len = nxp_get_u8(&m->len);
  uint8_t status = NINEDOF_CAL_OK;

  if (nxp_get_u16(&m->mote) != rx->my_id) {
    status = NINEDOF_CAL_E_MOTE;
  } else if (version == 0) {
    status = NINEDOF_CAL_E_VERSION;
  } else if (len == 0 || len > NINEDOF_FRAG_DATA ||
             (uint16_t)offset + len > CALSET_SIZE) {
    status = NINEDOF_CAL_E_FRAG;
  } else {
    uint8_t i;
    if (version != rx->staged_version)
      staging_clear(rx, version);          /* a new version restarts staging */
    memcpy((uint8_t *)&rx->staged + offset, m->data, len);
    for (i = offset; i < offset + len; i++)
      rx->have[i >> 3] |= (uint8_t)(1u << (i & 7));
  }
  nxp_set_u16(&ack->mote, rx->my_id);
  nxp_set_u16(&ack->version, version);
  nxp_set_u8(&ack->offset, offset);
  nxp_set_u8(&ack->status, status);
  *reply_type = AM_NINEDOF_CAL_FRAG_ACK_MSG;
  return (uint8_t)sizeof(*ack);
}

static uint8_t commit_apply(ninedof_calrx_t *rx, uint16_t version, uint8_t length,
                            uint16_t crc_expected, uint16_t *crc_out)
{
  ninedof_cal_t cal;
  uint8_t status;
  uint16_t crc;

  if (version == 0 || version != rx->staged_version)
    return NINEDOF_CAL_E_VERSION;
  if (length != CALSET_SIZE)
    return NINEDOF_CAL_E_FORMAT;
  if (!staging_complete(rx))
    return NINEDOF_CAL_E_INCOMPLETE;
  crc = ninedof_crc16(0, (const uint8_t *)&rx->staged, CALSET_SIZE);
  *crc_out = crc;
  if (crc != crc_expected)
    return NINEDOF_CAL_E_CRC;
  status = ninedof_cal_decode(&rx->staged, &cal);
  if (status != NINEDOF_CAL_OK)
    return status;
  status = ninedof_cal_validate(&cal, rx->my_id);
  if (status != NINEDOF_CAL_OK)
    return status;
  if (cal.version != version)
    return NINEDOF_CAL_E_VERSION;
  /* A repeated commit (its ack was lost) of the set already in force is
   * acknowledged again without another EEPROM write. */
  if (crc == rx->active_crc &&
      memcmp(&rx->staged, &rx->active_wire, CALSET_SIZE) == 0)
    return NINEDOF_CAL_OK;
  set_active(rx, &rx->staged, &cal);
  rx->dirty = 1;
  return NINEDOF_CAL_OK;
}

static uint8_t handle_commit(ninedof_calrx_t *rx, const ninedof_cal_commit_msg_t *m,
                             uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_commit_ack_msg_t *ack = (ninedof_cal_commit_ack_msg_t *)reply;
  uint16_t version = nxp_get_u16(&m->version);
  uint8_t action = nxp_get_u8(&m->action);
  uint16_t crc = 0;
  uint8_t status;

  if (nxp_get_u16(&m->mote) != rx->my_id) {
    status = NINEDOF_CAL_E_MOTE;
  } else if (action == NINEDOF_CAL_APPLY) {
    status = commit_apply(rx, version, nxp_get_u8(&m->length),
                          nxp_get_u16(&m->crc), &crc);
  } else if (action == NINEDOF_CAL_RESET) {
    if (version == 0) {
      status = NINEDOF_CAL_E_VERSION;
    } else {
      status = NINEDOF_CAL_OK;
      if (rx->active.sensors != 0 || rx->active.version != version) {
        active_identity(rx, version);
        rx->dirty = 1;
      }
      crc = rx->active_crc;
    }
  } else {
    status = NINEDOF_CAL_E_ACTION;
  }
  nxp_set_u16(&ack->mote, rx->my_id);
  nxp_set_u16(&ack->version, rx->active.version);
  nxp_set_u16(&ack->crc, crc);
  nxp_set_u8(&ack->status, status);
  nxp_set_u8(&ack->sensors, rx->active.sensors);
  *reply_type = AM_NINEDOF_CAL_COMMIT_ACK_MSG;
  return (uint8_t)sizeof(*ack);
}

static uint8_t handle_query(ninedof_calrx_t *rx, const ninedof_cal_query_msg_t *m,
                            uint8_t *reply, uint8_t *reply_type)
{
  ninedof_cal_report_msg_t *rep = (ninedof_cal_report_msg_t *)reply;
  uint8_t offset = nxp_get_u8(&m->offset);
  uint8_t len = 0;

  if (nxp_get_u16(&m->mote) != rx->my_id)
    return 0;
  memset(rep, 0, sizeof(*rep));
  if (offset < CALSET_SIZE) {
    len = (uint8_t)(CALSET_SIZE - offset);
    if (len > NINEDOF_FRAG_DATA)
      len = NINEDOF_FRAG_DATA;
    memcpy(rep->data, (const uint8_t *)&rx->active_wire + offset, len);
  }
  nxp_set_u16(&rep->mote, rx->my_id);
  nxp_set_u16(&rep->version, rx->active.version);
  nxp_set_u16(&rep->crc, rx->active_crc);
  nxp_set_u8(&rep->offset, offset);
  nxp_set_u8(&rep->len, len);
  *reply_type = AM_NINEDOF_CAL_REPORT_MSG;
  return (uint8_t)sizeof(*rep);
}

uint8_t ninedof_calrx_handle(ninedof_calrx_t *rx, uint8_t am_type,
                             const uint8_t *payload, uint8_t len,
                             uint8_t *reply, uint8_t *reply_type)
{
  switch (am_type) {
  case AM_NINEDOF_CAL_FRAG_MSG:
    if (len < sizeof(ninedof_cal_frag_msg_t))
      return 0;
    return handle_frag(rx, (const ninedof_cal_frag_msg_t *)payload, reply, reply_type);
  case AM_NINEDOF_CAL_COMMIT_MSG:
    if (len < sizeof(ninedof_cal_commit_msg_t))
      return 0;
    return handle_commit(rx, (const ninedof_cal_commit_msg_t *)payload, reply, reply_type);
  case AM_NINEDOF_CAL_QUERY_MSG:
    if (len < sizeof(ninedof_cal_query_msg_t))
      return 0;
    return handle_query(rx, (const ninedof_cal_query_msg_t *)payload, reply, reply_type);
  default:
    return 0;
  }
}

uint8_t ninedof_calrx_flags(const ninedof_calrx_t *rx)
{
  uint8_t f = (uint8_t)((rx->active.version << NINEDOF_FLAG_VERSION_SHIFT) &
                        NINEDOF_FLAG_VERSION_MASK);
  if (rx->active.sensors)
    f |= NINEDOF_FLAG_CORRECTED;
  return f;
}

void ninedof_calrx_correct_block(const ninedof_calrx_t *rx, const int16_t *raw,
                                 int16_t *out, uint16_t n)
{
  ninedof_correct_block(&rx->active, raw, out, n);
}

/* ---------------------------------------------------------------------- */
/* Persistent image                                                        */
/* ---------------------------------------------------------------------- */
static uint16_t image_crc(const uint8_t *image)
{
  uint16_t crc = ninedof_crc16(0, image + 2, 2);           /* generation */
  return ninedof_crc16(crc, image + 6, CALSET_SIZE);       /* the set */
}

void ninedof_calrx_image(const ninedof_calrx_t *rx, uint16_t generation,
                         uint8_t image[NINEDOF_IMAGE_SIZE])
{
  uint16_t crc;

  image[0] = 'N';
  image[1] = '9';
  image[2] = (uint8_t)(generation >> 8);
  image[3] = (uint8_t)generation;
  memcpy(image + 6, &rx->active_wire, CALSET_SIZE);
  crc = image_crc(image);
  image[4] = (uint8_t)(crc >> 8);
  image[5] = (uint8_t)crc;
}

uint8_t ninedof_image_check(const uint8_t image[NINEDOF_IMAGE_SIZE], uint16_t my_id,
                            uint16_t *generation)
{
  ninedof_cal_t cal;

  if (image[0] != 'N' || image[1] != '9')
    return 0;
  if (image_crc(image) != (uint16_t)((image[4] << 8) | image[5]))
    return 0;
  if (ninedof_cal_decode((const ninedof_calset_t *)(image + 6), &cal) != NINEDOF_CAL_OK)
    return 0;
  if (ninedof_cal_validate(&cal, my_id) != NINEDOF_CAL_OK)
    return 0;
  if (generation)
    *generation = (uint16_t)((image[2] << 8) | image[3]);
  return 1;
}

uint8_t ninedof_calrx_restore(ninedof_calrx_t *rx,
                              const uint8_t slot0[NINEDOF_IMAGE_SIZE],
                              const uint8_t slot1[NINEDOF_IMAGE_SIZE],
                              uint8_t *next_slot, uint16_t *next_generation)
{
  uint16_t g0 = 0, g1 = 0;
  uint8_t ok0 = ninedof_image_check(slot0, rx->my_id, &g0);
  uint8_t ok1 = ninedof_image_check(slot1, rx->my_id, &g1);
  uint8_t used;
  const uint8_t *img;
  uint16_t gen;
  ninedof_cal_t cal;

  if (!ok0 && !ok1) {
    *next_slot = 0;
    *next_generation = 1;
    return 0xFF;
  }
  if (ok0 && ok1)
    used = ((int16_t)(uint16_t)(g1 - g0) > 0) ? 1 : 0;   /* wrap-aware */
  else
    used = ok1 ? 1 : 0;
  img = used ? slot1 : slot0;
  gen = used ? g1 : g0;
  ninedof_cal_decode((const ninedof_calset_t *)(img + 6), &cal);
  set_active(rx, (const ninedof_calset_t *)(img + 6), &cal);
  rx->dirty = 0;
  *next_slot = (uint8_t)(used ^ 1);
  *next_generation = (uint16_t)(gen + 1);
  return used;
}
