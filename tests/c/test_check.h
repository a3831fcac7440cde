/*
 * test_check.h -- the checks of the C test programs (logic_tests.c,
 * twi_tests.c): CHECK(cond) counts a check and prints "FAIL line <n>;" when
 * it does not hold; check_summary() ends the output with "CHECKS <n> FAILED
 * <m>;END", which tests/avrsim.py (check_result) reads for tests/test_avr.py
 * and tests/test_twi.py.  Include after test_out.h.
 */
#ifndef TEST_CHECK_H
#define TEST_CHECK_H

#include <stdint.h>

static uint16_t checks, failed;

#define CHECK(cond)                                                     \
  do {                                                                  \
    checks++;                                                           \
    if (!(cond)) {                                                      \
      failed++;                                                         \
      out_s("FAIL line ");                                              \
      out_u16(__LINE__);                                                \
      out_c(';');                                                       \
    }                                                                   \
  } while (0)

static inline void check_summary(void)
{
  out_s("CHECKS ");
  out_u16(checks);
  out_s(" FAILED ");
  out_u16(failed);
  out_s(";END\n");
}

#endif /* TEST_CHECK_H */
