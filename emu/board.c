/* emu/board.c -- the board's true readings (board.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "board.h"

static const int16_t EMU_SYN_BASE[9] = { 0, 40, 200, -300, 100, 0, 100, -200, -500 };
static const int8_t EMU_SYN_SIGN[9] = { 1, -1, 1, 1, -1, 1, 1, 1, -1 };

emu_board_t *board_synthetic(void)
{
    return calloc(1, sizeof(emu_board_t));
}

emu_board_t *board_load(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "ninedof-emu: cannot open board file %s\n", path);
        return NULL;
    }
    char line[512];
    double rate = 0;
    if (!fgets(line, sizeof line, f) || sscanf(line, "# motecal-emu-board rate_hz=%lf", &rate) != 1
        || !(rate > 0)) {
        fprintf(stderr, "ninedof-emu: %s: first line must be '# motecal-emu-board rate_hz=R'\n", path);
        fclose(f);
        return NULL;
    }
    emu_board_t *b = calloc(1, sizeof *b);
    b->rate_hz = rate;
    long cap = 0;
    long lineno = 1;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n')
            continue;
        int v[9];
        float t = 25.0f;
        int got = sscanf(line, "%d %d %d %d %d %d %d %d %d %f", &v[0], &v[1], &v[2], &v[3],
                         &v[4], &v[5], &v[6], &v[7], &v[8], &t);
        if (got < 9) {
            fprintf(stderr, "ninedof-emu: %s:%ld: expected 9 integers\n", path, lineno);
            fclose(f);
            free(b->rows); free(b->temp_c); free(b);
            return NULL;
        }
        if (b->nrows == cap) {
            cap = cap ? cap * 2 : 4096;
            b->rows = realloc(b->rows, (size_t)cap * sizeof *b->rows);
            b->temp_c = realloc(b->temp_c, (size_t)cap * sizeof *b->temp_c);
        }
        for (int i = 0; i < 9; i++)
            b->rows[b->nrows][i] = (int16_t)(v[i] < -32768 ? -32768 : v[i] > 32767 ? 32767 : v[i]);
        b->temp_c[b->nrows] = t;
        b->nrows++;
    }
    fclose(f);
    if (!b->nrows) {
        fprintf(stderr, "ninedof-emu: %s: no rows\n", path);
        free(b);
        return NULL;
    }
    return b;
}

void board_set_temp(emu_board_t *b, double temp_c)
{
    b->temp_set = 1;
    b->temp_c_set = temp_c;
}

void board_truth(const emu_board_t *b, uint64_t t_ns, int16_t out[9], double *temp_c)
{
    if (b->temp_set && temp_c) {
        int16_t ignored[9];
        emu_board_t plain = *b;
        plain.temp_set = 0;
        board_truth(&plain, t_ns, out ? out : ignored, NULL);
        *temp_c = b->temp_c_set;
        return;
    }
    if (!b->nrows) {
        uint64_t k = t_ns / 1000000u;
        for (int i = 0; i < 9; i++)
            out[i] = (int16_t)(EMU_SYN_BASE[i] + EMU_SYN_SIGN[i] * (int)((k * (uint64_t)(i + 1)) % 512));
        if (temp_c)
            *temp_c = 25.0;
        return;
    }
    long r = (long)((long double)t_ns * b->rate_hz / 1e9L);
    if (r >= b->nrows)
        r = b->nrows - 1;
    memcpy(out, b->rows[r], 9 * sizeof(int16_t));
    if (temp_c)
        *temp_c = b->temp_c[r];
}
