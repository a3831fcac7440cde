/*
 * emu/channel.h -- one shared IEEE 802.15.4 medium for the emulated motes.
 *
 * Every radio attached to the channel hears every other one on the same
 * 802.15.4 channel number (no distance, no capture effect).  Frames take
 * their real air time (250 kbit/s: 32 us per byte; SHR 5 bytes + PHR 1 byte
 * + PSDU).  Two transmissions that overlap in time are both corrupted for
 * every receiver (they arrive with a bad FCS).  Each surviving frame is lost
 * for each receiver independently with probability `loss_rate` (the receiver
 * never notices it), decided by a generator seeded with `seed`, so a run is
 * reproducible.  The channel also carries the radios' own timed events
 * (PLL lock, CCA end), so everything happens in one time-ordered queue that
 * channel_step() works off once per lockstep quantum.
 */
#ifndef EMU_CHANNEL_H
#define EMU_CHANNEL_H

#include <stdint.h>
#include <stdio.h>

typedef struct emu_channel emu_channel_t;

emu_channel_t *channel_new(double loss_rate, uint32_t seed);
/* change the loss rate from now on (the harness's `loss P` control command) */
void channel_set_loss(emu_channel_t *ch, double loss_rate);
void channel_step(emu_channel_t *ch, uint64_t now_ns);
void channel_free(emu_channel_t *ch);
/* one line: frames sent, collided, deliveries, losses (all radios) */
void channel_stats(emu_channel_t *ch, FILE *out);

/* ---- for radio models (rf230.c) ---- */
#define CH_BYTE_NS      32000ull            /* 250 kbit/s */
#define CH_SHR_NS       (5 * CH_BYTE_NS)    /* preamble 4 + SFD 1 */
#define CH_PHR_END_NS   (6 * CH_BYTE_NS)    /* SHR + PHR: RX_START */
#define CH_MAX_PSDU     127

typedef struct ch_frame {
    uint64_t id;             /* 1, 2, ... in order of start */
    uint64_t start_ns;       /* first preamble bit */
    uint64_t end_ns;         /* last FCS bit; 0 while the PHR is not yet sent */
    int      chan;           /* 802.15.4 channel number (11..26) */
    int      sender;         /* port index */
    int      collided;       /* overlapped another transmission */
    int      corrupt;        /* sender-side fault (e.g. buffer underrun) */
    uint8_t  len;            /* PHR: PSDU length including the FCS */
    uint8_t  psdu[CH_MAX_PSDU];
    int      done;
} ch_frame_t;

typedef struct ch_port_ops {
    /* PHR time: return the PSDU length (1..127) the sender put in its buffer */
    uint8_t (*tx_length)(void *ctx, ch_frame_t *f);
    /* end of the sender's frame: fill f->psdu[0..len) (FCS included) */
    void (*tx_fill)(void *ctx, ch_frame_t *f);
    void (*tx_end)(void *ctx, ch_frame_t *f);
    /* SFD + PHR heard: return 1 if the radio starts receiving it */
    int  (*rx_start)(void *ctx, ch_frame_t *f);
    /* end of a frame the radio was receiving; ok = 0: bad FCS */
    void (*rx_end)(void *ctx, ch_frame_t *f, int ok);
} ch_port_ops_t;

typedef struct ch_port_stats {
    uint32_t tx;             /* frames sent */
    uint32_t rx_ok;          /* frames received with a good FCS */
    uint32_t rx_bad;         /* frames received with a bad FCS (collision) */
    uint32_t lost;           /* frames dropped by the loss rate */
    uint32_t missed;         /* frames on air while not listening (busy, off) */
} ch_port_stats_t;

int  channel_port(emu_channel_t *ch, const ch_port_ops_t *ops, void *ctx);
ch_port_stats_t *channel_port_stats(emu_channel_t *ch, int port);
/* start a transmission now; the channel asks tx_length at the PHR */
ch_frame_t *channel_tx_begin(emu_channel_t *ch, int port, int chan, uint64_t now_ns);
/* 1 if another radio transmits on `chan` at some time in [from, to] */
int  channel_busy(emu_channel_t *ch, int port, int chan, uint64_t from_ns, uint64_t to_ns);
/* a timed callback (ties run in the order they were scheduled) */
typedef void (*ch_event_fn)(void *ctx, uint64_t t_ns, uintptr_t arg);
void channel_at(emu_channel_t *ch, uint64_t t_ns, ch_event_fn fn, void *ctx, uintptr_t arg);
/* cancel events of (fn, ctx) not yet run */
void channel_cancel(emu_channel_t *ch, ch_event_fn fn, void *ctx);
/* deterministic uniform [0, 1) from the channel's generator */
double channel_random(emu_channel_t *ch);

#endif
