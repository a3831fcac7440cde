/*
 * emu/channel.c -- the shared 802.15.4 medium (see channel.h).
 */
#include <stdlib.h>
#include <string.h>

#include "channel.h"

#define MAX_PORTS 64

typedef struct ch_event {
    uint64_t t, seq;
    ch_event_fn fn;
    void *ctx;
    uintptr_t arg;
} ch_event_t;

struct emu_channel {
    double loss;
    uint64_t rng;
    /* event queue: binary heap on (t, seq) */
    ch_event_t *ev;
    size_t nev, cap;
    uint64_t seq;
    /* ports */
    int nports;
    const ch_port_ops_t *ops[MAX_PORTS];
    void *ctx[MAX_PORTS];
    ch_port_stats_t st[MAX_PORTS];
    /* frames on air (or recently ended, kept for channel_busy) */
    ch_frame_t **fr;
    size_t nfr, frcap;
    uint64_t next_id;
    /* receivers of each frame: bit per port */
    uint64_t now;
    /* totals */
    uint64_t frames, collided;
};

static uint64_t rng_next(emu_channel_t *ch)
{
    /* splitmix64 */
    uint64_t z = (ch->rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

void channel_set_loss(emu_channel_t *ch, double loss_rate)
{
    ch->loss = loss_rate < 0 ? 0 : loss_rate > 1 ? 1 : loss_rate;
}

double channel_random(emu_channel_t *ch)
{
    return (double)(rng_next(ch) >> 11) * (1.0 / 9007199254740992.0);
}

emu_channel_t *channel_new(double loss_rate, uint32_t seed)
{
    emu_channel_t *ch = calloc(1, sizeof *ch);
    if (!ch)
        return NULL;
    ch->loss = loss_rate < 0 ? 0 : loss_rate > 1 ? 1 : loss_rate;
    ch->rng = 0x6D6F746563616C00ull ^ seed;
    return ch;
}

void channel_free(emu_channel_t *ch)
{
    if (!ch)
        return;
    for (size_t i = 0; i < ch->nfr; i++)
        free(ch->fr[i]);
    free(ch->fr);
    free(ch->ev);
    free(ch);
}

static int ev_less(const ch_event_t *a, const ch_event_t *b)
{
    return a->t < b->t || (a->t == b->t && a->seq < b->seq);
}

void channel_at(emu_channel_t *ch, uint64_t t_ns, ch_event_fn fn, void *ctx, uintptr_t arg)
{
    if (ch->nev == ch->cap) {
        ch->cap = ch->cap ? 2 * ch->cap : 64;
        ch->ev = realloc(ch->ev, ch->cap * sizeof *ch->ev);
    }
    size_t i = ch->nev++;
    ch_event_t e = { t_ns, ch->seq++, fn, ctx, arg };
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (!ev_less(&e, &ch->ev[p]))
            break;
        ch->ev[i] = ch->ev[p];
        i = p;
    }
    ch->ev[i] = e;
}

static ch_event_t ev_pop(emu_channel_t *ch)
{
    ch_event_t top = ch->ev[0];
    ch_event_t last = ch->ev[--ch->nev];
    size_t i = 0, n = ch->nev;
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        const ch_event_t *mv = &last;
        if (l < n && ev_less(&ch->ev[l], mv)) { m = l; mv = &ch->ev[l]; }
        if (r < n && ev_less(&ch->ev[r], mv)) { m = r; mv = &ch->ev[r]; }
        if (m == i)
            break;
        ch->ev[i] = ch->ev[m];
        i = m;
    }
    if (n)
        ch->ev[i] = last;
    return top;
}

static void ev_noop(void *ctx, uint64_t t, uintptr_t arg)
{
    (void)ctx; (void)t; (void)arg;
}

void channel_cancel(emu_channel_t *ch, ch_event_fn fn, void *ctx)
{
    for (size_t i = 0; i < ch->nev; i++)
        if (ch->ev[i].fn == fn && ch->ev[i].ctx == ctx)
            ch->ev[i].fn = ev_noop;
}

int channel_port(emu_channel_t *ch, const ch_port_ops_t *ops, void *ctx)
{
    if (ch->nports == MAX_PORTS)
        return -1;
    ch->ops[ch->nports] = ops;
    ch->ctx[ch->nports] = ctx;
    return ch->nports++;
}

ch_port_stats_t *channel_port_stats(emu_channel_t *ch, int port)
{
    return &ch->st[port];
}

/* ---------------------------------------------------------------- frames */
typedef struct {
    ch_frame_t f;
    uint64_t rx_mask;        /* ports receiving it */
} frame_rec_t;

static void frame_gc(emu_channel_t *ch, uint64_t now)
{
    /* keep frames that ended less than 1 ms ago (CCA windows look back) */
    size_t j = 0;
    for (size_t i = 0; i < ch->nfr; i++) {
        ch_frame_t *f = ch->fr[i];
        if (f->done && f->end_ns + 1000000ull < now)
            free(f);
        else
            ch->fr[j++] = f;
    }
    ch->nfr = j;
}

static void frame_end(void *vctx, uint64_t t, uintptr_t arg)
{
    emu_channel_t *ch = vctx;
    frame_rec_t *r = (frame_rec_t *)arg;
    ch_frame_t *f = &r->f;
    (void)t;
    ch->ops[f->sender]->tx_fill(ch->ctx[f->sender], f);
    f->done = 1;
    ch->ops[f->sender]->tx_end(ch->ctx[f->sender], f);
    int ok = !f->collided && !f->corrupt;
    if (f->collided)
        ch->collided++;
    for (int p = 0; p < ch->nports; p++) {
        if (!(r->rx_mask & (1ull << p)))
            continue;
        if (ok)
            ch->st[p].rx_ok++;
        else
            ch->st[p].rx_bad++;
        ch->ops[p]->rx_end(ch->ctx[p], f, ok);
    }
}

static void frame_phr(void *vctx, uint64_t t, uintptr_t arg)
{
    emu_channel_t *ch = vctx;
    frame_rec_t *r = (frame_rec_t *)arg;
    ch_frame_t *f = &r->f;
    uint8_t len = ch->ops[f->sender]->tx_length(ch->ctx[f->sender], f);
    if (len < 1 || len > CH_MAX_PSDU) {
        /* no valid PHR: the frame is garbage of maximum length */
        f->corrupt = 1;
        len = CH_MAX_PSDU;
    }
    f->len = len;
    f->end_ns = f->start_ns + CH_PHR_END_NS + (uint64_t)len * CH_BYTE_NS;
    /* a transmission that started while this one's PHR was on air and
     * reaches past it was already marked in channel_tx_begin */
    for (int p = 0; p < ch->nports; p++) {
        if (p == f->sender)
            continue;
        if (ch->loss > 0 && channel_random(ch) < ch->loss) {
            ch->st[p].lost++;
            continue;
        }
        if (ch->ops[p]->rx_start(ch->ctx[p], f))
            r->rx_mask |= 1ull << p;
        else
            ch->st[p].missed++;
    }
    channel_at(ch, f->end_ns, frame_end, ch, (uintptr_t)r);
    (void)t;
}

ch_frame_t *channel_tx_begin(emu_channel_t *ch, int port, int chan, uint64_t now_ns)
{
    frame_rec_t *r = calloc(1, sizeof *r);
    ch_frame_t *f = &r->f;
    f->id = ++ch->next_id;
    f->start_ns = now_ns;
    f->chan = chan;
    f->sender = port;
    frame_gc(ch, now_ns);
    for (size_t i = 0; i < ch->nfr; i++) {
        ch_frame_t *o = ch->fr[i];
        if (o->chan == chan && !o->done && (o->end_ns == 0 || o->end_ns > now_ns)) {
            o->collided = 1;
            f->collided = 1;
        }
    }
    if (ch->nfr == ch->frcap) {
        ch->frcap = ch->frcap ? 2 * ch->frcap : 16;
        ch->fr = realloc(ch->fr, ch->frcap * sizeof *ch->fr);
    }
    ch->fr[ch->nfr++] = f;              /* f is the first member of r */
    ch->frames++;
    ch->st[port].tx++;
    channel_at(ch, now_ns + CH_PHR_END_NS, frame_phr, ch, (uintptr_t)r);
    return f;
}

int channel_busy(emu_channel_t *ch, int port, int chan, uint64_t from_ns, uint64_t to_ns)
{
    for (size_t i = 0; i < ch->nfr; i++) {
        ch_frame_t *f = ch->fr[i];
        if (f->sender == port || f->chan != chan)
            continue;
        if (f->start_ns <= to_ns && (f->end_ns == 0 || f->end_ns >= from_ns))
            return 1;
    }
    return 0;
}

void channel_step(emu_channel_t *ch, uint64_t now_ns)
{
    ch->now = now_ns;
    while (ch->nev && ch->ev[0].t <= now_ns) {
        ch_event_t e = ev_pop(ch);
        e.fn(e.ctx, e.t, e.arg);
    }
}

void channel_stats(emu_channel_t *ch, FILE *out)
{
    uint64_t ok = 0, bad = 0, lost = 0, missed = 0;
    for (int p = 0; p < ch->nports; p++) {
        ok += ch->st[p].rx_ok;
        bad += ch->st[p].rx_bad;
        lost += ch->st[p].lost;
        missed += ch->st[p].missed;
    }
    fprintf(out, "channel: frames=%llu collided=%llu rx_ok=%llu rx_bad=%llu lost=%llu missed=%llu loss_rate=%.4f\n",
            (unsigned long long)ch->frames, (unsigned long long)ch->collided,
            (unsigned long long)ok, (unsigned long long)bad,
            (unsigned long long)lost, (unsigned long long)missed, ch->loss);
}
